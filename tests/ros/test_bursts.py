"""Bursts of goals: 24 goals from 2 clients within about 1 s; every request answered, one end per goal.

Each client is a node of its own (its own ROS context). A new goal preempts the running one, so all
but the last end PREEMPTED; none may end with a false SIM_FAULT, and the last one succeeds.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Iterator

import pytest
from action_msgs.msg import GoalStatus
from rclpy.action import ActionClient
from rclpy.qos import QoSProfile

from sim_client import RosSession
from sim_interfaces.action import MoveArm, Walk
from sim_interfaces.srv import Reset
from sim_ros.session import WaitTimeout
from tests.ros.actions import ready_client, result, send
from tests.ros.processes import running

pytestmark = pytest.mark.slow

GOALS_PER_CLIENT = 12
READY_S = 90.0


def walk_goal(i: int) -> Walk.Goal:
    return Walk.Goal(distance=-0.3 if i % 2 else -0.2, speed=0.3)


def move_goal(i: int) -> MoveArm.Goal:
    goal = MoveArm.Goal(position_tolerance=0.002, orientation_tolerance=0.0)
    goal.target.header.frame_id = "world"
    goal.target.pose.position.x, goal.target.pose.position.y, goal.target.pose.position.z = 0.45, -0.1 + 0.01 * (i % 20), 0.3
    goal.target.pose.orientation.w = 1.0
    return goal


CASES = {"walk": ("g1", Walk, "/walk", walk_goal), "move_arm": ("panda", MoveArm, "/move_arm", move_goal)}


@pytest.fixture(scope="module")
def panda():
    """The Panda's bring-up for the Panda's tests of this file (each begins with a reset), started by the first of them:
    the G1's case runs before it, on a bring-up of its own."""
    with running(["bringup", "--robot", "panda", "--rtf", "1"]) as process:
        yield process


def _bringup(robot: str, request: pytest.FixtureRequest) -> contextlib.AbstractContextManager:
    """The G1 on a bring-up of its own; the Panda on the module's, reset to its keyframe."""
    if robot != "panda":
        return running(["bringup", "--robot", robot, "--rtf", "1"])
    request.getfixturevalue("panda")
    return _reset_first()


@contextlib.contextmanager
def _reset_first() -> Iterator[None]:
    with RosSession("burst_reset", use_sim_time=False) as session:
        assert session.call(Reset, "/sim/reset", Reset.Request(), timeout=READY_S).success
    yield


@pytest.mark.parametrize("case", list(CASES))
def test_a_burst_from_two_clients_is_answered_and_ends_once_per_goal(case, request):
    robot, action_type, name, make_goal = CASES[case]
    with _bringup(robot, request), \
         RosSession("burst_a", use_sim_time=False) as first, RosSession("burst_b", use_sim_time=False) as second:
        clients = [(first, ready_client(first, action_type, name, timeout=READY_S)),
                   (second, ready_client(second, action_type, name, timeout=READY_S))]
        sent: list[list] = [[], []]
        errors: list[BaseException] = []

        def burst(index: int) -> None:
            session, action = clients[index]
            try:
                for i in range(GOALS_PER_CLIENT):
                    sent[index].append(send(session, action, make_goal(i), timeout=30.0))
                    time.sleep(1.0 / (2 * GOALS_PER_CLIENT))  # the burst's rhythm: 24 goals in about 1 s
            except BaseException as error:  # noqa: BLE001 - reported by the test below
                errors.append(error)

        started = time.monotonic()
        threads = [threading.Thread(target=burst, args=(i,)) for i in range(2)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join(120.0)
        answered = time.monotonic() - started
        assert not errors, f"a goal request was not answered: {errors[0]}"
        goals = [(session, goal) for (session, _), batch in zip(clients, sent, strict=True) for goal in batch]
        assert len(goals) == 2 * GOALS_PER_CLIENT and all(goal.handle.accepted for _, goal in goals)
        print(f"{case}: {len(goals)} goal requests answered in {answered:.2f} s")
        outcomes = [result(session, goal, timeout=300.0) for session, goal in goals]
        codes = [outcome.result.error_code for outcome in outcomes]
        assert action_type.Result.SIM_FAULT not in codes, [o.result.error_msg for o in outcomes if o.result.error_code]
        ended = [o.status for o in outcomes]
        assert all(status in (GoalStatus.STATUS_SUCCEEDED, GoalStatus.STATUS_ABORTED) for status in ended), ended
        assert codes.count(action_type.Result.SUCCESS) >= 1
        preempted = codes.count(action_type.Result.PREEMPTED)
        assert preempted + codes.count(action_type.Result.SUCCESS) == len(codes), codes


AT_ONCE = 40


def warm_up(session: RosSession, action: ActionClient, attempts: int = 5) -> None:
    """One goal and its result, answered, before a burst: the server's answers to this client are then matched.

    ``server_is_ready`` says the server reads this client's requests; its reply writers may match this
    client's response readers a moment later on a loaded machine, and a response sent before that is lost
    (what a burst sent at once would count as unanswered). A goal whose response is lost is sent again.
    """
    for attempt in range(attempts):
        goal = move_goal(attempt)
        future = session.in_executor(lambda goal=goal: action.send_goal_async(goal))
        if wait_all(session, [future], 10.0) == 1:
            handle = future.result()
            assert handle.accepted
            outcome = session.in_executor(handle.get_result_async)
            assert wait_all(session, [outcome], 120.0) == 1, "the warm-up goal's result"
            return
    raise AssertionError(f"none of {attempts} warm-up goals was answered within 10 s")


def wait_all(session: RosSession, futures: list, timeout: float) -> int:
    """How many of ``futures`` are done once all are, or ``timeout`` wall seconds passed."""
    try:
        session.wait_for(lambda: all(f.done() for f in futures), timeout, "the answers")
    except WaitTimeout:
        pass
    return sum(f.done() for f in futures)


def test_goal_and_result_requests_sent_all_at_once_are_all_answered(request: pytest.FixtureRequest) -> None:
    """40 goal requests in one turn of the client's executor, then their 40 result requests likewise.

    The client keeps 1000 requests and responses (rclpy's default is keep-last 10 on both ends), so
    what is tested is the server: its request readers once kept the last 10, and 11 of 40 were answered.
    """
    deep = QoSProfile(depth=1000)
    with _bringup("panda", request), RosSession("at_once", use_sim_time=False) as session:
        action = ActionClient(session.node, MoveArm, "/move_arm", goal_service_qos_profile=deep,
                              result_service_qos_profile=deep, cancel_service_qos_profile=deep)
        session.wait_for(action.server_is_ready, READY_S, "action server /move_arm")
        warm_up(session, action)
        requests = session.in_executor(lambda: [action.send_goal_async(move_goal(i)) for i in range(AT_ONCE)])
        answered = wait_all(session, requests, 30.0)
        assert answered == AT_ONCE, f"{answered} of {AT_ONCE} goal requests answered within 30 s"
        handles = [f.result() for f in requests]
        assert all(handle.accepted for handle in handles)
        results = session.in_executor(lambda: [handle.get_result_async() for handle in handles])
        answered = wait_all(session, results, 120.0)
        assert answered == AT_ONCE, f"{answered} of {AT_ONCE} result requests answered within 120 s"
        codes = [f.result().result.error_code for f in results]
        # The server takes requests that arrive together in any order: one goal, the last it took, succeeds.
        assert codes.count(MoveArm.Result.SUCCESS) == 1 and codes.count(MoveArm.Result.PREEMPTED) == AT_ONCE - 1, codes
