"""The pre-serialized templates (/joint_states, /clock, /odom, the base's /tf and /sim's sensor streams) give the same
bytes' meaning as rclpy's own path: each template's bytes, deserialized, equal a message built field by field for random
values."""

from __future__ import annotations

import threading
import time

import mujoco
import numpy as np
import pytest
import rclpy
from geometry_msgs.msg import TransformStamped, Wrench, WrenchStamped
from nav_msgs.msg import Odometry
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import BatteryState, Imu, JointState
from tf2_msgs.msg import TFMessage

import nodes.sim.sensors
import robot_models
from nodes.sim.sensors import SensorStreams
from nodes.sim.serialized import (
    BatteryStateTemplate,
    ClockTemplate,
    HandSensorsTemplate,
    ImuTemplate,
    JointStateTemplate,
    OdometryTemplate,
    TemplateError,
    TransformTemplate,
    WrenchStampedTemplate,
    battery_message,
    hand_sensors_message,
    imu_message,
    odometry_message,
    stamp_of,
    transform_message,
    wrench_stamped_message,
)
from sim_bridge import Simulation, Slot
from sim_bridge.battery import Battery
from sim_bridge.locomotion import WalkingController
from sim_bridge.sensors import SensorSuite
from sim_interfaces.msg import HandSensors

STAMPS = (0.0, 1.5, 12345.000000001, 3.999999999)


