"""Typed action clients, built on :class:`sim_ros.session.RosSession`.

One small class per action of the project::

    with RosSession("my_script") as session:
        walk = WalkClient(session)
        handle = walk.send(WalkClient.goal(distance=2.0, speed=0.3))
        outcome = handle.wait(timeout=120.0)
        print(outcome.status, outcome.error_name, handle.feedback.distance_walked)

Every call blocks the calling thread: never use these from inside an executor callback.
"""

from __future__ import annotations

import math
import threading
import time
import uuid
import weakref
from dataclasses import dataclass
from typing import Any, ClassVar, Generic, TypeVar

from action_msgs.msg import GoalStatus
from geometry_msgs.msg import PoseStamped
from rclpy.action import ActionClient
from rclpy.action.client import ClientGoalHandle
from unique_identifier_msgs.msg import UUID

from sim_client.parameters import ParameterError, Parameters
from sim_interfaces.action import MoveArm, NavigateToPose, PickPlace, Walk
from sim_interfaces.srv import Push
from sim_ros.names import FEEDBACK_QOS
from sim_ros.session import RESPONSE_QOS, RosSession, WaitTimeout

GoalT = TypeVar("GoalT")
FeedbackT = TypeVar("FeedbackT")
ResultT = TypeVar("ResultT")

STATUS_NAMES: dict[int, str] = {
    GoalStatus.STATUS_UNKNOWN: "UNKNOWN",
    GoalStatus.STATUS_ACCEPTED: "ACCEPTED",
    GoalStatus.STATUS_EXECUTING: "EXECUTING",
    GoalStatus.STATUS_CANCELING: "CANCELING",
    GoalStatus.STATUS_SUCCEEDED: "SUCCEEDED",
    GoalStatus.STATUS_CANCELED: "CANCELED",
    GoalStatus.STATUS_ABORTED: "ABORTED",
}
REJECTED = "REJECTED"


class ActionError(RuntimeError):
    """The action server is not there, or did not answer in time."""


def error_code_names(result_type: type) -> dict[int, str]:
    """Result constants of an action (``{0: "SUCCESS", 1: "INVALID_GOAL", ...}``)."""
    names: dict[int, str] = {}
    for name in dir(result_type):
        value = getattr(result_type, name)
        if name.isupper() and isinstance(value, int) and not isinstance(value, bool):
            names.setdefault(value, name)
    return names


@dataclass(frozen=True)
class Outcome(Generic[ResultT]):
    """How a goal ended.

    Attributes:
        status: ``SUCCEEDED``, ``ABORTED``, ``CANCELED``, ``REJECTED`` (goal refused) or
            ``UNKNOWN``.
        error_code: the result's ``error_code`` (None when the goal was rejected).
        error_name: the constant naming ``error_code`` (``"SUCCESS"``, ``"INVALID_GOAL"``...);
            ``"REJECTED"`` for a rejected goal.
        error_msg: the result's ``error_msg``.
        result: the result message (None when rejected).
    """

    status: str
    error_code: int | None
    error_name: str
    error_msg: str
    result: ResultT | None

    @property
    def succeeded(self) -> bool:
        return self.status == "SUCCEEDED" and self.error_code == 0

    def __str__(self) -> str:
        text = f"{self.status} ({self.error_name})"
        return f"{text}: {self.error_msg}" if self.error_msg else text


@dataclass(frozen=True)
class FeedbackSample(Generic[FeedbackT]):
    """One feedback message with the client's sim time [s] when it arrived."""

    sim_time: float
    feedback: FeedbackT


def feedback_elapsed_s(feedback: Any) -> float | None:
    """The sim time [s] since its goal started that a feedback message reports (``elapsed``, or Navigate's
    ``navigation_time``); None for an action whose feedback has neither."""
    for name in ("elapsed", "navigation_time"):
        duration = getattr(feedback, name, None)
        if duration is not None:
            return float(duration.sec) + float(duration.nanosec) * 1e-9
    return None


