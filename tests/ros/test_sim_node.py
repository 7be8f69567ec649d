"""End-to-end tests of the /sim node, from a client in another process over Fast DDS."""

from __future__ import annotations

import itertools
import math
import os
import pathlib
import time

import numpy as np
import pytest
from nav_msgs.msg import Odometry
from rcl_interfaces.srv import DescribeParameters
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from tf2_msgs.msg import TFMessage

import robot_models
from robot_models import g1_constants
from sim_interfaces.srv import Reset, Step
from tests.ros.actions import sim_now as sim_at
from tests.ros.processes import running

STARTUP_S = 60.0


def stamp_s(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def clock_s(msg: Clock) -> float:
    return msg.clock.sec + msg.clock.nanosec * 1e-9


@pytest.fixture(scope="module")
def g1(client):
    with running(["sim_node", "--ros-args", "-p", "robot:=g1"]) as process:  # real time: a Python client keeps up
        clock = client.record(Clock, "/clock", keep=20_000)
        client.wait_for(lambda: clock.count > 0 or not process.alive(), STARTUP_S, "first /clock from the G1 sim node")
        assert process.alive(), process.output()
        yield process


def measured_rate(recorder, count: int, client, since: float = -math.inf) -> tuple[float, list]:
    """Rate [Hz of sim time] of the next ``count`` messages stamped after ``since`` [s of sim time], from their
    stamps (messages still queued from before, e.g. before a rate change, are not counted)."""
    recorder.clear()

    def fresh() -> list:
        return [m for m in recorder.messages() if stamp_s(m) > since]

    client.wait_for(lambda: len(fresh()) >= count, 60.0, f"{count} messages")
    messages = fresh()[:count]
    stamps = [stamp_s(m) for m in messages]
    return (len(stamps) - 1) / (stamps[-1] - stamps[0]), messages


def test_a_sim_node_started_directly_runs_every_thread_under_the_normal_policy(g1):
    """Only a lock-stepped bring-up's threads are SCHED_BATCH (sim_ros.scheduling; tests/ros/test_scheduling.py)."""
    if not hasattr(os, "SCHED_BATCH"):
        pytest.skip("Linux scheduling policies")
    tasks = pathlib.Path(f"/proc/{g1.process.pid}/task")
    policies = {(t / "comm").read_text().strip() + f"/{t.name}": os.sched_getscheduler(int(t.name)) for t in tasks.iterdir()}
    assert any(name.startswith("dds.") for name in policies) and set(policies.values()) == {os.SCHED_OTHER}, policies


def test_joint_states_arrive_at_the_configured_rate_stamped_with_sim_time(client, g1):
    # A deep queue (5 s at 200 Hz): a subscriber starved for a moment on a loaded machine still gets every message.
    joints = client.record(JointState, "/joint_states", qos=1000, keep=5000)
    clock = client.record(Clock, "/clock", keep=5000)
    rate, messages = measured_rate(joints, 400, client)
    assert rate == pytest.approx(200.0, rel=0.04)
    assert list(messages[-1].name) == list(g1_constants.ALL_JOINTS)
    stamps = [stamp_s(m) for m in messages]
    assert all(b > a for a, b in itertools.pairwise(stamps)), "stamps must increase"
    latest_clock = clock_s(clock.latest)
    assert stamps[-1] < 1e6, "stamps are sim time, not wall-clock epoch time"
    assert abs(latest_clock - stamps[-1]) < 5.0
    assert all(math.isfinite(v) for v in messages[-1].position)

    ok, reason = client.set_parameter("sim", "joint_state_rate", 100.0)
    assert ok, reason
    try:
        # Judged on messages stamped after the change: on a loaded machine the queue still holds 200 Hz ones.
        rate, _ = measured_rate(joints, 200, client, since=sim_at(client, "g1"))
        assert rate == pytest.approx(100.0, rel=0.04)
    finally:
        assert client.set_parameter("sim", "joint_state_rate", 200.0)[0]


def test_odom_and_tf_describe_the_standing_robot(client, g1):
    odom = client.record(Odometry, "/odom")
    tf = client.record(TFMessage, "/tf", keep=2000)
    client.wait_for(lambda: odom.count > 3, 30.0, "/odom")
    msg = odom.latest
    assert msg.header.frame_id == "odom" and msg.child_frame_id == g1_constants.ROOT_BODY
    assert 0.65 < msg.pose.pose.position.z < 0.85, "the G1 pelvis stands at about 0.76 m"

    def frames():
        return {(t.header.frame_id, t.child_frame_id) for m in tf.messages() for t in m.transforms}

    client.wait_for(lambda: ("odom", "pelvis") in frames() and ("pelvis", "left_hip_pitch_link") in frames(), 30.0, "/tf frames")
    children = {child for _, child in frames()}
    assert g1_constants.LEFT_FOOT_BODY in children and g1_constants.RIGHT_HAND_BODY in children


def test_clock_follows_the_real_time_factor(client, g1):
    clock = client.record(Clock, "/clock", keep=50_000)

    def factor(window_s: float) -> float:
        client.wait_for(lambda: clock.count > 0, 10.0, "/clock")
        sim0, wall0 = clock_s(clock.latest), time.monotonic()
        client.wait_for(lambda: time.monotonic() - wall0 >= window_s, window_s + 5.0, "measurement window")
        return (clock_s(clock.latest) - sim0) / (time.monotonic() - wall0)

    assert client.set_parameter("sim", "real_time_factor", 1.0)[0]
    try:
        paced = factor(3.0)
        assert 0.75 < paced < 1.1, f"at real_time_factor 1 the clock ran {paced:.2f}x"
        assert client.set_parameter("sim", "real_time_factor", 0.0)[0]
        unpaced = factor(2.0)
        assert unpaced > 2.0 * paced, f"as fast as possible ran only {unpaced:.2f}x"
    finally:
        client.set_parameter("sim", "real_time_factor", 1.0)


@pytest.mark.parametrize(
    ("name", "value", "reason_must_mention"),
    [
        ("real_time_factor", -1.0, "0.0"),  # below the range: the reason states the range
        ("joint_state_rate", 5000.0, "500"),  # above the range
        ("joint_state_rate", -3.0, "1.0"),  # a negative rate
        ("joint_state_rate", "fast", "type"),  # wrong type
        ("real_time_factor", 1, "type"),  # an integer for a double
        ("robot", "panda", "read-only"),  # read-only parameter
    ],
)
def test_bad_parameter_values_are_refused_with_a_reason_and_the_node_keeps_running(
    client, g1, name, value, reason_must_mention
):
    ok, reason = client.set_parameter("sim", name, value)
    assert not ok
    assert reason_must_mention.lower() in reason.lower(), reason
    clock = client.record(Clock, "/clock")
    client.wait_for(lambda: clock.count > 5, 20.0, "/clock after a refused parameter")
    assert g1.alive()


def test_parameters_are_described_with_ranges(client, g1):
    response = client.call(DescribeParameters, "/sim/describe_parameters",
                           DescribeParameters.Request(names=["real_time_factor", "joint_state_rate", "robot"]))
    rtf, rate, robot = response.descriptors
    assert rtf.floating_point_range[0].from_value == 0.0 and rtf.description
    assert rate.floating_point_range[0].to_value == 500.0
    assert robot.read_only


def test_reset_restores_the_keyframe_exactly_and_time_keeps_running(client, g1):
    keyframe = robot_models.load("g1").model.key("stand")
    model = robot_models.load("g1").model
    expected = np.array([keyframe.qpos[model.joint(j).qposadr[0]] for j in g1_constants.ALL_JOINTS])
    # Deep queues: a test process starved for a moment must not drop the message of the reset instant.
    joints = client.record(JointState, "/joint_states", qos=1000, keep=20_000)
    clock = client.record(Clock, "/clock", qos=1000, keep=50_000)
    client.wait_for(lambda: joints.count > 50, 20.0, "/joint_states")
    before = np.array(joints.latest.position)
    assert np.abs(before - expected).max() > 1e-6, "the standing robot has settled away from the keyframe"

    response = client.call(Reset, "/sim/reset", Reset.Request())
    assert response.success, response.message
    # The sim runs on: once a later joint state is in, every one stamped with the reset instant is too (a reliable
    # reader gets them in order). Waiting for the first one stamped so was not enough: a reset at a publication
    # stop follows the state published there with the same stamp, and on a loaded machine the test once took that one.
    client.wait_for(lambda: joints.count > 0 and stamp_s(joints.latest) > response.sim_time + 1e-9, 20.0,
                    "a joint state after the reset instant")
    # The last message stamped with the reset instant is the one published after the reset.
    at_reset = [m for m in joints.messages() if abs(stamp_s(m) - response.sim_time) < 1e-9][-1]
    np.testing.assert_allclose(np.array(at_reset.position), expected, atol=1e-9)
    client.wait_for(lambda: clock_s(clock.latest) > response.sim_time + 0.5, 20.0, "clock after reset")
    times = [clock_s(m) for m in clock.messages()]
    assert all(b >= a for a, b in itertools.pairwise(times)), "the clock must stay monotonic across a reset"

    bad = client.call(Reset, "/sim/reset", Reset.Request(keyframe="lying_down"))
    assert not bad.success and "stand" in bad.message


def test_pause_step_and_resume(client, g1):
    assert client.call(Trigger, "/sim/pause", Trigger.Request()).success
    try:
        first = client.call(Step, "/sim/step", Step.Request(steps=1))
        assert first.success, first.message
        stepped = client.call(Step, "/sim/step", Step.Request(steps=25))
        assert stepped.success, stepped.message
        assert stepped.sim_time == pytest.approx(first.sim_time + 25 * 0.004, abs=1e-9)
        refused = client.call(Step, "/sim/step", Step.Request(steps=0))
        assert not refused.success and "1" in refused.message
        # A step sent again with its id (its answer was lost) is answered again and not taken twice.
        with_id = client.call(Step, "/sim/step", Step.Request(steps=10, request_id=7_000_001))
        again = client.call(Step, "/sim/step", Step.Request(steps=10, request_id=7_000_001))
        assert with_id.success and with_id.sim_time == pytest.approx(stepped.sim_time + 10 * 0.004, abs=1e-9)
        assert again.success and again.sim_time == with_id.sim_time and "not stepped" in again.message
        next_id = client.call(Step, "/sim/step", Step.Request(steps=10, request_id=7_000_002))
        assert next_id.sim_time == pytest.approx(with_id.sim_time + 10 * 0.004, abs=1e-9)
    finally:
        assert client.call(Trigger, "/sim/resume", Trigger.Request()).success
    not_paused = client.call(Step, "/sim/step", Step.Request(steps=3))
    assert not not_paused.success and "pause" in not_paused.message


def test_services_are_answered_while_the_sim_runs_as_fast_as_possible(client, g1):
    """Unpaced, the physics thread takes its lock back after every stretch: a waiting service is handed it."""
    assert client.set_parameter("sim", "real_time_factor", 0.0)[0]
    try:
        for _ in range(5):
            reset = client.call(Reset, "/sim/reset", Reset.Request())
            assert reset.success, reset.message
            assert client.call(Trigger, "/sim/pause", Trigger.Request()).success
            stepped = client.call(Step, "/sim/step", Step.Request(steps=1))
            assert stepped.success, stepped.message
            assert stepped.sim_time > reset.sim_time
            assert client.call(Trigger, "/sim/resume", Trigger.Request()).success
    finally:
        assert client.set_parameter("sim", "real_time_factor", 1.0)[0]


def test_unknown_robot_is_refused_with_the_known_names():
    with running(["sim_node", "--ros-args", "-p", "robot:=atlas"]) as process:
        code = process.process.wait(timeout=STARTUP_S)
        assert code == 2, "the node must exit with status 2 when the robot is unknown"
        output = process.output()
        assert "atlas" in output and "g1" in output and "panda" in output


def test_robot_description_is_the_robot_as_simulated_with_a_frame_per_link(client, g1):
    """/robot_description (latched, as robot_state_publisher publishes it): a URDF naming every joint of
    /joint_states, whose every link is a frame on /tf (or the odometry's child), with meshes on this disk."""
    import pathlib
    import xml.etree.ElementTree as ET

    from std_msgs.msg import String

    from sim_ros.names import LATCHED

    description = client.record(String, "/robot_description", qos=LATCHED, keep=1)
    joints = client.record(JointState, "/joint_states", keep=5)
    tf = client.record(TFMessage, "/tf", keep=500)
    client.wait_for(lambda: description.count and joints.count and tf.count >= 20, 60.0, "/robot_description, /joint_states, /tf")
    urdf = ET.fromstring(description.latest.data)
    moving = {j.get("name") for j in urdf.iter("joint") if j.get("type") != "fixed"}
    assert set(joints.latest.name) <= moving, set(joints.latest.name) - moving
    frames = {t.child_frame_id for m in tf.messages() for t in m.transforms}
    links = {link.get("name") for link in urdf.iter("link")}
    assert links <= frames, links - frames
    meshes = [m.get("filename") for m in urdf.iter("mesh")]
    assert meshes and all(pathlib.Path(uri.removeprefix("file://")).is_file() for uri in meshes)
