"""Bursts of goals: 24 goals from 2 clients within about 1 s; every request answered, one end per goal.

Each client is a node of its own (its own ROS context). A new goal preempts the running one, so all
but the last end PREEMPTED; none may end with a false SIM_FAULT, and the last one succeeds.
"""

from __future__ import annotations

import threading
import time

import pytest
from action_msgs.msg import GoalStatus

from sim_client import RosSession
from sim_interfaces.action import MoveArm, Walk
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


@pytest.mark.parametrize("case", list(CASES))
def test_a_burst_from_two_clients_is_answered_and_ends_once_per_goal(case):
    robot, action_type, name, make_goal = CASES[case]
    with running(["bringup", "--robot", robot, "--rtf", "1"]), \
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