class GoalHandle(Generic[FeedbackT, ResultT]):
    """A sent goal: its feedback (latest and history), cancel, and wait for the outcome."""

    def __init__(self, client: SimActionClient, goal: Any) -> None:
        self._client = client
        self._session = client.session
        self.goal = goal
        self._lock = threading.Lock()
        self._history: list[FeedbackSample[FeedbackT]] = []
        self._handle: ClientGoalHandle | None = None
        self._result_future = None
        self._outcome: Outcome[ResultT] | None = None
        self.sent_at: float = client.sim_now()

    # Called from the executor thread: only append.
    def _on_feedback(self, feedback: Any) -> None:
        with self._lock:
            self._history.append(FeedbackSample(self._client.sim_now(), feedback))

    @property
    def accepted(self) -> bool:
        return self._handle is not None and bool(self._handle.accepted)

    @property
    def feedback(self) -> FeedbackT | None:
        """The latest feedback message, or None before the first one."""
        with self._lock:
            return self._history[-1].feedback if self._history else None

    @property
    def feedback_history(self) -> list[FeedbackSample[FeedbackT]]:
        with self._lock:
            return list(self._history)

    @property
    def done(self) -> bool:
        if self._outcome is not None:
            return True
        return self._result_future is None or self._result_future.done()

    def cancel(self, timeout: float = 10.0) -> bool:
        """Ask the server to cancel; True when the server accepted the cancel request."""
        if not self.accepted or self.done:
            return False
        assert self._handle is not None
        request = self._session.in_executor(self._handle.cancel_goal_async, timeout, f"cancel of {self._client.name}")
        response = self._session.wait_future(request, timeout, f"cancel of {self._client.name}")
        return bool(response.goals_canceling)

    def outcome(self) -> Outcome[ResultT] | None:
        """The outcome if the goal has ended, else None (does not block)."""
        if self._outcome is None and self.done:
            self._outcome = self._make_outcome()
        return self._outcome

    def wait(self, timeout: float) -> Outcome[ResultT]:
        """Block until the goal ends (``timeout`` wall seconds) and return its outcome.

        Raises:
            WaitTimeout: the goal did not end in time (it keeps running; cancel it if needed).
        """
        self._session.wait_for(lambda: self.done, timeout, f"the result of {self._client.name}")
        outcome = self.outcome()
        assert outcome is not None
        return outcome

    def _make_outcome(self) -> Outcome[ResultT]:
        if not self.accepted:
            return Outcome(REJECTED, None, REJECTED, f"goal rejected by {self._client.name}", None)
        assert self._result_future is not None
        response = self._result_future.result()
        result = response.result
        code = int(getattr(result, "error_code", 0))
        return Outcome(
            status=STATUS_NAMES.get(int(response.status), str(response.status)),
            error_code=code,
            error_name=self._client.error_names.get(code, str(code)),
            error_msg=str(getattr(result, "error_msg", "")),
            result=result,
        )


PROBE_ATTEMPT_S = 2.0  # [s of wall time] a probe request not answered in this long is sent again


def wait_until_answering(session: RosSession, client: ActionClient, timeout: float) -> None:
    """Wait until an action server answers this client's cancel and result requests (both ways matched).

    ``server_is_ready()`` says this client's *requests* reach the server. Its responses come back
    on readers the server's side of discovery has to match too, and until it has (seconds on a
    loaded machine) a response is dropped: the request is never answered. A first cancel sent just
    after the server became "ready" once waited 30 s for nothing that way. A cancel and a result
    request for a goal id nobody has are answered at once and change nothing; each is sent (again
    every :data:`PROBE_ATTEMPT_S`) until it is answered.

    Raises:
        WaitTimeout: the server did not answer both within ``timeout`` wall seconds.
    """
    deadline = time.monotonic() + timeout
    session.wait_for(client.server_is_ready, timeout, f"action server {client._action_name}")
    nobody = ClientGoalHandle(client, UUID(uuid=list(uuid.uuid4().bytes)),
                              client._action_type.Impl.SendGoalService.Response())
    for probe, what in ((nobody.cancel_goal_async, "a cancel request"), (nobody.get_result_async, "a result request")):
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                raise WaitTimeout(f"action server {client._action_name} did not answer {what} within {timeout:.1f} s")
            future = session.in_executor(probe, remaining, what)
            try:
                session.wait_future(future, min(PROBE_ATTEMPT_S, remaining), f"the answer to {what}")
                break
            except WaitTimeout:
                continue


