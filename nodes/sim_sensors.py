"""``/sim``'s sensor streams: /imu, the soles' and wrists' wrenches, and the simulated battery.

Each stream rides along the sim node's publication stops (like ``/odom``): it is published at the
first stop at or after it falls due, stamped with that sim time, and only while someone subscribes
(a stream faster than the stops, set by ``clock_rate`` and ``joint_state_rate``, is published at every
stop). The readings come from :mod:`sim_bridge.sensors`; the battery is drained in the control step
(:class:`sim_bridge.battery.BatteryMeter`) and only reported here.

Topics: ``/imu`` (sensor_msgs/Imu), ``/<foot>/wrench`` (geometry_msgs/WrenchStamped in the sole
frame), ``/sim/hand_sensors`` (raw wrist F/T for ``/hand_sensors``), ``/sim/battery``
(sensor_msgs/BatteryState for ``/power``), ``/tf_static`` (the sensor frames). In:
``/sim/battery_config`` (from ``/power``); service ``/sim/set_battery_level``.
"""

from __future__ import annotations

import math
import threading

from geometry_msgs.msg import TransformStamped, Wrench as WrenchMsg, WrenchStamped
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile
from sensor_msgs.msg import BatteryState, Imu
from tf2_msgs.msg import TFMessage

from nodes.conversions import set_time
from nodes.parameters import ParameterSpec, declare
from sim_bridge import Simulation
from sim_bridge.battery import Battery, BatteryConfig
from sim_bridge.sensors import ImuNoise, SensorSuite, Wrench, WristNoise
from sim_interfaces.msg import BatteryConfig as BatteryConfigMsg, HandSensors
from sim_interfaces.srv import SetBatteryLevel

HAND_SENSORS_TOPIC = "/sim/hand_sensors"
BATTERY_TOPIC = "/sim/battery"
BATTERY_CONFIG_TOPIC = "/sim/battery_config"
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
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


def _set_wrench(msg: WrenchMsg, wrench: Wrench) -> None:
    f, t = wrench.force.tolist(), wrench.torque.tolist()
    msg.force.x, msg.force.y, msg.force.z = f[0], f[1], f[2]
    msg.torque.x, msg.torque.y, msg.torque.z = t[0], t[1], t[2]


