"""Small helpers for action tests: send a goal, collect feedback, wait for the result."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from rclpy.action import ActionClient
from rclpy.qos import QoSProfile

from sim_client import RosSession
from sim_client.actions import wait_until_answering
from sim_interfaces.action import NavigateToPose
from sim_ros.session import WaitTimeout


@dataclass
class Sent:
    """A goal in flight: its handle, the feedback received so far."""

    handle: Any
    session: RosSession | None = None
    feedback: list = field(default_factory=list)
    _result_future: Any = None

    def result_future(self) -> Any:
        """The one result request of this goal (asked once, shared by every waiter)."""
        if self._result_future is None:
            assert self.session is not None
            self._result_future = self.session.in_executor(self.handle.get_result_async, what="the result request")
        return self._result_future

    def cancel(self, timeout: float = 10.0) -> Any:
        """Request a cancel and return the server's cancel response."""
        assert self.session is not None
        request = self.session.in_executor(self.handle.cancel_goal_async, timeout, "the cancel request")
        return self.session.wait_future(request, timeout, "the cancel response")


def send(session: RosSession, client: ActionClient, goal: Any, timeout: float = 30.0) -> Sent:
    sent = Sent(handle=None, session=session)

    def on_feedback(msg: Any) -> None:
        sent.feedback.append(msg.feedback)

    # Sent from the executor's thread: see RosSession.in_executor for the rclpy race this avoids.
    future = session.in_executor(lambda: client.send_goal_async(goal, feedback_callback=on_feedback),
                                 timeout, "the goal request")
    sent.handle = session.wait_future(future, timeout, "goal acceptance")
    return sent


def result(session: RosSession, sent: Sent, timeout: float = 120.0) -> Any:
    """The wrapped result (``.status``, ``.result``)."""
    return session.wait_future(sent.result_future(), timeout, "the action result")


def wait_feedback(session: RosSession, sent: Sent, predicate: Callable[[Any], bool], timeout: float, what: str) -> Any:
    """Wait until the latest feedback satisfies ``predicate``; fail at once, naming why, if the goal ends first."""
    future = sent.result_future()

    def ready() -> bool:
        if sent.feedback and predicate(sent.feedback[-1]):
            return True
        if future.done():
            outcome = future.result()
            raise AssertionError(f"the goal ended (status {outcome.status}, code {outcome.result.error_code}: "
                                 f"{outcome.result.error_msg!r}) before {what}")
        return False

    return session.wait_for(ready, timeout, what)


def action_client(session: RosSession, action_type: Any, name: str) -> ActionClient:
    """A plain rclpy ActionClient, not waited for: made early, its discovery goes on while a test does other things.

    It keeps 100 feedback messages, as the servers' writers do: an unpaced sim's feedback comes in bursts."""
    return ActionClient(session.node, action_type, name, feedback_sub_qos_profile=QoSProfile(depth=100))


def ready_client(session: RosSession, action_type: Any, name: str, timeout: float = 60.0,
                 made: ActionClient | None = None) -> ActionClient:
    """A plain rclpy ActionClient (``made``, or a new :func:`action_client`) whose server has answered it (a cancel
    and a result request: both ways matched)."""
    deadline = time.monotonic() + timeout
    while True:
        client = made if made is not None else action_client(session, action_type, name)
        made = None
        remaining = deadline - time.monotonic()
        try:
            wait_until_answering(session, client, min(FRESH_CLIENT_S, remaining))
            return client
        except WaitTimeout:
            session.in_executor(client.destroy, what="destroying an unanswered action client")
            if time.monotonic() + 1.0 >= deadline:
                raise
            # A server that answers nothing for this long has not matched this client's endpoints (seen once
            # for 90 s after a bring-up); a new client is discovered afresh. A stuck server fails below anyway.


FRESH_CLIENT_S = 30.0  # [s of wall time] an action client whose probes are not answered this long is made anew


def sim_now(client: RosSession, entity: str, sim: str = "/sim") -> float:
    """The sim's time [s] now, asked of /sim (an entity's state is stamped when it is read).

    A client's latest message of a topic can lag the sim by seconds on a loaded machine (a deep queue loses
    nothing but is read late); a time read this way is at or after every request this client has had answered.
    """
    from sim_ros.stamps import seconds_of
    from simulation_interfaces.srv import GetEntityState

    response = client.call(GetEntityState, f"{sim}/get_entity_state", GetEntityState.Request(entity=entity), timeout=30.0)
    return seconds_of(response.state.header.stamp)


def nav_goal(x: float, y: float, yaw: float = 0.0) -> NavigateToPose.Goal:
    """A NavigateToPose goal to (x, y) [m] facing ``yaw`` [rad], in the world frame."""
    goal = NavigateToPose.Goal()
    goal.pose.header.frame_id = "world"
    goal.pose.pose.position.x, goal.pose.pose.position.y = x, y
    goal.pose.pose.orientation.z, goal.pose.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    return goal