class SimActionClient(Generic[GoalT, FeedbackT, ResultT]):
    """One action client on a session; a subclass per action sets ``action_type``, ``default_name`` and its goal builder."""

    action_type: ClassVar[Any]
    default_name: ClassVar[str]

    def __init__(self, session: RosSession, name: str | None = None) -> None:
        self.session = session
        self.name = name or self.default_name
        self._client = ActionClient(session.node, self.action_type, self.name, goal_service_qos_profile=RESPONSE_QOS,
                                    result_service_qos_profile=RESPONSE_QOS, cancel_service_qos_profile=RESPONSE_QOS,
                                    feedback_sub_qos_profile=FEEDBACK_QOS)
        self.error_names = error_code_names(self.action_type.Result)
        self._answering = False  # the server has answered this client's probes (wait_for_server)
        # Feedback is read on a subscription of our own: rclpy's ActionClient drops a goal's feedback that
        # it takes after the goal's result (it forgets the goal's callback then), and with a burst of
        # feedback queued behind a result (a lock-stepped run on a loaded machine) the last messages of a
        # goal were lost that way. Here every message of a goal this client sent reaches its handle.
        self._handles: weakref.WeakValueDictionary[bytes, GoalHandle[FeedbackT, ResultT]] = weakref.WeakValueDictionary()
        self._handles_lock = threading.Lock()
        self._feedback = session.node.create_subscription(
            self.action_type.Impl.FeedbackMessage, f"{self.name}/_action/feedback", self._on_feedback_message,
            FEEDBACK_QOS)

    # Called from the executor thread.
    def _on_feedback_message(self, message: Any) -> None:
        with self._handles_lock:
            handle = self._handles.get(bytes(message.goal_id.uuid))
        if handle is not None:
            handle._on_feedback(message.feedback)

    def sim_now(self) -> float:
        """The session's clock [s] (sim time when the session uses sim time)."""
        return self.session.node.get_clock().now().nanoseconds * 1e-9

    def wait_for_server(self, timeout: float = 30.0) -> None:
        """Wait until the server answers this client (once per client; see :func:`wait_until_answering`)."""
        if self._answering and self._client.server_is_ready():
            return
        try:
            wait_until_answering(self.session, self._client, timeout)
            # ... and its feedback reaches us from the first message on (lock-stepped runs wait for it).
            self.session.wait_for(lambda: self._feedback.get_publisher_count() > 0, timeout,
                                  f"the feedback of {self.name}")
        except WaitTimeout as error:
            raise ActionError(f"{error}; is the node that serves {self.name} running?") from None
        self._answering = True

    def server_ready(self) -> bool:
        return bool(self._client.server_is_ready())

    def feedback_period_s(self) -> float | None:
        """[s of sim time] between two feedback messages of this action's server: its ``feedback_rate``
        parameter, asked of the node that publishes the feedback; None when no such node answers."""
        node = self.session.node
        for info in node.get_publishers_info_by_topic(node.resolve_topic_name(f"{self.name}/_action/feedback")):
            try:
                rate = Parameters(self.session, f"{info.node_namespace.rstrip('/')}/{info.node_name}", 2.0).get(
                    "feedback_rate")
            except (ParameterError, WaitTimeout):
                continue
            if isinstance(rate, int | float) and rate > 0:
                return 1.0 / float(rate)
        return None

    def send(self, goal: GoalT, timeout: float = 30.0) -> GoalHandle[FeedbackT, ResultT]:
        """Send a goal and wait (``timeout`` wall seconds) for it to be accepted or rejected.

        A rejected goal gives a handle whose ``wait()`` returns an ``Outcome`` with status
        ``REJECTED`` at once.
        """
        self.wait_for_server(timeout)
        handle: GoalHandle[FeedbackT, ResultT] = GoalHandle(self, goal)
        goal_id = UUID(uuid=list(uuid.uuid4().bytes))
        with self._handles_lock:
            self._handles[bytes(goal_id.uuid)] = handle
        what = f"acceptance of the {self.name} goal"
        future = self.session.in_executor(lambda: self._client.send_goal_async(goal, goal_uuid=goal_id), timeout, what)
        goal_handle = self.session.wait_future(future, timeout, what)
        handle._handle = goal_handle
        if goal_handle.accepted:
            handle._result_future = self.session.in_executor(goal_handle.get_result_async, timeout,
                                                             f"the {self.name} result request")
        return handle

    def destroy(self) -> None:
        self.session.node.destroy_subscription(self._feedback)
        self._client.destroy()


