"""bringup's stand-in for an action server that dies: no action client waits forever for a result.

The ROS action protocol answers a goal's result request (and a cancel request) only from the server
that took the goal. A server that is killed (SIGKILL, a crash) leaves its clients waiting for ever,
and the server bringup restarts cannot help: it never received those requests, and rmw gives no
process a way to answer a request it did not take (rclpy exposes no request writer's GUID).

DDS, however, delivers a service request to *every* server of that service. :class:`ResultKeeper`
serves each action's ``_action/get_result`` and ``_action/cancel_goal`` services next to the real
server and answers nothing while that server lives: it keeps each result request until the action's
status topic says the goal ended (the real server answered it), and each cancel request for
:data:`CANCEL_KEEP_S`. When bringup sees the server's process die, the keeper answers every request
it keeps for a goal that had not ended: ABORTED with ``SIM_FAULT`` and a message naming the dead
server; a cancel gets ``ERROR_GOAL_TERMINATED``. Later requests about those goals are answered the
same way at once, and so is a request about a goal no status listed while no server runs (from the death
until bringup starts the server again: the goal can only be the dead server's). The robot itself
stops when its server goes silent (the skill in ``/sim`` ends).

The keeper can answer only the requests DDS delivered to it: those sent after its side of discovery
matched the client's writers. A client whose endpoints it has not yet matched (seconds after the client
appeared, on a loaded machine) and whose server dies in that time is not answered.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from action_msgs.msg import GoalStatus, GoalStatusArray
from action_msgs.srv import CancelGoal
from rclpy.node import Node
from rclpy.qos import qos_profile_action_status_default
from rclpy.serialization import deserialize_message
from rclpy.service import Service

from sim_ros.session import RosSession, quiet_events

UNSEEN_KEEP_S = 60.0  # [s of wall time] a result request for a goal no status has listed is kept this long
STATUS_READ_S = 1.0  # [s of wall time] the status topic is read at most this often (and when a server dies)
CANCEL_KEEP_S = 10.0  # [s of wall time] a cancel request is kept this long (the live server answers in ms)
TERMINAL = (GoalStatus.STATUS_SUCCEEDED, GoalStatus.STATUS_CANCELED, GoalStatus.STATUS_ABORTED)
NO_GOAL = bytes(16)  # a cancel request's goal id that means "every goal" (with a stamp) or none
RESEND_EVERY_S = 0.5  # [s of wall time] an answer rmw could not send (the client's reader not matched) is sent again
RESEND_FOR_S = 30.0  # [s of wall time] ... for this long


@dataclass
class _Kept:
    """A request whose answer is the live server's business, kept in case it dies."""

    service: Service
    header: Any
    goal: bytes
    since_s: float  # [s, monotonic]
    request: Any = None


@dataclass
class _ActionWatch:
    """What the keeper holds for one action."""

    name: str
    action_type: Any
    results: list[_Kept] = field(default_factory=list)
    cancels: list[_Kept] = field(default_factory=list)
    status: dict[bytes, int] = field(default_factory=dict)  # the latest status of each goal listed
    status_raw: bytes | None = None  # the latest status message, serialized, not yet read into ``status``
    status_read_s: float = -math.inf  # [s, monotonic] when ``status`` was last read from it
    orphans: dict[bytes, str] = field(default_factory=dict)  # goals whose server died -> why
    dead_why: str = ""  # while its server is dead and not yet restarted: why (else "")


