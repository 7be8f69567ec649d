"""``/reset_pose`` (std_srvs/Trigger) of ``/locomotion``: back to the default standing posture, answered when reached.

The pose is reached by the ResetPose skill in ``/sim``'s control step
(:mod:`sim_bridge.skills.reset_pose`), started over the goal protocol like any action's goal: a START
on ``/sim/skill_command``, the outcome on ``/sim/skill_state``. It owns the legs, so a running Walk or
NavigateToPose is preempted first (it ends PREEMPTED). The answer is success=true once every joint is
within the tolerance of the default pose; success=false with the reason otherwise ("fallen: reset the
simulation" for a fallen robot). Trigger is the standard type for a request without arguments that
answers success and a message, what ``ros2 service call /reset_pose std_srvs/srv/Trigger`` expects.
"""

from __future__ import annotations

import itertools
import os
import threading
import time
from dataclasses import dataclass, field

from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.serialization import deserialize_message, serialize_message
from rclpy.task import Future
from std_srvs.srv import Trigger

from nodes.runtime.executor import wait_parked
from sim_bridge.skills import LEGS
from sim_interfaces.action import ResetPose
from sim_interfaces.msg import SkillCommand, SkillState
from sim_ros.names import SKILL_COMMAND_TOPIC, SKILL_QOS, SKILL_STATE_TOPIC

ACK_TIMEOUT_S = 10.0  # wall seconds for /sim to report the goal it was sent
RESEND_PERIOD_S = 0.1  # a START not yet reported is sent again (a message sent before discovery is lost)
_TERMINAL = frozenset((SkillState.SUCCEEDED, SkillState.ABORTED, SkillState.CANCELED))
# Goal numbers of this process's reset_pose goals: apart from the action servers' (see nodes.servers.server).
_seq = itertools.count(1 + (os.getpid() % 4096) * 1_000_000 + 900_000)


@dataclass
class _Pending:
    command: SkillCommand
    sent_at: float = field(default_factory=time.monotonic)
    acked: bool = False
    done: Future = field(default_factory=Future)  # (succeeded, message)


class ResetPoseService:
    """Serves ``/reset_pose`` on ``node`` (see the module's text)."""

    def __init__(self, node: Node) -> None:
        self._node = node
        self._lock = threading.Lock()
        self._pending: dict[int, _Pending] = {}
        group = ReentrantCallbackGroup()
        self._commands = node.create_publisher(SkillCommand, SKILL_COMMAND_TOPIC, SKILL_QOS)
        node.create_subscription(SkillState, SKILL_STATE_TOPIC, self._on_state, SKILL_QOS, callback_group=group)
        node.create_service(Trigger, "reset_pose", self._on_reset_pose, callback_group=group)
        self._resend = node.create_timer(RESEND_PERIOD_S, self._watchdog, callback_group=group,
                                         clock=Clock(clock_type=ClockType.STEADY_TIME))
        self._resend.cancel()  # runs only while a START is unanswered

    async def _on_reset_pose(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        command = SkillCommand(request=SkillCommand.START, skill="reset_pose", resource=LEGS, goal_seq=next(_seq) & 0xFFFFFFFF,
                               goal=serialize_message(ResetPose.Goal()))
        pending = _Pending(command)
        with self._lock:
            self._pending[command.goal_seq] = pending
            self._resend.reset()
        self._send(command)
        try:
            response.success, response.message = await wait_parked(pending.done)
        finally:
            with self._lock:
                self._pending.pop(command.goal_seq, None)
        log = self._node.get_logger()
        (log.info if response.success else log.warning)(f"reset_pose: {response.message}")
        return response

    def _on_state(self, state: SkillState) -> None:
        if state.skill != "reset_pose":
            return
        with self._lock:
            pending = self._pending.get(state.goal_seq)
            if pending is None or pending.done.done():
                return
            pending.acked = True
            if state.status not in _TERMINAL:
                return
            result = deserialize_message(bytes(state.result), ResetPose.Result) if state.result else None
            message = result.error_msg if result is not None else (state.message or "ended without a result")
            pending.done.set_result((state.status == SkillState.SUCCEEDED, message))

    def _watchdog(self) -> None:
        now = time.monotonic()
        with self._lock:
            waiting = [p for p in self._pending.values() if not p.acked and not p.done.done()]
            if not waiting:
                self._resend.cancel()
            for pending in waiting:
                if now - pending.sent_at > ACK_TIMEOUT_S:
                    pending.done.set_result((False, f"no answer from /sim on {SKILL_STATE_TOPIC} within "
                                                    f"{ACK_TIMEOUT_S:g} s: is /sim running with a walking robot?"))
        for pending in waiting:
            if not pending.done.done():
                self._send(pending.command)

    def _send(self, command: SkillCommand) -> None:
        command.header.stamp = self._node.get_clock().now().to_msg()
        self._commands.publish(command)