def _stamp_s(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def _set_stamp(msg, seconds: float) -> None:
    msg.header.stamp.sec, msg.header.stamp.nanosec = stamp_of(seconds)


@pytest.mark.parametrize("robot", robot_models.ROBOT_NAMES)
def test_joint_state_template_round_trips_every_field(robot):
    names = list(robot_models.load(robot).actuated_joints)
    template = JointStateTemplate(names)
    rng = np.random.default_rng(3)
    for stamp in (0.0, 1.5, 12345.000000001):
        values = [rng.normal(size=len(names)) * 10 for _ in range(3)]
        msg = deserialize_message(template.serialize(stamp, *values), JointState)
        assert list(msg.name) == names
        assert msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9 == pytest.approx(stamp, abs=1e-9)
        for got, want in zip((msg.position, msg.velocity, msg.effort), values, strict=False):
            np.testing.assert_array_equal(np.asarray(got), want)


def test_joint_state_template_bytes_equal_rclpy_serialization():
    names = ["a", "bb", "ccc"]
    values = [np.array([1.0, -2.0, 3.5]), np.array([0.1, 0.2, 0.3]), np.array([-9.0, 0.0, 9.0])]
    reference = JointState(name=names, position=values[0].tolist(), velocity=values[1].tolist(), effort=values[2].tolist())
    reference.header.stamp.sec, reference.header.stamp.nanosec = 3, 250_000_000
    assert JointStateTemplate(names).serialize(3.25, *values) == serialize_message(reference)


def test_clock_template_bytes_equal_rclpy_serialization():
    reference = Clock()
    reference.clock.sec, reference.clock.nanosec = 42, 7
    assert ClockTemplate().serialize(42.000000007) == serialize_message(reference)


# ----- the sensor streams' templates, against messages built field by field here -----------------------------
def test_imu_template_equals_a_message_built_field_by_field():
    rng = np.random.default_rng(11)
    covariances = [rng.random(9) for _ in range(3)]
    template = ImuTemplate("imu_in_pelvis", covariances)
    for i, stamp in enumerate(STAMPS):
        if i == 2:  # new covariances (a parameter changed) reach the next message
            covariances = [rng.random(9) for _ in range(3)]
            template.set_covariances(covariances)
        q, w, a = rng.normal(size=4), rng.normal(size=3) * 5, rng.normal(size=3) * 20
        raw = template.serialize(stamp, q, w, a)
        got = deserialize_message(raw, Imu)

        want = Imu()
        want.header.frame_id = "imu_in_pelvis"
        _set_stamp(want, stamp)
        want.orientation.w, want.orientation.x, want.orientation.y, want.orientation.z = (float(v) for v in q)
        want.angular_velocity.x, want.angular_velocity.y, want.angular_velocity.z = (float(v) for v in w)
        want.linear_acceleration.x, want.linear_acceleration.y, want.linear_acceleration.z = (float(v) for v in a)
        want.orientation_covariance = covariances[0].tolist()
        want.angular_velocity_covariance = covariances[1].tolist()
        want.linear_acceleration_covariance = covariances[2].tolist()

        assert got.header.frame_id == "imu_in_pelvis"
        assert (got.header.stamp.sec, got.header.stamp.nanosec) == (want.header.stamp.sec, want.header.stamp.nanosec)
        assert _stamp_s(got) == pytest.approx(stamp, abs=1e-9)
        assert (got.orientation.w, got.orientation.x, got.orientation.y, got.orientation.z) == tuple(q.tolist())
        assert (got.angular_velocity.x, got.angular_velocity.y, got.angular_velocity.z) == tuple(w.tolist())
        assert (got.linear_acceleration.x, got.linear_acceleration.y, got.linear_acceleration.z) == tuple(a.tolist())
        np.testing.assert_array_equal(got.orientation_covariance, covariances[0])
        np.testing.assert_array_equal(got.angular_velocity_covariance, covariances[1])
        np.testing.assert_array_equal(got.linear_acceleration_covariance, covariances[2])
        assert got == want
        assert raw == serialize_message(want)
        assert imu_message("imu_in_pelvis", stamp_of(stamp), q, w, a, covariances) == want  # the fallback path


def test_wrench_stamped_template_equals_a_message_built_field_by_field():
    rng = np.random.default_rng(12)
    template = WrenchStampedTemplate("left_sole")
    for stamp in STAMPS:
        force, torque = rng.normal(size=3) * 300, rng.normal(size=3) * 30
        raw = template.serialize(stamp, force, torque)
        got = deserialize_message(raw, WrenchStamped)

        want = WrenchStamped()
        want.header.frame_id = "left_sole"
        _set_stamp(want, stamp)
        f, t = want.wrench.force, want.wrench.torque
        f.x, f.y, f.z = (float(v) for v in force)
        t.x, t.y, t.z = (float(v) for v in torque)

        assert got.header.frame_id == "left_sole" and _stamp_s(got) == pytest.approx(stamp, abs=1e-9)
        assert (got.wrench.force.x, got.wrench.force.y, got.wrench.force.z) == tuple(force.tolist())
        assert (got.wrench.torque.x, got.wrench.torque.y, got.wrench.torque.z) == tuple(torque.tolist())
        assert got == want
        assert raw == serialize_message(want)
        assert wrench_stamped_message("left_sole", stamp_of(stamp), force, torque) == want


def _unit_quaternion(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


def test_odometry_template_equals_a_message_built_field_by_field():
    rng = np.random.default_rng(13)
    template = OdometryTemplate("odom", "pelvis")
    for stamp in STAMPS:
        position, orientation = rng.normal(size=3) * 5, _unit_quaternion(rng)
        linear, angular = rng.normal(size=3), rng.normal(size=3)
        raw = template.serialize(stamp, position, orientation, linear, angular)
        got = deserialize_message(raw, Odometry)

        want = Odometry(child_frame_id="pelvis")
        want.header.frame_id = "odom"
        _set_stamp(want, stamp)
        pose, twist = want.pose.pose, want.twist.twist
        pose.position.x, pose.position.y, pose.position.z = (float(v) for v in position)
        q = pose.orientation
        q.w, q.x, q.y, q.z = (float(v) for v in orientation)
        twist.linear.x, twist.linear.y, twist.linear.z = (float(v) for v in linear)
        twist.angular.x, twist.angular.y, twist.angular.z = (float(v) for v in angular)

        assert (got.header.frame_id, got.child_frame_id) == ("odom", "pelvis")
        assert _stamp_s(got) == pytest.approx(stamp, abs=1e-9)
        assert (got.pose.pose.orientation.w, got.pose.pose.orientation.x) == (orientation[0], orientation[1])
        assert not any(got.pose.covariance) and not any(got.twist.covariance)
        assert got == want  # not byte for byte: rclpy leaves the padding after child_frame_id unwritten
        assert odometry_message("odom", "pelvis", stamp_of(stamp), position, orientation, linear, angular) == want


def test_transform_template_equals_a_message_built_field_by_field():
    rng = np.random.default_rng(14)
    template = TransformTemplate("odom", "pelvis")
    for stamp in STAMPS:
        translation, rotation = rng.normal(size=3) * 5, _unit_quaternion(rng)
        raw = template.serialize(stamp, translation, rotation)
        got = deserialize_message(raw, TFMessage)

        transform = TransformStamped(child_frame_id="pelvis")
        transform.header.frame_id = "odom"
        _set_stamp(transform, stamp)
        t, r = transform.transform.translation, transform.transform.rotation
        t.x, t.y, t.z = (float(v) for v in translation)
        r.w, r.x, r.y, r.z = (float(v) for v in rotation)
        want = TFMessage(transforms=[transform])

        assert len(got.transforms) == 1 and got.transforms[0].transform.rotation.w == rotation[0]
        assert got == want  # not byte for byte: rclpy leaves the padding after child_frame_id unwritten
        assert transform_message("odom", "pelvis", stamp_of(stamp), translation, rotation) == want


@pytest.mark.parametrize("robot", robot_models.ROBOT_NAMES)
def test_hand_sensors_template_equals_a_message_built_field_by_field(robot):
    wrists = robot_models.load(robot).sensors.wrists
    names, frames = [w.name for w in wrists], [w.frame for w in wrists]
    n = len(names)
    template = HandSensorsTemplate(names, frames)
    rng = np.random.default_rng(13)
    for stamp in STAMPS:
        wrenches, linear, angular = rng.normal(size=(n, 6)) * 10, rng.random(n), rng.random(n) * 3
        contact = rng.random(n) < 0.5
        raw = template.serialize(stamp, wrenches, linear, angular, contact)
        got = deserialize_message(raw, HandSensors)

        want = HandSensors()
        _set_stamp(want, stamp)
        want.names, want.frame_ids = list(names), list(frames)
        want.wrenches = [Wrench() for _ in names]
        for wrench, row in zip(want.wrenches, wrenches, strict=True):
            wrench.force.x, wrench.force.y, wrench.force.z = (float(v) for v in row[:3])
            wrench.torque.x, wrench.torque.y, wrench.torque.z = (float(v) for v in row[3:])
        want.linear_speeds, want.angular_speeds = linear.tolist(), angular.tolist()
        want.in_contact = [bool(v) for v in contact]

        assert list(got.names) == names and list(got.frame_ids) == frames
        assert _stamp_s(got) == pytest.approx(stamp, abs=1e-9)
        for wrench, row in zip(got.wrenches, wrenches, strict=True):
            assert (wrench.force.x, wrench.force.y, wrench.force.z, wrench.torque.x, wrench.torque.y,
                    wrench.torque.z) == tuple(row.tolist())
        np.testing.assert_array_equal(got.linear_speeds, linear)
        np.testing.assert_array_equal(got.angular_speeds, angular)
        assert list(got.in_contact) == contact.tolist()
        assert got == want
        assert raw == serialize_message(want)
        assert hand_sensors_message(names, frames, stamp_of(stamp), wrenches, linear, angular, contact) == want


def test_battery_state_template_equals_a_message_built_field_by_field():
    template = BatteryStateTemplate()
    rng = np.random.default_rng(14)
    for stamp in STAMPS:
        voltage, current, charge, capacity = 42.0 + rng.random() * 12, -rng.random() * 20, rng.random() * 9, 8.0 + rng.random()
        percentage = rng.random()
        raw = template.serialize(stamp, voltage, current, charge, capacity, capacity, percentage)
        got = deserialize_message(raw, BatteryState)

        want = BatteryState()
        _set_stamp(want, stamp)
        want.voltage, want.current, want.charge = voltage, current, charge  # float32 fields: rclpy rounds them
        want.capacity, want.design_capacity, want.percentage = capacity, capacity, percentage
        want.power_supply_status = BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
        want.power_supply_health = BatteryState.POWER_SUPPLY_HEALTH_GOOD
        want.power_supply_technology = BatteryState.POWER_SUPPLY_TECHNOLOGY_LION
        want.present, want.location, want.serial_number = True, "torso", "sim"

        assert _stamp_s(got) == pytest.approx(stamp, abs=1e-9)
        for name, value in (("voltage", voltage), ("current", current), ("charge", charge), ("capacity", capacity),
                            ("design_capacity", capacity), ("percentage", percentage)):
            assert getattr(got, name) == float(np.float32(value)), name
        assert got.temperature == 0.0 and list(got.cell_voltage) == [] and list(got.cell_temperature) == []
        assert (got.location, got.serial_number, got.present) == ("torso", "sim", True)
        assert got == deserialize_message(serialize_message(want), BatteryState)
        assert raw == serialize_message(want)
        assert battery_message(stamp_of(stamp), voltage, current, charge, capacity, capacity, percentage) == want


def test_a_template_that_cannot_be_laid_out_says_so():
    with pytest.raises(TemplateError):
        HandSensorsTemplate([], [])
    with pytest.raises(TemplateError):
        HandSensorsTemplate(["left_wrist"], [])


# ----- the readings behind them ---------------------------------------------------------------------------------
def _reference_foot_wrench(model: mujoco.MjModel, data: mujoco.MjData, geom: int, site: int) -> tuple[np.ndarray, np.ndarray]:
    """The sole's wrench summed contact by contact, as the first implementation did (the vectorised sum's reference)."""
    force, torque = np.zeros(3), np.zeros(3)
    local = np.empty(6)
    for i in range(int(data.ncon)):
        contact = data.contact[i]
        if geom not in (int(contact.geom[0]), int(contact.geom[1])):
            continue
        mujoco.mj_contactForce(model, data, i, local)
        frame = contact.frame.reshape(3, 3)
        sign = 1.0 if int(contact.geom[1]) == geom else -1.0
        f = sign * (frame.T @ local[:3])
        force += f
        torque += np.cross(contact.pos - data.site_xpos[site], f) + sign * (frame.T @ local[3:])
    rotation = data.site_xmat[site].reshape(3, 3)
    return rotation.T @ force, rotation.T @ torque


def test_walking_the_feet_wrenches_equal_the_contact_by_contact_sum_and_the_templates_carry_the_readings():
    spec = robot_models.load("g1")
    sim = Simulation(spec)
    walker = WalkingController(sim.model, sim.robot.biped)
    sim.set_controller(Slot.LOCOMOTION, walker)
    walker.set_velocity_command(0.4, 0.05, 0.2)
    suite = SensorSuite(sim.model, spec.sensors)
    feet = spec.sensors.feet
    foot_templates = [WrenchStampedTemplate(foot.frame) for foot in feet]
    imu_template = ImuTemplate(spec.sensors.imu.frame, [[1e-6] * 9] * 3)
    contacts = []
    for _ in range(150):  # 3 s of sim time in 20 ms stops: single and double support
        sim.step(5)
        data = sim.data
        contacts.append(int(data.ncon))
        for foot, wrench, template in zip(feet, suite.foot_wrenches(data), foot_templates, strict=True):
            force, torque = _reference_foot_wrench(sim.model, data, sim.model.geom(foot.geom).id, sim.model.site(foot.frame).id)
            np.testing.assert_allclose(wrench.force, force, rtol=1e-12, atol=1e-9)
            np.testing.assert_allclose(wrench.torque, torque, rtol=1e-12, atol=1e-9)
            msg = deserialize_message(template.serialize(sim.time, wrench.force, wrench.torque), WrenchStamped)
            assert msg == wrench_stamped_message(foot.frame, stamp_of(sim.time), wrench.force, wrench.torque)
        imu = suite.imu(data)
        msg = deserialize_message(imu_template.serialize(sim.time, imu.orientation_wxyz, imu.angular_velocity,
                                                         imu.linear_acceleration), Imu)
        assert msg == imu_message(spec.sensors.imu.frame, stamp_of(sim.time), imu.orientation_wxyz, imu.angular_velocity,
                                  imu.linear_acceleration, [[1e-6] * 9] * 3)
    assert max(contacts) > min(contacts) > 0, "the walk changed the contacts"


# ----- the streams of /sim, in-process: the template path and the ordinary path publish the same -------------
TOPICS = {"/imu": Imu, "/left_foot/wrench": WrenchStamped, "/right_foot/wrench": WrenchStamped,
          "/left_wrist/wrench": WrenchStamped, "/right_wrist/wrench": WrenchStamped,
          "/sim/hand_sensors": HandSensors, "/sim/battery": BatteryState}


class _Listener:
    """Raw subscriptions to the sensor topics in a context of the test's own, spun by an executor thread."""

    def __init__(self, context: Context) -> None:
        self.node = Node("sensor_listener", context=context)
        self.received: dict[str, list[bytes]] = {topic: [] for topic in TOPICS}
        self._lock = threading.Lock()
        for topic, msg_type in TOPICS.items():
            self.node.create_subscription(msg_type, topic, lambda data, topic=topic: self._take(topic, data), 100, raw=True)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self._thread = threading.Thread(target=self.executor.spin, daemon=True)
        self._thread.start()

    def _take(self, topic: str, data: bytes) -> None:
        with self._lock:
            self.received[topic].append(data)

    def take_all(self, count: int, timeout: float = 20.0) -> dict[str, list[bytes]]:
        """Wait until every topic has ``count`` messages (a deadline, not a sleep), then hand them over."""
        deadline = time.monotonic() + timeout
        while True:
            with self._lock:
                if all(len(v) >= count for v in self.received.values()):
                    taken = {topic: list(v) for topic, v in self.received.items()}
                    for v in self.received.values():
                        v.clear()
                    return taken
            assert time.monotonic() < deadline, {t: len(v) for t, v in self.received.items()}
            time.sleep(0.005)


def _publish(context: Context, name: str, sim: Simulation, battery: Battery, listener: _Listener) -> dict[str, list]:
    """A SensorStreams on a node of its own publishes every stream once at the simulation's present state."""
    node = Node(name, context=context)
    streams = SensorStreams(node, sim, threading.RLock(), battery)
    deadline = time.monotonic() + 20.0
    publishers = [streams._imu_pub, streams._hand_pub, streams._battery_pub, *(foot.publisher for foot in streams._feet)]
    while not all(p is not None and p.get_subscription_count() > 0 for p in publishers):
        assert time.monotonic() < deadline, "the listener never matched the streams"
        time.sleep(0.01)
    streams.publish_due(sim.time)
    streams.publish_battery(sim.time)
    received = listener.take_all(1)
    node.destroy_node()
    return {topic: [deserialize_message(raw, TOPICS[topic]) for raw in data] for topic, data in received.items()}


def test_sim_streams_publish_the_same_messages_through_templates_and_the_ordinary_path(monkeypatch):
    spec = robot_models.load("g1")
    sim = Simulation(spec)
    walker = WalkingController(sim.model, sim.robot.biped)
    sim.set_controller(Slot.LOCOMOTION, walker)
    walker.set_velocity_command(0.3, 0.0, 0.0)
    sim.step(200)  # walking: contacts, hand motion, a drained battery
    battery = Battery()
    battery.drain(350.0, 30.0)
    context = Context()
    rclpy.init(context=context)
    try:
        listener = _Listener(context)
        templated = _publish(context, "sim_templates", sim, battery, listener)

        refused = []

        def refuse(*args, **kwargs):
            refused.append(args)
            raise TemplateError("refused by the test")

        for name in ("ImuTemplate", "WrenchStampedTemplate", "HandSensorsTemplate", "BatteryStateTemplate"):
            monkeypatch.setattr(nodes.sim.sensors, name, refuse)
        ordinary = _publish(context, "sim_ordinary", sim, battery, listener)
        assert len(refused) == 7, "every stream fell back: /imu, two feet, two wrists, the hands' raw readings, the battery"
        for topic in TOPICS:
            assert len(templated[topic]) == len(ordinary[topic]) == 1, topic
            assert templated[topic][0] == ordinary[topic][0], topic
        imu = templated["/imu"][0]
        assert imu.header.frame_id == "imu_in_pelvis" and _stamp_s(imu) == pytest.approx(sim.time, abs=1e-9)
        assert imu.linear_acceleration_covariance[0] > 0.0
        assert templated["/left_foot/wrench"][0].header.frame_id == "left_sole"
        assert templated["/right_wrist/wrench"][0].header.frame_id == "right_wrist_ft"
        assert list(templated["/sim/hand_sensors"][0].names) == [w.name for w in spec.sensors.wrists]
        assert templated["/sim/battery"][0].percentage == pytest.approx(battery.level_percent / 100.0, rel=1e-6)
        listener.executor.shutdown()
        listener.node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
