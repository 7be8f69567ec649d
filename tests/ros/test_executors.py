"""The nodes' executors: rclpy's events executor (the device nodes'), spun so that a callback that raises does not end
the node, and the servers' :class:`~nodes.runtime.executor.ServerExecutor`, which follows ``/clock`` in its own thread.

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


def _run(script: str) -> subprocess.CompletedProcess[str]:
    """Run ``script`` in a Python process of its own, from the project's root."""
    return subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120,
                          env=dict(os.environ), cwd=os.path.dirname(os.path.dirname(os.path.dirname(__file__))))


def test_a_callback_that_raises_is_logged_and_the_events_executor_spins_on():
    done = _run(SCRIPT)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "timer calls: 3" in done.stdout, done.stdout + done.stderr
    assert "a callback raised; the node keeps serving" in done.stderr and "a malformed request" in done.stderr, done.stderr


SERVER_SCRIPT = textwrap.dedent("""
    import threading
    import time

    import rclpy
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from builtin_interfaces.msg import Time
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import Empty

    from nodes.runtime.executor import ServerExecutor

    rclpy.init()
    node = Node("server", parameter_overrides=[Parameter("use_sim_time", value=True)])
    source = Node("source")
    clock_pub = source.create_publisher(Clock, "/clock", 10)
    ping_pub = source.create_publisher(Empty, "ping", 10)
    seen = {"clock": set(), "ping": set()}
    node.create_subscription(Clock, "/clock", lambda _msg: seen["clock"].add(threading.get_ident()), 10)
    node.create_subscription(Empty, "ping", lambda _msg: seen["ping"].add(threading.get_ident()), 10)
    executor = ServerExecutor(num_threads=2)
    executor.add_node(node)
    deadline, seconds = time.monotonic() + 30.0, 0
    while time.monotonic() < deadline and (node.get_clock().now().nanoseconds < 5_000_000_000 or not seen["ping"]):
        seconds += 1
        clock_pub.publish(Clock(clock=Time(sec=seconds)))
        ping_pub.publish(Empty())
        executor.spin_once(timeout_sec=0.05)
    main = threading.get_ident()
    print("sim time:", node.get_clock().now().nanoseconds // 1_000_000_000, flush=True)
    print("clock in the spinning thread:", seen["clock"] == {main}, flush=True)
    print("ping in a pool thread:", bool(seen["ping"]) and main not in seen["ping"], flush=True)
    executor.shutdown()
    node.destroy_node()
    source.destroy_node()
    rclpy.try_shutdown()
""")


def test_the_server_executor_follows_clock_in_its_own_thread_and_runs_other_callbacks_on_its_pool():
    done = _run(SERVER_SCRIPT)
    assert done.returncode == 0, done.stdout + done.stderr
    lines = done.stdout.splitlines()
    assert int(lines[0].split(":")[1]) >= 5, done.stdout  # the node's sim-time clock followed /clock
    assert "clock in the spinning thread: True" in lines and "ping in a pool thread: True" in lines, done.stdout