class SensorStreams:
    """The sensor and battery streams of one simulation (see the module's text).

    Args:
        node: the sim node.
        sim: its simulation.
        lock: the lock that guards ``sim``; ``publish_due``/``on_*`` are called with it held.
        battery: the battery drained in the control step (None for a robot without one).
    """

    def __init__(self, node: Node, sim: Simulation, lock: threading.RLock, battery: Battery | None) -> None:
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
        self._apply_noise()
        self._next_imu = self._next_wrench = 0.0
        qos = QoSProfile(depth=100)
        self._imu_pub = node.create_publisher(Imu, "/imu", qos) if layout.imu is not None else None
        self._imu_msg = Imu()
        if layout.imu is not None:
            self._imu_msg.header.frame_id = layout.imu.frame
        self._feet = [(foot.name, node.create_publisher(WrenchStamped, f"/{foot.name}/wrench", qos), WrenchStamped())
                      for foot in layout.feet]
        for (_, _, msg), foot in zip(self._feet, layout.feet, strict=True):
            msg.header.frame_id = foot.frame
        self._hand_pub = node.create_publisher(HandSensors, HAND_SENSORS_TOPIC, qos) if layout.wrists else None
        self._hand_msg = HandSensors(names=[w.name for w in layout.wrists], frame_ids=[w.frame for w in layout.wrists],
                                     wrenches=[WrenchMsg() for _ in layout.wrists])
        self._publish_static_frames()
        if battery is not None:
            self._battery_pub = node.create_publisher(BatteryState, BATTERY_TOPIC, qos)
            self._battery_msg = BatteryState(power_supply_status=BatteryState.POWER_SUPPLY_STATUS_DISCHARGING,
                                             power_supply_health=BatteryState.POWER_SUPPLY_HEALTH_GOOD,
                                             power_supply_technology=BatteryState.POWER_SUPPLY_TECHNOLOGY_LION,
                                             present=True, location="torso", serial_number="sim")
            group = MutuallyExclusiveCallbackGroup()
            node.create_subscription(BatteryConfigMsg, BATTERY_CONFIG_TOPIC, self._on_battery_config, LATCHED,
                                     callback_group=group)
            node.create_service(SetBatteryLevel, "~/set_battery_level", self._on_set_level, callback_group=group)

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
            self._next_imu = _next_due(self._next_imu, self._imu_period, now)
            if self._imu_pub is not None and self._imu_pub.get_subscription_count() > 0:
                self._publish_imu(now)
        if now + eps >= self._next_wrench:
            self._next_wrench = _next_due(self._next_wrench, self._wrench_period, now)
            data = self._sim.data
            for name, publisher, msg in self._feet:
                if publisher.get_subscription_count() > 0:
                    set_time(msg.header.stamp, now)
                    _set_wrench(msg.wrench, self.suite.foot_wrench(data, name))
                    publisher.publish(msg)
            if self._hand_pub is not None and self._hand_pub.get_subscription_count() > 0:
                self._publish_hands(now)

    def _publish_imu(self, now: float) -> None:
        assert self._imu_pub is not None
        reading = self.suite.imu(self._sim.data)
        msg = self._imu_msg
        set_time(msg.header.stamp, now)
        q, w, a = reading.orientation_wxyz.tolist(), reading.angular_velocity.tolist(), reading.linear_acceleration.tolist()
        msg.orientation.w, msg.orientation.x, msg.orientation.y, msg.orientation.z = q[0], q[1], q[2], q[3]
        msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = w[0], w[1], w[2]
        msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z = a[0], a[1], a[2]
        msg.orientation_covariance, msg.angular_velocity_covariance, msg.linear_acceleration_covariance = self._covariances
        self._imu_pub.publish(msg)

    def _publish_hands(self, now: float) -> None:
        assert self._hand_pub is not None
        data = self._sim.data
        msg = self._hand_msg
        set_time(msg.header.stamp, now)
        linear, angular, contact = [], [], []
        for name, wrench_msg in zip(msg.names, msg.wrenches, strict=True):
            _set_wrench(wrench_msg, self.suite.wrist_wrench(data, name))
            hand = self.suite.hand_state(data, name)
            linear.append(hand.linear_speed)
            angular.append(hand.angular_speed)
            contact.append(hand.in_contact)
        msg.linear_speeds, msg.angular_speeds, msg.in_contact = linear, angular, contact
        self._hand_pub.publish(msg)

    def publish_battery(self, now: float) -> None:
        """Under the lock, at state_rate: /sim/battery while someone (``/power``) subscribes."""
        battery = self.battery
        if battery is None or self._battery_pub.get_subscription_count() == 0:
            return
        msg = self._battery_msg
        set_time(msg.header.stamp, now)
        voltage = battery.voltage_v
        capacity_ah = battery.config.capacity_wh / voltage if voltage > 0 else math.nan
        msg.voltage = voltage
        msg.current = -battery.power_w / voltage  # negative while discharging (REP: BatteryState)
        msg.charge = battery.energy_wh / voltage
        msg.capacity = capacity_ah
        msg.design_capacity = capacity_ah
        msg.percentage = battery.level_percent / 100.0  # 0..1, as BatteryState defines it
        self._battery_pub.publish(msg)

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
        self._static_pub = self._node.create_publisher(TFMessage, "/tf_static", LATCHED)
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


def _next_due(previous: float, period: float, now: float) -> float:
    """Next due time on the period grid, skipping slots already in the past."""
    nxt = previous + period
    if nxt <= now:
        nxt = now + period - ((now - previous) % period)
    return nxt