def _pose(x: float, y: float, z: float, roll: float = 0.0, pitch: float = 0.0, yaw: float = 0.0,
          frame: str = "world") -> PoseStamped:
    """A PoseStamped from a position [m] and roll/pitch/yaw [rad] (extrinsic x-y-z)."""
    pose = PoseStamped()
    pose.header.frame_id = frame
    pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = float(x), float(y), float(z)
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    q = pose.pose.orientation
    q.w = cr * cp * cy + sr * sp * sy
    q.x = sr * cp * cy - cr * sp * sy
    q.y = cr * sp * cy + sr * cp * sy
    q.z = cr * cp * sy - sr * sp * cy
    return pose


def push_request(body: str, force_n: tuple[float, float, float], torque_nm: tuple[float, float, float],
                 duration_s: float) -> Push.Request:
    """A ``/sim/push`` request: force [N] and torque [N m] in the world frame; empty body = the base."""
    request = Push.Request(body=body, duration=float(duration_s))
    request.wrench.force.x, request.wrench.force.y, request.wrench.force.z = map(float, force_n)
    request.wrench.torque.x, request.wrench.torque.y, request.wrench.torque.z = map(float, torque_nm)
    return request


class MoveArmClient(SimActionClient[MoveArm.Goal, MoveArm.Feedback, MoveArm.Result]):
    """``/move_arm`` (served by ``/arm``)."""

    action_type = MoveArm
    default_name = "move_arm"  # relative: under the session's namespace

    @staticmethod
    def goal(
        x: float, y: float, z: float, rpy: tuple[float, float, float] | None = None, arm: str = "",
        position_tolerance: float = 0.005, orientation_tolerance: float = 0.0,
        max_velocity_scaling: float = 0.0, timeout: float = 0.0, frame: str = "world",
    ) -> MoveArm.Goal:
        """A MoveArm goal: tool position [m] in ``frame``; ``rpy`` [rad] or None for position only."""
        goal = MoveArm.Goal()
        goal.target = _pose(x, y, z, *(rpy or (0.0, 0.0, 0.0)), frame=frame)
        if rpy is None:
            goal.target.pose.orientation.w, goal.target.pose.orientation.x = 1.0, 0.0
            goal.target.pose.orientation.y = goal.target.pose.orientation.z = 0.0
        goal.end_effector = arm
        goal.position_tolerance = float(position_tolerance)
        goal.orientation_tolerance = float(orientation_tolerance if rpy is not None else 0.0)
        goal.max_velocity_scaling = float(max_velocity_scaling)
        goal.timeout = float(timeout)
        return goal


class PickPlaceClient(SimActionClient[PickPlace.Goal, PickPlace.Feedback, PickPlace.Result]):
    """``/pick_place`` (served by ``/arm``)."""

    action_type = PickPlace
    default_name = "pick_place"  # relative: under the session's namespace

    @staticmethod
    def goal(object_id: str, place: tuple[float, float, float], arm: str = "", timeout: float = 0.0) -> PickPlace.Goal:
        """Pick ``object_id`` and put its centre at ``place`` [m, world]; z <= 0 = on the table."""
        goal = PickPlace.Goal()
        goal.object_id = object_id
        goal.place_pose = _pose(*place)
        goal.end_effector = arm
        goal.timeout = float(timeout)
        return goal


class WalkClient(SimActionClient[Walk.Goal, Walk.Feedback, Walk.Result]):
    """``/walk`` (served by ``/locomotion``)."""

    action_type = Walk
    default_name = "walk"  # relative: under the session's namespace

    @staticmethod
    def goal(distance: float, speed: float = 0.0, timeout: float = 0.0) -> Walk.Goal:
        """Walk ``distance`` [m] (signed) at ``speed`` [m/s] (0 = the walking_speed parameter)."""
        return Walk.Goal(distance=float(distance), speed=float(speed), timeout=float(timeout))


class NavigateClient(SimActionClient[NavigateToPose.Goal, NavigateToPose.Feedback, NavigateToPose.Result]):
    """``/navigate_to_pose`` (served by ``/locomotion``)."""

    action_type = NavigateToPose
    default_name = "navigate_to_pose"  # relative: under the session's namespace

    @staticmethod
    def goal(x: float, y: float, yaw: float = 0.0, frame: str = "odom") -> NavigateToPose.Goal:
        """Go to (x, y) [m] facing ``yaw`` [rad] in ``frame``."""
        return NavigateToPose.Goal(pose=_pose(x, y, 0.0, yaw=yaw, frame=frame))


ACTION_CLIENTS: dict[str, type[SimActionClient]] = {
    "move_arm": MoveArmClient,
    "pick_place": PickPlaceClient,
    "walk": WalkClient,
    "navigate": NavigateClient,
}
