"""Nodes on two hosts over DDS: the sim and its servers in one Linux network namespace, a client in another,
joined by a veth pair, discovery by ``ROS_STATIC_PEERS`` and UDP only (shared memory would bypass the
network: both namespaces share this kernel's /dev/shm). The client walks the robot and reads /joint_states.

Creating network namespaces needs CAP_NET_ADMIN (root here); without it the test is skipped, saying so."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import uuid

import pytest

from sim_ros.processes import BIN

pytestmark = pytest.mark.slow

SIM_ADDRESS, CLIENT_ADDRESS = "10.231.7.1", "10.231.7.2"

CLIENT = r"""
import json, math
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState
from sim_client import RosSession
from sim_client.actions import WalkClient
with RosSession("remote_client") as session:
    joints = session.record(JointState, "joint_states", keep=10)
    odom = session.record(Odometry, "odom", keep=10)
    session.wait_for(lambda: joints.count > 0 and odom.count > 0, 120.0, "/joint_states and /odom over the veth")
    start = odom.latest.pose.pose.position
    walk = WalkClient(session)
    walk.wait_for_server(timeout=120.0)
    outcome = walk.send(WalkClient.goal(0.3, 0.3)).wait(timeout=240.0)
    session.wait_for(lambda: odom.latest.header.stamp.sec >= int(walk.sim_now()), 60.0, "/odom up to now")
    end = odom.latest.pose.pose.position
    print(json.dumps({"joints": len(joints.latest.name), "status": str(outcome.status),
                      "moved": math.hypot(end.x - start.x, end.y - start.y)}))
"""


def _ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True, capture_output=True, text=True, timeout=30)


@pytest.fixture()
def two_hosts():
    tag = uuid.uuid4().hex[:6]
    sim_ns, client_ns = f"simhost{tag}", f"clienthost{tag}"
    try:
        _ip("netns", "add", sim_ns)
    except (OSError, subprocess.CalledProcessError) as error:
        pytest.skip(f"this machine cannot create network namespaces (needs CAP_NET_ADMIN): {error}")
    try:
        _ip("netns", "add", client_ns)
        _ip("link", "add", f"v{tag}a", "type", "veth", "peer", "name", f"v{tag}b")
        _ip("link", "set", f"v{tag}a", "netns", sim_ns)
        _ip("link", "set", f"v{tag}b", "netns", client_ns)
        for ns, dev, address in ((sim_ns, f"v{tag}a", SIM_ADDRESS), (client_ns, f"v{tag}b", CLIENT_ADDRESS)):
            _ip("-n", ns, "addr", "add", f"{address}/24", "dev", dev)
            _ip("-n", ns, "link", "set", dev, "up")
            _ip("-n", ns, "link", "set", "lo", "up")
        yield sim_ns, client_ns
    finally:
        for ns in (sim_ns, client_ns):
            subprocess.run(["ip", "netns", "del", ns], capture_output=True, timeout=30)


def _env(peer: str) -> dict[str, str]:
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="SUBNET", ROS_STATIC_PEERS=peer,
               FASTDDS_BUILTIN_TRANSPORTS="UDPv4")
    return env


def test_a_client_on_another_host_walks_the_robot_over_dds(two_hosts):
    sim_ns, client_ns = two_hosts
    sim = subprocess.Popen(["ip", "netns", "exec", sim_ns, str(BIN / "bringup"), "--robot", "g1", "--rtf", "1"],
                           env=_env(CLIENT_ADDRESS), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           start_new_session=True)
    try:
        client = subprocess.run(["ip", "netns", "exec", client_ns, sys.executable, "-c", CLIENT], env=_env(SIM_ADDRESS),
                                capture_output=True, text=True, timeout=400)
        assert client.returncode == 0, client.stdout[-2000:] + client.stderr[-3000:]
        answer = json.loads(client.stdout.strip().splitlines()[-1])
        assert answer["joints"] >= 29, answer
        assert answer["status"] == "SUCCEEDED", answer
        assert answer["moved"] == pytest.approx(0.3, abs=0.05), answer
    finally:
        os.killpg(sim.pid, signal.SIGINT)
        try:
            sim.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(sim.pid, signal.SIGKILL)
            sim.wait()
