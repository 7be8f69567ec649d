"""The device nodes' executor: rclpy's events executor, spun so that a callback that raises does not end the node.

Run in a process of its own: the events executor is C++ code that stays loaded (and enables faulthandler) in
whatever process made it, and a test worker runs many other tests after this one."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

SCRIPT = textwrap.dedent("""
    import time
    import rclpy
    from rclpy.node import Node
    from nodes.runtime.executor import events_executor, spin_once_logging

    rclpy.init()
    node = Node("raising")
    calls = []

    def tick():
        calls.append(time.monotonic())
        if len(calls) == 1:
            raise ValueError("a malformed request")

    node.create_timer(0.01, tick)
    executor = events_executor()
    executor.add_node(node)
    deadline = time.monotonic() + 30.0
    while len(calls) < 3 and time.monotonic() < deadline:
        spin_once_logging(executor, node, timeout_sec=0.05)
    print("timer calls:", len(calls), flush=True)
    executor.shutdown()
    node.destroy_node()
    rclpy.try_shutdown()
""")


def test_a_callback_that_raises_is_logged_and_the_events_executor_spins_on():
    done = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=120,
                          env=dict(os.environ), cwd=os.path.dirname(os.path.dirname(os.path.dirname(__file__))))
    assert done.returncode == 0, done.stdout + done.stderr
    assert "timer calls: 3" in done.stdout, done.stdout + done.stderr
    assert "a callback raised; the node keeps serving" in done.stderr and "a malformed request" in done.stderr, done.stderr
