"""Isolation as the README states it: a node on another ROS domain sees nothing of ours; on ours it does."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

from tests.ros.processes import running

# Looks at the graph and listens to /clock for a fixed window (an observation, not a wait for something),
# then prints what it saw.
PROBE = textwrap.dedent("""
    import time, rclpy
    from rosgraph_msgs.msg import Clock
    rclpy.init()
    node = rclpy.create_node("isolation_probe")
    got = []
    node.create_subscription(Clock, "/clock", got.append, 10)
    end = time.monotonic() + float(__import__("sys").argv[1])
    while time.monotonic() < end and not got:
        rclpy.spin_once(node, timeout_sec=0.1)
    topics = sorted(name for name, _ in node.get_topic_names_and_types())
    nodes = sorted(node.get_node_names())
    print(f"clock={len(got)} nodes={nodes} topics={topics}")
""")


def probe(domain: str, window_s: float) -> str:
    env = dict(os.environ, ROS_DOMAIN_ID=domain)
    done = subprocess.run([sys.executable, "-c", PROBE, str(window_s)], env=env, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout.strip()


def test_a_node_on_another_domain_sees_nothing_of_ours():
    ours = os.environ["ROS_DOMAIN_ID"]
    other = str(1 + (int(ours) + 49) % 101)  # a valid domain id far from ours and from the other test workers'
    with running(["sim_node", "--ros-args", "-p", "robot:=panda"]):
        same = probe(ours, 60.0)  # on our domain it hears /clock (and stops looking as soon as it does)
        assert "clock=0" not in same and "'/joint_states'" in same, same
        elsewhere = probe(other, 8.0)  # the same look, on another domain, for a fixed window
        assert "clock=0" in elsewhere and "'sim'" not in elsewhere and "/joint_states" not in elsewhere, elsewhere
