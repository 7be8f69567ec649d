"""bringup restarts a node that dies, as a launch file's respawn does; the servers serve the restarted sim."""

from __future__ import annotations

import os
import signal

import pytest
from action_msgs.msg import GoalStatus

from nodes.processes import ChildProcess, child_processes
from sim_interfaces.action import Walk
from tests.ros.actions import ready_client, result, send, wait_feedback

pytestmark = pytest.mark.slow

READY_S = 90.0


def child_pid(parent: int, executable: str) -> int | None:
    """The pid of ``parent``'s child process running ``executable``, if any."""
    return child_processes(parent).get(executable)


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
