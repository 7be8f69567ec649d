"""bringup restarts a node that dies, as a launch file's respawn does; the servers serve the restarted sim, and the
clients of a server that died get their results from bringup."""

from __future__ import annotations

import contextlib
import os
import pathlib
import signal
import time

import pytest
from action_msgs.msg import GoalStatus
from action_msgs.srv import CancelGoal
from rcl_interfaces.srv import ListParameters

from sim_interfaces.action import MoveArm, Walk
from sim_ros.processes import ChildProcess, child_processes
from sim_ros.session import RESPONSE_QOS, RosSession, WaitTimeout
from tests.ros.actions import action_client, ready_client, result, send, wait_feedback
from tests.ros.test_arm_server import move_goal

pytestmark = pytest.mark.slow

READY_S = 90.0
RESENDS_PER_CLIENT = 3  # goals (10 s each) a client sends to a restarted server before one in a new participant does


def child_pid(parent: int, executable: str) -> int | None:
    """The pid of ``parent``'s child process running ``executable``, if any."""
    return child_processes(parent).get(executable)


def transports_of(pid: int | None) -> str | None:
    """The Fast DDS built-in transports a process was started with (its FASTDDS_BUILTIN_TRANSPORTS), if named."""
    assert pid is not None
    entries = pathlib.Path(f"/proc/{pid}/environ").read_bytes().split(b"\0")
    named = [entry.split(b"=", 1)[1].decode() for entry in entries if entry.startswith(b"FASTDDS_BUILTIN_TRANSPORTS=")]
    return named[0] if named else None


def test_a_killed_sim_is_reported_restarted_from_its_keyframe_and_served_again(client, tmp_path):
    bringup = ChildProcess(["bringup", "--robot", "g1", "--respawn-delay", "0.2"], tmp_path)
    try:
        walk = ready_client(client, Walk, "/walk", timeout=READY_S)
        sent = send(client, walk, Walk.Goal(distance=-2.0, speed=0.3))
        wait_feedback(client, sent, lambda f: True, READY_S, "walk feedback")
        first = child_pid(bringup.process.pid, "sim_node")
        assert first is not None
        os.kill(first, signal.SIGKILL)
        outcome = result(client, sent, timeout=60.0)  # ended by the server: /sim went silent
        assert outcome.status == GoalStatus.STATUS_ABORTED and outcome.result.error_code == Walk.Result.SIM_FAULT

        def restarted() -> bool:
            pid = child_pid(bringup.process.pid, "sim_node")
            return pid is not None and pid != first and "active: physics running" in bringup.output().split(
                "restarting sim_node")[-1]

        client.wait_for(restarted, READY_S, "bringup to restart sim_node")
        assert transports_of(child_pid(bringup.process.pid, "sim_node")) == "UDPv4"  # no shared-memory port of its own
        log = bringup.output()
        assert "sim_node died with exit code -9" in log and "restarting sim_node (it starts from its keyframe)" in log
        again = send(client, walk, Walk.Goal(distance=-0.5, speed=0.3))
        assert again.handle.accepted
        final = result(client, again, timeout=120.0)
        assert final.status == GoalStatus.STATUS_SUCCEEDED, final.result.error_msg
        assert final.result.final_distance == pytest.approx(-0.5, abs=0.05)
        assert bringup.alive()
    finally:
        assert bringup.stop(timeout=30.0) == 0


@pytest.fixture
def client():
    """A client of each test's own (a DDS participant made after the earlier tests' kills).

    Every test here kills a node with SIGKILL. Fast DDS's shared-memory port of a killed process stays broken for
    the processes that had used it (eProsima/Fast-DDS#5469), and the next bring-up's processes take the freed ports:
    a module-wide client once reached nothing of the next test's bringup.
    """
    with RosSession("test_client", use_sim_time=False) as session:
        yield session


def bringup_has_matched(client: RosSession) -> None:
    """Wait until bringup has matched every endpoint ``client`` has made so far.

    DDS delivers a request only to the servers that had matched its writer when it was sent, and bringup can answer
    only the requests it received: in CI bringup once kept none of a client's requests while the server had them
    all (that client had talked to a node killed in an earlier test). A request to bringup from a service client
    made now is announced after every endpoint made before it: once bringup answers it, it has matched them all.
    """
    probe = client.in_executor(lambda: client.node.create_client(ListParameters, "/bringup/list_parameters",
                                                                  qos_profile=RESPONSE_QOS), what="a new client")
    try:
        client.wait_for(probe.service_is_ready, READY_S, "bringup's parameter services")
        client.until_answered(lambda: probe.call_async(ListParameters.Request()), READY_S, "bringup's parameter list")
    finally:
        client.in_executor(lambda: client.node.destroy_client(probe), what="destroying the client")


