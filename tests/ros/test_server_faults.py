"""No client hangs: a goal ends with a result when /sim dies or its server stops; a paused sim is not a dead one.

The sim node and the locomotion server run as separate processes here (not under bringup, which
would stop every node when one dies), so each can be killed on its own.
"""

from __future__ import annotations

import signal
import time

import pytest
from action_msgs.msg import GoalStatus
from std_srvs.srv import Trigger

from nodes.servers.server import SIM_SILENCE_S
from sim_interfaces.action import Walk
from sim_ros.processes import ChildProcess
from sim_ros.session import WaitTimeout
from tests.ros.actions import ready_client, result, send, wait_feedback

pytestmark = pytest.mark.slow

READY_S = 90.0
END_WALL_S = 30.0  # a generous bound on a loaded machine; the latency itself is printed, not asserted


def walk_goal(distance: float = -2.0) -> Walk.Goal:
    return Walk.Goal(distance=distance, speed=0.3)


def first_goal(client, walk, goal: Walk.Goal | None = None):
    """The first goal to a server that has just started: a request sent before the server's side of
    discovery has matched this client is lost (the client already sees the server), so it is sent
    again after a while; a goal that did arrive twice is preempted by the second."""
    for _ in range(6):
        try:
            sent = send(client, walk, goal or walk_goal(), timeout=5.0)
        except WaitTimeout:
            continue
        assert sent.handle.accepted
        return sent
    raise AssertionError("the walk goal was never answered")


@pytest.fixture
def nodes(tmp_path):
    started: list[ChildProcess] = []

    def start(*args: str) -> ChildProcess:
        process = ChildProcess(list(args), tmp_path / f"{len(started)}")
        started.append(process)
        return process

    yield start
    for process in reversed(started):
        process.stop(timeout=30.0)


def test_a_goal_ends_sim_fault_when_the_sim_dies_and_the_server_serves_the_next_sim(client, nodes):
    sim = nodes("sim_node", "--ros-args", "-p", "robot:=g1")
    nodes("locomotion_server", "--ros-args", "-p", "robot:=g1")
    walk = ready_client(client, Walk, "/walk", timeout=READY_S)
    sent = send(client, walk, walk_goal())
    assert sent.handle.accepted
    wait_feedback(client, sent, lambda f: True, READY_S, "walk feedback")
    killed = time.monotonic()
    sim.send_signal(signal.SIGKILL)
    outcome = result(client, sent, timeout=END_WALL_S)
    latency = time.monotonic() - killed
    print(f"goal ended {latency:.2f} s (wall) after SIGKILL of /sim (silence bound {SIM_SILENCE_S} s)")
    assert outcome.status == GoalStatus.STATUS_ABORTED
    assert outcome.result.error_code == Walk.Result.SIM_FAULT and "stopped answering" in outcome.result.error_msg

    fresh = nodes("sim_node", "--ros-args", "-p", "robot:=g1")  # a new sim: the same server serves it
    client.wait_for(lambda: "active: physics running" in fresh.output(), READY_S, "the new /sim")
    again = send(client, walk, walk_goal(-0.5))
    assert again.handle.accepted
    final = result(client, again, timeout=120.0)
    assert final.status == GoalStatus.STATUS_SUCCEEDED, final.result.error_msg


def test_a_paused_sim_keeps_its_goals_and_a_stopped_server_ends_them(client, nodes):
    nodes("sim_node", "--ros-args", "-p", "robot:=g1")
    server = nodes("locomotion_server", "--ros-args", "-p", "robot:=g1")
    walk = ready_client(client, Walk, "/walk", timeout=READY_S)
    sent = first_goal(client, walk)
    wait_feedback(client, sent, lambda f: True, READY_S, "walk feedback")
    # Pausing twice is pausing: resend if the first answer of a /sim just started is lost (its reply writer
    # had not matched this client yet; rmw_fastrtps then drops the response after 100 ms).
    assert client.call(Trigger, "/sim/pause", Trigger.Request(), timeout=READY_S, resend_every_s=5.0).success
    paused_at = time.monotonic()
    # Paused for three times the silence bound: the goal must still be running (the sim answers).
    with pytest.raises(WaitTimeout):
        client.wait_for(lambda: sent.result_future().done(), 3 * SIM_SILENCE_S, "no result while paused")
    assert time.monotonic() - paused_at >= 3 * SIM_SILENCE_S
    assert client.call(Trigger, "/sim/resume", Trigger.Request(), timeout=READY_S).success
    count = len(sent.feedback)
    client.wait_for(lambda: len(sent.feedback) > count + 1, READY_S, "feedback after resume")

    server.send_signal(signal.SIGINT)  # Ctrl-C of the server while the walk runs
    outcome = result(client, sent, timeout=END_WALL_S)
    assert outcome.status == GoalStatus.STATUS_ABORTED
    assert "shutting down" in outcome.result.error_msg
    assert server.process.wait(timeout=30.0) == 0


def test_a_server_started_before_the_sim_waits_for_it_and_says_so(client, nodes):
    server = nodes("locomotion_server")  # no robot given: it asks /sim, which is not there yet
    client.wait_for(lambda: "waiting for /sim" in server.output(), READY_S, "the server to say it waits for /sim")
    assert server.alive()
    nodes("sim_node", "--ros-args", "-p", "robot:=g1")
    client.wait_for(lambda: "serving /walk" in server.output(), READY_S, "the server to serve once /sim is up")
    walk = ready_client(client, Walk, "/walk", timeout=READY_S)
    outcome = result(client, first_goal(client, walk, walk_goal(-0.5)), timeout=120.0)  # a short walk: served
    assert outcome.status == GoalStatus.STATUS_SUCCEEDED, outcome.result.error_msg
