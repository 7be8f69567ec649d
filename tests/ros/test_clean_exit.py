"""Every node ends cleanly on Ctrl-C: exit code 0 and no traceback, after serving for a while."""

from __future__ import annotations

import re
import signal

import pytest

from sim_interfaces.action import MoveArm
from tests.ros.actions import ready_client
from tests.ros.processes import NodeProcess

STARTUP_S = 60.0
READY = {"sim_node": "active: physics running", "arm_server": "serving /move_arm", "locomotion_server": "serving /walk"}


@pytest.mark.parametrize("robot", ["panda", "g1"])
def test_sim_node_and_servers_exit_cleanly_on_ctrl_c(client, robot):
    commands = [["sim_node", "--ros-args", "-p", f"robot:={robot}"], ["arm_server", "--ros-args", "-p", f"robot:={robot}"]]
    if robot == "g1":
        commands.append(["locomotion_server", "--ros-args", "-p", "robot:=g1"])
    processes = [NodeProcess(command) for command in commands]
    try:
        ready_client(client, MoveArm, "/move_arm", timeout=STARTUP_S)
        client.wait_for(lambda: client.node.count_publishers("/joint_states") > 0, STARTUP_S, "/joint_states")
        # Each of *these* processes serves (the graph can still list a previous test's nodes on this domain).
        client.wait_for(lambda: all(READY[p.args[0]] in p.output() for p in processes), STARTUP_S, "every node serving")
    finally:
        for process in processes:
            process.send_signal(signal.SIGINT)
        # Generous: the test is about a clean exit, not a fast one (two test workers share two cores).
        codes = [process.stop(timeout=30.0) for process in processes]
    outputs = [process.output() for process in processes]
    for process in processes:
        process.discard_log()  # their logs were files of their own in the temporary directory (left behind before)
    for process, code, output in zip(processes, codes, outputs, strict=True):
        assert code == 0, f"{process.args[0]} exited with {code}:\n{output[-3000:]}"
        # An error raised while stopping (e.g. destroying the node), not the interrupt itself: Python may
        # report a KeyboardInterrupt that lands inside a finalizer ("Exception ignored in ...").
        errors = re.findall(r"^[\w.]*(?:Error|Exception):.*$", output, re.MULTILINE)
        assert not errors, f"{process.args[0]} raised on Ctrl-C: {errors}\n{output[-3000:]}"