KILLED_SERVERS = {  # robot, the server's executable, its action, a goal that runs for seconds, a short one
    "locomotion_server": ("g1", Walk, "/walk", Walk.Goal(distance=3.0, speed=0.3), Walk.Goal(distance=0.3, speed=0.3)),
    "arm_server": ("panda", MoveArm, "/move_arm", move_goal(0.5, 0.3, 0.3, scaling=0.05), move_goal(0.5, -0.3, 0.3)),
}


@pytest.mark.parametrize("executable", sorted(KILLED_SERVERS))
def test_a_client_of_a_killed_server_gets_a_result_and_the_restarted_server_serves(client, tmp_path, executable):
    robot, action_type, name, long_goal, short_goal = KILLED_SERVERS[executable]
    # The restart waits 2 s: the cancel below must reach the keeper before a restarted server could answer it.
    bringup = ChildProcess(["bringup", "--robot", robot, "--respawn-delay", "2.0"], tmp_path)
    stack = contextlib.ExitStack()
    try:
        action = ready_client(client, action_type, name, timeout=READY_S)
        bringup_has_matched(client)
        sent = send(client, action, long_goal)
        assert sent.handle.accepted
        wait_feedback(client, sent, lambda f: True, READY_S, f"{name} feedback")
        first = child_pid(bringup.process.pid, executable)
        assert first is not None
        os.kill(first, signal.SIGKILL)
        # The ROS action protocol answers a result only from the goal's server; bringup answers for a dead one.
        try:
            outcome = result(client, sent, timeout=30.0)
        except WaitTimeout as timeout:
            raise AssertionError(f"{timeout}; bringup's last output:\n{bringup.output()[-6000:]}") from timeout
        assert outcome.status == GoalStatus.STATUS_ABORTED
        assert outcome.result.error_code == action_type.Result.SIM_FAULT
        assert f"({executable}) died with exit code -9" in outcome.result.error_msg
        assert sent.cancel().return_code == CancelGoal.Response.ERROR_GOAL_TERMINATED  # a cancel is answered too

        client.wait_for(lambda: child_pid(bringup.process.pid, executable) not in (None, first), READY_S,
                        f"bringup to restart {executable}")
        assert transports_of(child_pid(bringup.process.pid, executable)) == "UDPv4"
        assert transports_of(child_pid(bringup.process.pid, "sim_node")) is None  # the others keep shared memory
        restarted_at = time.monotonic()
        log = bringup.output()
        assert f"{executable} died with exit code -9" in log and f"waiting on {executable}'s goals" in log

        sessions = [client]
        clients = [action]

        def next_goal_succeeds() -> bool:  # the restarted server may not be discovered yet: send again until taken
            try:
                again = send(sessions[-1], clients[-1], short_goal, timeout=10.0)
            except WaitTimeout:
                # On a loaded machine a restarted server once took none of this client's goals for 3 min. The client's
                # process had talked to the killed one, whose DDS port the restarted process may take, and Fast DDS's
                # shared-memory port of a killed process stays broken for the processes that used it
                # (eProsima/Fast-DDS#5469). A client in a new process-level participant (a new context) is not.
                if len(clients) * 10.0 * RESENDS_PER_CLIENT < time.monotonic() - restarted_at:
                    sessions.append(stack.enter_context(RosSession(f"test_client_{len(sessions)}", use_sim_time=False)))
                    clients.append(action_client(sessions[-1], action_type, name))
                return False
            if not again.handle.accepted:
                return False
            final = result(sessions[-1], again, timeout=120.0)
            assert final.status == GoalStatus.STATUS_SUCCEEDED, final.result.error_msg
            return True

        try:
            client.wait_for(next_goal_succeeds, 2 * READY_S, f"a goal to the restarted {executable} to succeed", poll=1.0)
        except WaitTimeout as timeout:
            raise AssertionError(f"{timeout}; bringup's last output:\n{bringup.output()[-6000:]}") from timeout
        assert bringup.alive()
    finally:
        stack.close()
        assert bringup.stop(timeout=30.0) == 0
