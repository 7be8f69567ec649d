"""``/sim``'s sensor streams: /imu, the soles' and wrists' wrenches, and the simulated battery.

Each stream rides along the sim node's publication stops (like ``/odom``): it is published at the
first stop at or after it falls due, stamped with that sim time, and only while someone subscribes
(a stream faster than the stops, set by ``clock_rate`` and ``joint_state_rate``, is published at every
stop). The readings come from :mod:`sim_bridge.sensors`, each computed once per stop and only for a
stream that is due and subscribed; the battery is drained where the physics runs
(:class:`sim_bridge.battery.BatteryMeter`) and only reported here. Like /joint_states, every stream is
serialized once (:mod:`nodes.sim.serialized`) and only its numbers are written at each publish; a template
that fails its self-check falls back to building the same message the ordinary way.

Topics: ``/imu`` (sensor_msgs/Imu), ``/<foot>/wrench`` (geometry_msgs/WrenchStamped in the sole
frame), ``/sim/hand_sensors`` (raw wrist F/T for ``/hand_sensors``), ``/sim/battery``
(sensor_msgs/BatteryState for ``/power``), ``/tf_static`` (the sensor frames). In:
``/sim/battery_config`` (from ``/power``); service ``/sim/set_battery_level``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np
from geometry_msgs.msg import TransformStamped, WrenchStamped
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile
from sensor_msgs.msg import BatteryState, Imu
from tf2_msgs.msg import TFMessage

from nodes.runtime.parameters import ParameterSpec, declare
from nodes.sim.handoff import HandOffLock
from nodes.sim.publication import next_due
from nodes.sim.serialized import (
    BatteryStateTemplate,
    HandSensorsTemplate,
    ImuTemplate,
    TemplateError,
    WrenchStampedTemplate,
    battery_message,
    hand_sensors_message,
    imu_message,
    stamp_of,
    wrench_stamped_message,
)
from sim_bridge import Simulation
from sim_bridge.battery import Battery, BatteryConfig
from sim_bridge.sensors import ImuNoise, SensorSuite, WristNoise
from sim_interfaces.msg import BatteryConfig as BatteryConfigMsg, HandSensors
from sim_interfaces.srv import SetBatteryLevel
from sim_ros.names import (
    BATTERY_CONFIG_TOPIC,
    BATTERY_TOPIC,
    HAND_OFFSETS_APPLIED_TOPIC,
    HAND_OFFSETS_TOPIC,
    HAND_SENSORS_TOPIC,
    IMU_TOPIC,
    LATCHED,
    TF_STATIC_TOPIC,
    wrench_topic,
)

SEED_MAX = 2**31 - 1
IMU_PARAMETERS = (
    ParameterSpec("imu.gyro_noise", 0.0, "IMU angular-velocity white noise, standard deviation [rad/s]", 0.0, 1.0),
    ParameterSpec("imu.accel_noise", 0.0, "IMU acceleration white noise, standard deviation [m/s^2]", 0.0, 5.0),
    ParameterSpec("imu.gyro_bias", 0.0, "IMU angular-velocity constant bias, drawn per axis with this deviation [rad/s]",
                  0.0, 0.5),
    ParameterSpec("imu.accel_bias", 0.0, "IMU acceleration constant bias, drawn per axis with this deviation [m/s^2]",
                  0.0, 2.0),
    ParameterSpec("imu.seed", 0, "seed of the IMU's noise and bias", 0, SEED_MAX),
)
WRIST_PARAMETERS = (
    ParameterSpec("wrist_ft.force_bias", 2.0, "wrist F/T force offset, drawn per axis with this deviation [N]", 0.0, 50.0),
    ParameterSpec("wrist_ft.torque_bias", 0.1, "wrist F/T torque offset, drawn per axis with this deviation [N m]", 0.0, 5.0),
    ParameterSpec("wrist_ft.force_drift", 0.05, "wrist F/T slow force drift [N per minute of sim time]", 0.0, 10.0),
    ParameterSpec("wrist_ft.force_noise", 0.05, "wrist F/T force white noise, standard deviation [N]", 0.0, 5.0),
    ParameterSpec("wrist_ft.torque_noise", 0.005, "wrist F/T torque white noise, standard deviation [N m]", 0.0, 0.5),
    ParameterSpec("wrist_ft.seed", 0, "seed of the wrist sensors' offsets, drift directions and noise", 0, SEED_MAX),
)
RATE_PARAMETERS = (
    ParameterSpec("imu_rate", 100.0, "/imu rate [Hz of sim time] (at most the rate of /clock or /joint_states)", 1.0, 500.0),
    ParameterSpec("wrench_rate", 50.0, "foot and wrist wrench rate [Hz of sim time] (at most that of /clock or "
                  "/joint_states)", 1.0, 500.0),
)

T = TypeVar("T")

SENSOR_HISTORY_DEPTH = 1000  # messages each sensor writer keeps for a reader that lags (10 s of IMU at 100 Hz)


@dataclass(frozen=True)
class _WrenchStream:
    """A sole's or a wrist's wrench stream: its index in the layout, frame, publisher and template (None: publish messages)."""

    index: int
    frame: str
    publisher: Publisher
    template: WrenchStampedTemplate | None


class SensorStreams:
    """The sensor and battery streams of one simulation (see the module's text).

    Args:
        node: the sim node.
        sim: its simulation.
        lock: the lock that guards ``sim``; ``publish_due``/``on_*`` are called with it held.
        battery: the battery drained in the control step (None for a robot without one).
    """

    def __init__(self, node: Node, sim: Simulation, lock: HandOffLock, battery: Battery | None) -> None:
        self._node = node
        self._sim = sim
        self._lock = lock
        self.battery = battery
        layout = sim.robot.sensors
        self.suite = SensorSuite(sim.model, layout)
        specs = RATE_PARAMETERS + (IMU_PARAMETERS if layout.imu is not None else ()) + (WRIST_PARAMETERS if layout.wrists else ())
        declare(node, specs)
        self._names = {spec.name for spec in specs}
        self._imu_period = self._wrench_period = 0.0
        self._covariances = (_diagonal(1e-6), _diagonal(1e-8), _diagonal(1e-6))
        self._imu_template: ImuTemplate | None = None
        self._apply_noise()
        self._next_imu = self._next_wrench = 0.0
        # 10 s of each sensor stream at its default rate (IMU 100 Hz) for a reader that lags, as /clock and /joint_states
        # keep: a lock-stepped run publishes a stride of sim time in a burst, and with 100 (1 s of IMU) a recorder on
        # a loaded machine lost IMU messages mid-run.
        qos = QoSProfile(depth=SENSOR_HISTORY_DEPTH)
        self._imu_pub = node.create_publisher(Imu, IMU_TOPIC, qos) if layout.imu is not None else None
        self._imu_frame = layout.imu.frame if layout.imu is not None else ""
        if layout.imu is not None:
            self._imu_template = self._template(lambda: ImuTemplate(self._imu_frame, self._covariances), IMU_TOPIC)
        self._feet = [_WrenchStream(k, foot.frame, node.create_publisher(WrenchStamped, wrench_topic(foot.name), qos),
                            self._template(functools.partial(WrenchStampedTemplate, foot.frame), wrench_topic(foot.name)))
                      for k, foot in enumerate(layout.feet)]
        self._hand_names = [w.name for w in layout.wrists]
        self._hand_frames = [w.frame for w in layout.wrists]
        self._hand_pub = node.create_publisher(HandSensors, HAND_SENSORS_TOPIC, qos) if layout.wrists else None
        self._hand_template = (self._template(lambda: HandSensorsTemplate(self._hand_names, self._hand_frames),
                                              HAND_SENSORS_TOPIC) if layout.wrists else None)
        n = len(layout.wrists)  # the hands' readings, gathered here at each publish
        self._hand_wrenches, self._hand_linear, self._hand_angular = np.zeros((n, 6)), np.zeros(n), np.zeros(n)
        self._hand_contact = np.zeros(n, dtype=bool)
        # Each wrist's calibrated wrench (raw - the offset /hand_sensors calibrated; zero until then), on /<wrist>/wrench.
        self._wrists = [_WrenchStream(k, wrist.frame, node.create_publisher(WrenchStamped, wrench_topic(wrist.name), qos),
                              self._template(functools.partial(WrenchStampedTemplate, wrist.frame), wrench_topic(wrist.name)))
                        for k, wrist in enumerate(layout.wrists)]
        self._hand_offsets = np.zeros((n, 6))
        if layout.wrists:
            self._offsets_applied_pub = node.create_publisher(HandSensors, HAND_OFFSETS_APPLIED_TOPIC, LATCHED)
            node.create_subscription(HandSensors, HAND_OFFSETS_TOPIC, self._on_hand_offsets, LATCHED,
                                     callback_group=MutuallyExclusiveCallbackGroup())
        self._publish_static_frames()
        if battery is not None:
            self._battery_pub = node.create_publisher(BatteryState, BATTERY_TOPIC, qos)
            self._battery_template = self._template(BatteryStateTemplate, BATTERY_TOPIC)
            group = MutuallyExclusiveCallbackGroup()
            node.create_subscription(BatteryConfigMsg, BATTERY_CONFIG_TOPIC, self._on_battery_config, LATCHED,
                                     callback_group=group)
            node.create_service(SetBatteryLevel, "~/set_battery_level", self._on_set_level, callback_group=group)

    def _template(self, make: Callable[[], T], topic: str) -> T | None:
        """A stream's serialized template, or None (then it publishes ordinary messages) if it cannot be made."""
        try:
            return make()
        except TemplateError as error:
            self._node.get_logger().warning(f"{error}; publishing {topic} the ordinary way")
            return None

    # ----- parameters ----------------------------------------------------------------------
    def _apply_noise(self) -> None:
        """Read the rate and noise parameters into the values the publication stops use (no look-ups there)."""
        value = self._node.get_parameter
        self._imu_period = 1.0 / float(value("imu_rate").value)
        self._wrench_period = 1.0 / float(value("wrench_rate").value)
        if self._sim.robot.sensors.imu is not None:
            self.suite.set_imu_noise(ImuNoise(
                float(value("imu.gyro_noise").value), float(value("imu.accel_noise").value),
                float(value("imu.gyro_bias").value), float(value("imu.accel_bias").value), int(value("imu.seed").value)))
            noise = self.suite.imu_noise
            # Covariances (row-major 3x3, diagonal): the noise as configured, a floor for the true values (0 = unknown).
            self._covariances = (_diagonal(1e-6),  # orientation: ground truth from the simulation
                                 _diagonal(max(noise.gyro_noise ** 2 + noise.gyro_bias ** 2, 1e-8)),
                                 _diagonal(max(noise.accel_noise ** 2 + noise.accel_bias ** 2, 1e-6)))
            if self._imu_template is not None:
                self._imu_template.set_covariances(self._covariances)
        if self._sim.robot.sensors.wrists:
            self.suite.set_wrist_noise(WristNoise(
                float(value("wrist_ft.force_bias").value), float(value("wrist_ft.torque_bias").value),
                float(value("wrist_ft.force_drift").value), float(value("wrist_ft.force_noise").value),
                float(value("wrist_ft.torque_noise").value), int(value("wrist_ft.seed").value)))

    def on_parameters(self, parameters: list[Parameter]) -> None:
        """Under the lock, after parameters of the sim node changed."""
        if any(p.name in self._names for p in parameters):
            self._apply_noise()

    # ----- publishing ----------------------------------------------------------------------
    def publish_due(self, now: float) -> None:
        """Under the lock, at every publication stop: the streams that fell due, each while someone subscribes."""
        eps = 1e-9
        if now + eps >= self._next_imu:
            self._next_imu = next_due(self._next_imu, self._imu_period, now)
            if self._imu_pub is not None and self._imu_pub.get_subscription_count() > 0:
                self._publish_imu(now)
        if now + eps >= self._next_wrench:
            self._next_wrench = next_due(self._next_wrench, self._wrench_period, now)
            feet = [foot for foot in self._feet if foot.publisher.get_subscription_count() > 0]
            if feet:
                self._publish_feet(now, feet)
            wrists = [wrist for wrist in self._wrists if wrist.publisher.get_subscription_count() > 0]
            raw = self._hand_pub is not None and self._hand_pub.get_subscription_count() > 0
            if raw or wrists:
                self._publish_hands(now, raw, wrists)

    def _publish_imu(self, now: float) -> None:
        assert self._imu_pub is not None
        reading = self.suite.imu(self._sim.data)
        payload: Any
        if self._imu_template is not None:
            payload = self._imu_template.serialize(now, reading.orientation_wxyz, reading.angular_velocity,
                                                   reading.linear_acceleration)
        else:
            payload = imu_message(self._imu_frame, stamp_of(now), reading.orientation_wxyz, reading.angular_velocity,
                                  reading.linear_acceleration, self._covariances)
        self._imu_pub.publish(payload)

    def _publish_feet(self, now: float, feet: list[_WrenchStream]) -> None:
        """The subscribed soles' wrenches, from one pass over the contacts."""
        wrenches = self.suite.foot_wrenches(self._sim.data)
        for foot in feet:
            wrench = wrenches[foot.index]
            if foot.template is not None:
                foot.publisher.publish(foot.template.serialize(now, wrench.force, wrench.torque))
            else:
                foot.publisher.publish(wrench_stamped_message(foot.frame, stamp_of(now), wrench.force, wrench.torque))

    def _publish_hands(self, now: float, raw: bool, wrists: list[_WrenchStream]) -> None:
        """The raw readings (for /hand_sensors' calibration) and the subscribed wrists' calibrated wrenches."""
        assert self._hand_pub is not None
        data = self._sim.data
        for k, name in enumerate(self._hand_names):
            wrench = self.suite.wrist_wrench(data, name)
            hand = self.suite.hand_state(data, name)
            self._hand_wrenches[k, :3] = wrench.force
            self._hand_wrenches[k, 3:] = wrench.torque
            self._hand_linear[k], self._hand_angular[k], self._hand_contact[k] = (
                hand.linear_speed, hand.angular_speed, hand.in_contact)
        for wrist in wrists:
            calibrated = self._hand_wrenches[wrist.index] - self._hand_offsets[wrist.index]
            if wrist.template is not None:
                wrist.publisher.publish(wrist.template.serialize(now, calibrated[:3], calibrated[3:]))
            else:
                wrist.publisher.publish(wrench_stamped_message(wrist.frame, stamp_of(now), calibrated[:3], calibrated[3:]))
        if not raw:
            return
        payload: Any
        if self._hand_template is not None:
            payload = self._hand_template.serialize(now, self._hand_wrenches, self._hand_linear, self._hand_angular,
                                                    self._hand_contact)
        else:
            payload = hand_sensors_message(self._hand_names, self._hand_frames, stamp_of(now), self._hand_wrenches,
                                           self._hand_linear, self._hand_angular, self._hand_contact)
        self._hand_pub.publish(payload)

    def _on_hand_offsets(self, msg: HandSensors) -> None:
        """/hand_sensors' calibrated offsets (by sensor name; others' ignored), subtracted from every wrist wrench
        published after this; echoed on HAND_OFFSETS_APPLIED_TOPIC once they are."""
        offsets = {name: wrench for name, wrench in zip(msg.names, msg.wrenches, strict=False)}
        with self._lock:
            for k, name in enumerate(self._hand_names):
                if name in offsets:
                    w = offsets[name]
                    self._hand_offsets[k] = (w.force.x, w.force.y, w.force.z, w.torque.x, w.torque.y, w.torque.z)
            self._offsets_applied_pub.publish(msg)

    def publish_battery(self, now: float) -> None:
        """Under the lock, at state_rate: /sim/battery while someone (``/power``) subscribes."""
        battery = self.battery
        if battery is None or self._battery_pub.get_subscription_count() == 0:
            return
        voltage = battery.voltage_v
        capacity_ah = battery.config.capacity_wh / voltage if voltage > 0 else math.nan
        values = (voltage,
                  -battery.power_w / voltage,  # current: negative while discharging (REP: BatteryState)
                  battery.energy_wh / voltage,  # charge [Ah]
                  capacity_ah, capacity_ah,  # capacity, design capacity [Ah]
                  battery.level_percent / 100.0)  # percentage: 0..1, as BatteryState defines it
        template = self._battery_template
        payload: Any = (template.serialize(now, *values) if template is not None
                        else battery_message(stamp_of(now), *values))
        self._battery_pub.publish(payload)

    def _publish_static_frames(self) -> None:
        """The sensor frames (fixed in their bodies) on /tf_static; a writer of its own, latched."""
        pairs = self._sim.robot.sensors.frames()
        if not pairs:
            return
        model = self._sim.model
        transforms = []
        for body, site in pairs:
            transform = TransformStamped()
            transform.header.frame_id = body
            transform.child_frame_id = site
            p, q = model.site(site).pos.tolist(), model.site(site).quat.tolist()
            t, r = transform.transform.translation, transform.transform.rotation
            t.x, t.y, t.z = p[0], p[1], p[2]
            r.w, r.x, r.y, r.z = q[0], q[1], q[2], q[3]
            transforms.append(transform)
        self._static_pub = self._node.create_publisher(TFMessage, TF_STATIC_TOPIC, LATCHED)
        self._static_pub.publish(TFMessage(transforms=transforms))

    # ----- battery inputs and resets -------------------------------------------------------------
    def _on_battery_config(self, msg: BatteryConfigMsg) -> None:
        assert self.battery is not None
        try:
            config = BatteryConfig(msg.capacity_wh, msg.idle_power_w, msg.drive_efficiency, msg.low_threshold_percent,
                                   self.battery.config.voltage_full_v, self.battery.config.voltage_empty_v)
        except ValueError as error:
            self._node.get_logger().warning(f"battery settings from /power refused: {error}")
            return
        with self._lock:
            self.battery.configure(config)

    def _on_set_level(self, request: SetBatteryLevel.Request, response: SetBatteryLevel.Response) -> SetBatteryLevel.Response:
        assert self.battery is not None
        with self._lock:
            try:
                self.battery.set_level(request.level_percent)
            except ValueError as error:
                response.success, response.message = False, str(error)
                return response
        response.success = True
        response.message = f"battery at {request.level_percent:.1f} % (a /sim/reset fills it again)"
        return response

    def on_reset(self) -> None:
        """Under the lock, after a reset (the battery was refilled by its meter's reset)."""
        self.suite.invalidate()
        self._next_imu = self._next_wrench = self._sim.time


def _diagonal(value: float) -> list[float]:
    return [value, 0.0, 0.0, 0.0, value, 0.0, 0.0, 0.0, value]