class ResultKeeper:
    """Answers the result and cancel requests of goals whose action server died.

    Everything runs on its session's executor thread (the services' callbacks, the status topic and
    :meth:`server_died`), so nothing here needs a lock. A request is kept up to :data:`STATUS_READ_S`
    longer than its goal runs.

    Args:
        actions: executable -> ``[(action name, action type), ...]`` it serves.
        namespace: the bring-up's namespace ("" = the root): the keeper watches the actions under it.
    """

    def __init__(self, actions: dict[str, list[tuple[str, Any]]], namespace: str = "") -> None:
        self._watches: dict[str, list[_ActionWatch]] = {}
        self._verdicts: dict[int, tuple[_ActionWatch, bytes, Any] | None] = {}  # id(response) -> keep (what) or send
        self._send_now: dict[int, Callable[[Any, Any], None]] = {}  # id(service) -> rclpy's own send_response
        self._session = RosSession("bringup", use_sim_time=False, namespace=namespace)
        node = self._session.node
        self._unsent: list[tuple[Service, Any, Any, float]] = []  # (service, response, header, first try [monotonic s])
        node.create_timer(RESEND_EVERY_S, self._send_again)
        for executable, served in actions.items():
            self._watches[executable] = [self._watch(node, name, action_type) for name, action_type in served]

    def close(self) -> None:
        self._session.close()

    # ----- bringup's side --------------------------------------------------------------------
    def server_died(self, executable: str, code: int | None) -> int:
        """``executable`` died: answer every request kept for its goals that had not ended. Returns how many."""
        if not self._watches.get(executable):
            return 0
        return self._session.in_executor(lambda: self._answer_orphans(executable, code), what="the orphans' answers")

    def server_restarting(self, executable: str) -> None:
        """bringup starts ``executable`` again: from now on a goal this keeper never saw may be the new server's."""
        def alive_again() -> None:
            for watch in self._watches.get(executable, []):
                watch.dead_why = ""

        self._session.in_executor(alive_again, what="the restart")

    def _answer_orphans(self, executable: str, code: int | None) -> int:
        answered = 0
        for watch in self._watches[executable]:
            why = (f"the action server of {watch.name} ({executable}) died with exit code {code} before the goal "
                   "ended; bringup restarts it: send the goal again")
            self._read_status(watch)  # the server's last word, however recent
            self._prune(watch)
            watch.dead_why = why
            for goal, status in watch.status.items():
                if status not in TERMINAL:
                    watch.orphans[goal] = why
            for kept in watch.results:
                watch.orphans.setdefault(kept.goal, why)
            results, watch.results = watch.results, []
            cancels, watch.cancels = watch.cancels, []
            watch.status, watch.status_raw = {}, None
            for kept in results:
                self._send(kept.service, self._aborted(watch, watch.orphans[kept.goal]), kept.header)
            for kept in cancels:  # the dead server may have answered some already: a second answer is ignored
                self._send(kept.service, self._cancel_answer(watch, kept.request), kept.header)
            answered += len(results) + len(cancels)
        return answered

    def _send(self, service: Service, response: Any, header: Any, first_s: float | None = None) -> None:
        """Send an answer; one rmw could not send is sent again every RESEND_EVERY_S for RESEND_FOR_S.

        rmw sends a response only once the service's response writer has matched the client's reader (it
        waits 100 ms); otherwise rclpy drops it with a RuntimeWarning, "failed to send response (timeout)",
        and the client waits for ever. Seen on a loaded machine: bringup answered a killed server's client,
        which got nothing in 30 s. Sent again once matched, it arrives (only an unsent answer is repeated).
        """
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            self._send_now[id(service)](response, header)
        if any("failed to send response" in str(warning.message) for warning in caught):
            first_s = time.monotonic() if first_s is None else first_s
            if time.monotonic() - first_s < RESEND_FOR_S:
                self._unsent.append((service, response, header, first_s))

    def _send_again(self) -> None:
        unsent, self._unsent = self._unsent, []
        for service, response, header, first_s in unsent:
            self._send(service, response, header, first_s)

    # ----- the services ----------------------------------------------------------------------
    def _watch(self, node: Node, name: str, action_type: Any) -> _ActionWatch:
        watch = _ActionWatch(name, action_type)
        results = node.create_service(action_type.Impl.GetResultService, f"{name}/_action/get_result",
                                      lambda request, response: self._on_result(watch, request, response))
        cancels = node.create_service(CancelGoal, f"{name}/_action/cancel_goal",
                                      lambda request, response: self._on_cancel(watch, request, response))
        for service in (results, cancels):
            self._route_responses(service)
        # Kept serialized: a status array lists every goal of the last 15 min (rclpy's result timeout) and
        # comes at every change of any goal; read at most every STATUS_READ_S, it costs next to nothing.
        node.create_subscription(GoalStatusArray, f"{name}/_action/status",
                                 lambda data: setattr(watch, "status_raw", data), qos_profile_action_status_default,
                                 event_callbacks=quiet_events(), raw=True)
        return watch

    def _route_responses(self, service: Service) -> None:
        """rclpy sends whatever a service callback returns; here the callback's verdict decides: send it,
        or keep the request's header for later (the live server answers it)."""
        self._send_now[id(service)] = service.send_response

        def send_response(response: Any, header: Any) -> None:
            keep = self._verdicts.pop(id(response), None)
            if keep is None:
                self._send(service, response, header)
                return
            watch, goal, cancel = keep
            kept = _Kept(service, header, goal, time.monotonic(), cancel)
            (watch.results if cancel is None else watch.cancels).append(kept)

        service.send_response = send_response  # type: ignore[method-assign]  # this instance's own route

    @staticmethod
    def _orphan_if_dead(watch: _ActionWatch, goal: bytes) -> None:
        """While no server runs, a goal no status listed as ended can only be the dead server's (a server killed
        seconds after it started, before this keeper had its status; seen in a fresh-clone run)."""
        if watch.dead_why and goal != NO_GOAL and goal not in watch.orphans and watch.status.get(goal) not in TERMINAL:
            watch.orphans[goal] = watch.dead_why

    def _on_result(self, watch: _ActionWatch, request: Any, response: Any) -> Any:
        goal = bytes(request.goal_id.uuid)
        self._prune(watch)
        self._orphan_if_dead(watch, goal)
        why = watch.orphans.get(goal)
        if why is not None:
            return self._aborted(watch, why, response)
        self._verdicts[id(response)] = (watch, goal, None)
        return response

    def _on_cancel(self, watch: _ActionWatch, request: Any, response: Any) -> Any:
        goal = bytes(request.goal_info.goal_id.uuid)
        self._prune(watch)
        self._orphan_if_dead(watch, goal)
        if goal in watch.orphans:
            return self._cancel_answer(watch, request, response)
        self._verdicts[id(response)] = (watch, goal, request)
        return response

    # ----- answers ---------------------------------------------------------------------------
    @staticmethod
    def _read_status(watch: _ActionWatch, at_most_every_s: float = 0.0) -> None:
        """``status`` from the latest status message, unless it was read less than ``at_most_every_s`` ago."""
        now = time.monotonic()
        if watch.status_raw is None or now - watch.status_read_s < at_most_every_s:
            return
        msg = deserialize_message(watch.status_raw, GoalStatusArray)
        watch.status = {bytes(status.goal_info.goal_id.uuid): int(status.status) for status in msg.status_list}
        watch.status_raw, watch.status_read_s = None, now

    @classmethod
    def _prune(cls, watch: _ActionWatch) -> None:
        """Forget what the live server has answered (the goal ended) or never will need (never listed)."""
        cls._read_status(watch, STATUS_READ_S)
        now = time.monotonic()

        def still_open(kept: _Kept) -> bool:
            status = watch.status.get(kept.goal)
            if status is None:
                return now - kept.since_s < UNSEEN_KEEP_S
            return status not in TERMINAL

        watch.results = [kept for kept in watch.results if still_open(kept)]
        watch.cancels = [kept for kept in watch.cancels if now - kept.since_s < CANCEL_KEEP_S]

    @staticmethod
    def _aborted(watch: _ActionWatch, why: str, response: Any | None = None) -> Any:
        response = watch.action_type.Impl.GetResultService.Response() if response is None else response
        response.status = GoalStatus.STATUS_ABORTED
        response.result = watch.action_type.Result(error_code=watch.action_type.Result.SIM_FAULT, error_msg=why)
        return response

    @staticmethod
    def _cancel_answer(watch: _ActionWatch, request: Any, response: Any | None = None) -> Any:
        """A cancel request answered for a dead server: its goals have ended (ABORTED by this keeper)."""
        response = CancelGoal.Response() if response is None else response
        goal = bytes(request.goal_info.goal_id.uuid)
        ended = goal in watch.orphans or goal == NO_GOAL
        response.return_code = (CancelGoal.Response.ERROR_GOAL_TERMINATED if ended
                                else CancelGoal.Response.ERROR_UNKNOWN_GOAL_ID)
        return response
