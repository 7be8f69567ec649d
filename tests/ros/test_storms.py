"""Storms: three clients send, cancel and preempt at random; one end per goal, no hung client, a robot standing.

Each client is a node of its own, in a thread of its own, doing rounds of: send a goal; then at random
cancel it at once, cancel it a little later, or leave it to be preempted by the next goal (of any
client). Every goal must end with a terminal status whose result code agrees with it, and nothing
may end SIM_FAULT. Afterwards the G1 stands (or the Panda holds still) and a new goal succeeds.
"""

from __future__ import annotations

import random
import threading
import time

import pytest
from action_msgs.msg import GoalStatus
from nav_msgs.msg import Odometry

from nodes.servers.protocol import result_codes
from sim_client import RosSession
from sim_interfaces.action import MoveArm, Walk
from tests.ros.actions import ready_client, result, send
from tests.ros.processes import running
from tests.ros.test_bursts import move_goal, walk_goal

pytestmark = pytest.mark.slow

CLIENTS = 3
ROUNDS = 8
READY_S = 90.0
CASES = {"walk": ("g1", Walk, "/walk", walk_goal), "move_arm": ("panda", MoveArm, "/move_arm", move_goal)}
AGREES = {GoalStatus.STATUS_SUCCEEDED: ("SUCCESS",), GoalStatus.STATUS_CANCELED: ("CANCELED",),
          GoalStatus.STATUS_ABORTED: ("PREEMPTED", "INVALID_GOAL", "TIMEOUT", "UNREACHABLE", "FELL")}


@pytest.mark.parametrize("case", list(CASES))
def test_a_storm_of_send_cancel_and_preempt_from_three_clients(case, client):
    robot, action_type, name, make_goal = CASES[case]
    names = result_codes(action_type)
    with running(["bringup", "--robot", robot, "--rtf", "0"]):
        sessions = [RosSession(f"storm_{i}", use_sim_time=False) for i in range(CLIENTS)]
        try:
            actions = [ready_client(session, action_type, name, timeout=READY_S) for session in sessions]
            goals: list[tuple[RosSession, object]] = []
            errors: list[BaseException] = []
            lock = threading.Lock()

            def storm(index: int) -> None:
                rng = random.Random(index)  # the same storm every run
                session, action = sessions[index], actions[index]
                try:
                    for i in range(ROUNDS):
                        sent = send(session, action, make_goal(i + 10 * index), timeout=30.0)
                        with lock:
                            goals.append((session, sent))
                        move = rng.choice(("cancel_now", "cancel_later", "leave"))
                        if move != "leave" and sent.handle.accepted:
                            if move == "cancel_later":
                                time.sleep(rng.uniform(0.05, 0.3))  # the storm's rhythm, not a wait for something
                            sent.cancel(timeout=30.0)
                except BaseException as error:  # noqa: BLE001 - reported by the test below
                    errors.append(error)

            threads = [threading.Thread(target=storm, args=(i,)) for i in range(CLIENTS)]
            for thread in threads:
                thread.start()
            for thread in threads:
                thread.join(300.0)
            assert not errors, f"a request was not answered: {errors[0]!r}"
            assert len(goals) == CLIENTS * ROUNDS
            for session, sent in goals:
                assert sent.handle.accepted
                outcome = result(session, sent, timeout=300.0)  # never hangs: bounded, and it must come
                code = names.get(outcome.result.error_code, str(outcome.result.error_code))
                assert code in AGREES.get(outcome.status, ()), (outcome.status, code, outcome.result.error_msg)
                assert code != "SIM_FAULT"
        finally:
            for session in sessions:
                session.close()
        final = result(client, send(client, ready_client(client, action_type, name, timeout=READY_S), make_goal(0)),
                       timeout=300.0)
        assert final.status == GoalStatus.STATUS_SUCCEEDED, final.result.error_msg
        if robot == "g1":
            odom = client.record(Odometry, "/odom", keep=10)
            client.wait_for(lambda: odom.count > 0, 30.0, "/odom")
            assert odom.latest.pose.pose.position.z > 0.6, "the G1 stands after the storm"
