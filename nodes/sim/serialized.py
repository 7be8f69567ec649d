"""Messages serialized once, with their numbers patched into the bytes at each publish.

rclpy converts a Python message to C and serializes it on every publish; for a JointState that
means copying every joint name again. The sim node publishes the same names thousands of times
per second, so it serializes a template once, finds where the stamp and the arrays sit in the
CDR bytes, and at each publish writes only the numbers there and hands rclpy the bytes
(``Publisher.publish(bytes)`` publishes them as they are).

The offsets are found by serializing sentinel values (a run of booleans: by serializing it both ways
and finding the bytes that differ), and every template checks itself at construction against rclpy's
own serialization; :class:`TemplateError` means "publish normally". The sensor streams' templates are
built from the same functions that build their ordinary messages (:func:`imu_message` and friends), so
the fallback path and the bytes carry the same content by construction.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Mapping, Sequence
from typing import Any, ClassVar

import numpy as np
from geometry_msgs.msg import TransformStamped, Wrench, WrenchStamped
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import BatteryState, Imu, JointState
from tf2_msgs.msg import TFMessage

from sim_interfaces.msg import HandSensors

NANOSECONDS_PER_SECOND = 1_000_000_000
_STAMP_SENTINEL = (0x2BADF00D, 0x1CEB00DA)  # (sec, nanosec) unlikely to occur by chance


class TemplateError(RuntimeError):
    """The serialized layout could not be located or failed its self-check."""


def _locate(buffer: bytes, pattern: bytes, what: str) -> int:
    offset = buffer.find(pattern)
    if offset < 0 or buffer.find(pattern, offset + 1) >= 0:
        raise TemplateError(f"cannot locate {what} in the serialized template")
    return offset


def _little_endian(buffer: bytes) -> None:
    # CDR encapsulation: byte 1 is 0x01 for little-endian plain CDR (0x03 for PL_CDR LE).
    if len(buffer) < 4 or buffer[1] not in (0x01, 0x03):
        raise TemplateError("serialized template is not little-endian CDR")


def stamp_of(seconds: float) -> tuple[int, int]:
    """(sec, nanosec) of a sim time [s], rounded to the nanosecond as ``sim_ros.conversions.set_time`` does."""
    total = round(seconds * NANOSECONDS_PER_SECOND)
    return total // NANOSECONDS_PER_SECOND, total % NANOSECONDS_PER_SECOND


def _write_stamp(buffer: bytearray, offset: int, seconds: float) -> None:
    struct.pack_into("<iI", buffer, offset, *stamp_of(seconds))


class JointStateTemplate:
    """sensor_msgs/JointState with fixed names; stamp, positions, velocities and efforts patched.

    Args:
        names: joint names, in the order of the arrays given to :meth:`serialize`.
        frame_id: header frame (empty, as robot_state_publisher expects).

    Raises:
        TemplateError: the layout could not be located or verified.
    """

    def __init__(self, names: list[str], frame_id: str = "") -> None:
        n = len(names)
        self._names = list(names)
        sentinels = [np.array([base + 1.0e-3 * (i + 1) for i in range(n)]) for base in (1.5e11, 2.5e11, 3.5e11)]
        msg = JointState(name=self._names)
        msg.header.frame_id = frame_id
        msg.header.stamp.sec, msg.header.stamp.nanosec = _STAMP_SENTINEL
        msg.position, msg.velocity, msg.effort = (values.tolist() for values in sentinels)
        raw = serialize_message(msg)
        _little_endian(raw)
        self._buffer = bytearray(raw)
        self._stamp_offset = _locate(raw, struct.pack("<iI", *_STAMP_SENTINEL), "the stamp")
        fields = ("position", "velocity", "effort")
        offsets = [_locate(raw, values.astype("<f8").tobytes(), name) for values, name in zip(sentinels, fields, strict=True)]
        self._arrays = [np.frombuffer(self._buffer, dtype="<f8", count=n, offset=offset) for offset in offsets]
        self._check()

    def serialize(self, stamp_s: float, positions: np.ndarray, velocities: np.ndarray, efforts: np.ndarray) -> bytes:
        """The message bytes for these values (stamp in sim seconds, arrays shaped like the names)."""
        _write_stamp(self._buffer, self._stamp_offset, stamp_s)
        position, velocity, effort = self._arrays
        position[:] = positions
        velocity[:] = velocities
        effort[:] = efforts
        return bytes(self._buffer)

    def _check(self) -> None:
        n = len(self._names)
        rng = np.random.default_rng(0)
        values = [rng.normal(size=n) for _ in range(3)]
        msg = deserialize_message(self.serialize(12.345678901, *values), JointState)
        ok = (list(msg.name) == self._names and (msg.header.stamp.sec, msg.header.stamp.nanosec) == (12, 345678901)
              and all(np.array_equal(np.asarray(got), want)
                      for got, want in zip((msg.position, msg.velocity, msg.effort), values, strict=True)))
        if not ok:
            raise TemplateError("JointState template failed its self-check")


class ClockTemplate:
    """rosgraph_msgs/Clock with the time patched in.

    Raises:
        TemplateError: the layout could not be located or verified.
    """

    def __init__(self) -> None:
        msg = Clock()
        msg.clock.sec, msg.clock.nanosec = _STAMP_SENTINEL
        raw = serialize_message(msg)
        _little_endian(raw)
        self._buffer = bytearray(raw)
        self._offset = _locate(raw, struct.pack("<iI", *_STAMP_SENTINEL), "the clock")
        msg = deserialize_message(self.serialize(7.000000001), Clock)
        if (msg.clock.sec, msg.clock.nanosec) != (7, 1):
            raise TemplateError("Clock template failed its self-check")

    def serialize(self, now_s: float) -> bytes:
        _write_stamp(self._buffer, self._offset, now_s)
        return bytes(self._buffer)


# ----- the sensor streams: message builders (the ordinary path) and their templates ----------------------
Stamp = tuple[int, int]  # (sec, nanosec)
Values = Mapping[str, np.ndarray]
Numbers = Sequence[float] | np.ndarray
Flags = Sequence[bool] | np.ndarray


def _set_stamp(msg: Any, stamp: Stamp) -> None:
    msg.header.stamp.sec, msg.header.stamp.nanosec = stamp


def _set_wrench(msg: Wrench, force: Numbers, torque: Numbers) -> None:
    msg.force.x, msg.force.y, msg.force.z = (float(v) for v in force)
    msg.torque.x, msg.torque.y, msg.torque.z = (float(v) for v in torque)


def imu_message(frame_id: str, stamp: Stamp, orientation_wxyz: Numbers, angular_velocity: Numbers,
                linear_acceleration: Numbers, covariances: Sequence[Numbers]) -> Imu:
    """sensor_msgs/Imu: orientation (w, x, y, z), angular velocity [rad/s], acceleration [m/s^2], and the three
    row-major 3x3 covariances (orientation, angular velocity, linear acceleration)."""
    msg = Imu()
    msg.header.frame_id = frame_id
    _set_stamp(msg, stamp)
    q = msg.orientation
    q.w, q.x, q.y, q.z = (float(v) for v in orientation_wxyz)
    msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = (float(v) for v in angular_velocity)
    a = msg.linear_acceleration
    a.x, a.y, a.z = (float(v) for v in linear_acceleration)
    orientation, angular, linear = ([float(v) for v in c] for c in covariances)
    msg.orientation_covariance, msg.angular_velocity_covariance, msg.linear_acceleration_covariance = orientation, angular, linear
    return msg


def wrench_stamped_message(frame_id: str, stamp: Stamp, force: Numbers, torque: Numbers) -> WrenchStamped:
    """geometry_msgs/WrenchStamped: force [N] and torque [N m] in ``frame_id``."""
    msg = WrenchStamped()
    msg.header.frame_id = frame_id
    _set_stamp(msg, stamp)
    _set_wrench(msg.wrench, force, torque)
    return msg


def hand_sensors_message(names: Sequence[str], frame_ids: Sequence[str], stamp: Stamp, wrenches: np.ndarray,
                         linear_speeds: Numbers, angular_speeds: Numbers,
                         in_contact: Flags) -> HandSensors:
    """sim_interfaces/HandSensors; ``wrenches`` (n, 6): each sensor's force [N] then torque [N m]."""
    msg = HandSensors(names=list(names), frame_ids=list(frame_ids))
    _set_stamp(msg, stamp)
    rows = np.asarray(wrenches, dtype=float).reshape(len(names), 6)
    msg.wrenches = [Wrench() for _ in names]
    for wrench, row in zip(msg.wrenches, rows, strict=True):
        _set_wrench(wrench, row[:3], row[3:])
    msg.linear_speeds = [float(v) for v in linear_speeds]
    msg.angular_speeds = [float(v) for v in angular_speeds]
    msg.in_contact = [bool(v) for v in in_contact]
    return msg


def odometry_message(frame_id: str, child_frame_id: str, stamp: Stamp, position: Numbers, orientation_wxyz: Numbers,
                     linear_velocity: Numbers, angular_velocity: Numbers) -> Odometry:
    """nav_msgs/Odometry: the pose of ``child_frame_id`` in ``frame_id`` (position [m], orientation w first) and its
    twist in ``child_frame_id`` (linear [m/s], angular [rad/s]); covariances zero (unknown)."""
    msg = Odometry(child_frame_id=child_frame_id)
    msg.header.frame_id = frame_id
    _set_stamp(msg, stamp)
    pose, twist = msg.pose.pose, msg.twist.twist
    pose.position.x, pose.position.y, pose.position.z = (float(v) for v in position)
    q = pose.orientation
    q.w, q.x, q.y, q.z = (float(v) for v in orientation_wxyz)
    twist.linear.x, twist.linear.y, twist.linear.z = (float(v) for v in linear_velocity)
    twist.angular.x, twist.angular.y, twist.angular.z = (float(v) for v in angular_velocity)
    return msg


def transform_message(frame_id: str, child_frame_id: str, stamp: Stamp, translation: Numbers,
                      rotation_wxyz: Numbers) -> TFMessage:
    """tf2_msgs/TFMessage with one transform: ``child_frame_id`` in ``frame_id`` (translation [m], rotation w first)."""
    transform = TransformStamped(child_frame_id=child_frame_id)
    transform.header.frame_id = frame_id
    _set_stamp(transform, stamp)
    t, r = transform.transform.translation, transform.transform.rotation
    t.x, t.y, t.z = (float(v) for v in translation)
    r.w, r.x, r.y, r.z = (float(v) for v in rotation_wxyz)
    return TFMessage(transforms=[transform])


BATTERY_FIELDS = ("voltage", "current", "charge", "capacity", "design_capacity", "percentage")


def battery_message(stamp: Stamp, voltage: float, current: float, charge: float, capacity: float,
                    design_capacity: float, percentage: float) -> BatteryState:
    """sensor_msgs/BatteryState of the simulated pack: [V], [A] (negative discharging), [Ah], [Ah], [Ah], 0..1."""
    msg = BatteryState(power_supply_status=BatteryState.POWER_SUPPLY_STATUS_DISCHARGING,
                       power_supply_health=BatteryState.POWER_SUPPLY_HEALTH_GOOD,
                       power_supply_technology=BatteryState.POWER_SUPPLY_TECHNOLOGY_LION,
                       present=True, location="torso", serial_number="sim")
    _set_stamp(msg, stamp)
    msg.voltage, msg.current, msg.charge = float(voltage), float(current), float(charge)
    msg.capacity, msg.design_capacity, msg.percentage = float(capacity), float(design_capacity), float(percentage)
    return msg


def _sentinels(dtype: str, count: int, run: int) -> np.ndarray:
    """Distinct values, exact in ``dtype``, unlikely to occur by chance in a message's bytes."""
    if dtype == "?":
        return np.zeros(count, dtype=bool)
    if dtype == "<f4":  # exact in float32: multiples of 64 around -1e9
        return -(1.0e9 + 64.0 * (1000 * (run + 1) + np.arange(1, count + 1))).astype(np.float32).astype(float)
    return (run + 1) * 1.5e11 + 1.0e-3 * np.arange(1, count + 1)


def _locate_difference(raw: bytes, other: bytes, count: int, what: str) -> int:
    """Offset of the ``count`` bytes in which two serializations of equal length differ (all of them)."""
    if len(raw) != len(other):
        raise TemplateError(f"cannot locate {what} in the serialized template (its length changed)")
    differ = [i for i, (a, b) in enumerate(zip(raw, other, strict=True)) if a != b]
    if count == 0 or len(differ) != count or differ[-1] - differ[0] != count - 1:
        raise TemplateError(f"cannot locate {what} in the serialized template")
    return differ[0]


class _Patched:
    """One message's CDR bytes with its stamp and named runs of numbers located, for patching in place.

    Args:
        what: the message's name, for errors.
        build: the ordinary message from a stamp and one array per run (the reference it is checked against).
        runs: per run, its little-endian numpy dtype (``"<f8"``, ``"<f4"``, ``"?"`` for bool) and length.

    Raises:
        TemplateError: the layout could not be located, or patched bytes differ from rclpy's serialization.
    """

    def __init__(self, what: str, build: Callable[[Stamp, Values], Any], runs: Mapping[str, tuple[str, int]]) -> None:
        self._what = what
        self._build = build
        self._runs = dict(runs)
        sentinels = {name: _sentinels(dtype, count, k) for k, (name, (dtype, count)) in enumerate(self._runs.items())}
        raw = serialize_message(build(_STAMP_SENTINEL, sentinels))
        _little_endian(raw)
        self._buffer = bytearray(raw)
        self._stamp_offset = _locate(raw, struct.pack("<iI", *_STAMP_SENTINEL), "the stamp")
        self.views: dict[str, np.ndarray] = {}
        for name, (dtype, count) in self._runs.items():
            if dtype == "?":
                flipped = {**sentinels, name: np.ones(count, dtype=bool)}
                offset = _locate_difference(raw, serialize_message(build(_STAMP_SENTINEL, flipped)), count, name)
            else:
                offset = _locate(raw, sentinels[name].astype(dtype).tobytes(), name)
            self.views[name] = np.frombuffer(self._buffer, dtype=dtype, count=count, offset=offset)
        self._check()

    def bytes_at(self, stamp_s: float) -> bytes:
        """The message with the runs as they are now in :attr:`views`, stamped at ``stamp_s`` [s]."""
        _write_stamp(self._buffer, self._stamp_offset, stamp_s)
        return bytes(self._buffer)

    def _check(self) -> None:
        rng = np.random.default_rng(12345)
        for stamp_s in (0.0, 12.345678901, 98765.000000001):
            values = {name: (rng.random(count) < 0.5 if dtype == "?" else rng.normal(size=count) * 100.0)
                      for name, (dtype, count) in self._runs.items()}
            for name, view in self.views.items():
                view[:] = values[name]
                values[name] = view.astype(bool if view.dtype == bool else float)  # as the bytes hold them
            # Compared as messages: the alignment padding after a string is not written by rclpy's serializer (a
            # fresh serialization of an Odometry once carried a 1 where the template's padding held 0).
            want = self._build(stamp_of(stamp_s), values)
            if deserialize_message(self.bytes_at(stamp_s), type(want)) != want:
                raise TemplateError(f"{self._what} template failed its self-check")
        for view in self.views.values():
            view[:] = 0


class ImuTemplate:
    """sensor_msgs/Imu in a fixed frame; stamp, orientation, angular velocity and acceleration patched.

    Args:
        frame_id: the IMU's frame.
        covariances: the three row-major 3x3 covariances (orientation, angular velocity, acceleration);
            :meth:`set_covariances` changes them.

    Raises:
        TemplateError: the layout could not be located or verified.
    """

    _RUNS: ClassVar[dict[str, tuple[str, int]]] = {  # in the message's order; the quaternion is x, y, z, w there
        "orientation_xyzw": ("<f8", 4), "orientation_covariance": ("<f8", 9),
        "angular_velocity": ("<f8", 3), "angular_velocity_covariance": ("<f8", 9),
        "linear_acceleration": ("<f8", 3), "linear_acceleration_covariance": ("<f8", 9)}

    def __init__(self, frame_id: str, covariances: Sequence[Numbers]) -> None:
        def build(stamp: Stamp, v: Values) -> Imu:
            x, y, z, w = v["orientation_xyzw"]
            return imu_message(frame_id, stamp, (w, x, y, z), v["angular_velocity"], v["linear_acceleration"],
                               (v["orientation_covariance"], v["angular_velocity_covariance"],
                                v["linear_acceleration_covariance"]))

        self._patched = _Patched("Imu", build, self._RUNS)
        views = self._patched.views
        self._orientation = views["orientation_xyzw"]
        self._angular = views["angular_velocity"]
        self._linear = views["linear_acceleration"]
        self._covariances = (views["orientation_covariance"], views["angular_velocity_covariance"],
                             views["linear_acceleration_covariance"])
        self.set_covariances(covariances)

    def set_covariances(self, covariances: Sequence[Numbers]) -> None:
        for view, values in zip(self._covariances, covariances, strict=True):
            view[:] = values

    def serialize(self, stamp_s: float, orientation_wxyz: np.ndarray, angular_velocity: np.ndarray,
                  linear_acceleration: np.ndarray) -> bytes:
        """The message bytes for a reading at sim time ``stamp_s`` [s] (orientation (4,) w first, (3,), (3,))."""
        self._orientation[:3] = orientation_wxyz[1:]
        self._orientation[3] = orientation_wxyz[0]
        self._angular[:] = angular_velocity
        self._linear[:] = linear_acceleration
        return self._patched.bytes_at(stamp_s)


class WrenchStampedTemplate:
    """geometry_msgs/WrenchStamped in a fixed frame; stamp, force and torque patched.

    Raises:
        TemplateError: the layout could not be located or verified.
    """

    def __init__(self, frame_id: str) -> None:
        def build(stamp: Stamp, v: Values) -> WrenchStamped:
            return wrench_stamped_message(frame_id, stamp, v["wrench"][:3], v["wrench"][3:])

        self._patched = _Patched("WrenchStamped", build, {"wrench": ("<f8", 6)})
        self._wrench = self._patched.views["wrench"]

    def serialize(self, stamp_s: float, force: np.ndarray, torque: np.ndarray) -> bytes:
        """The message bytes at sim time ``stamp_s`` [s]; force (3,) [N], torque (3,) [N m]."""
        self._wrench[:3] = force
        self._wrench[3:] = torque
        return self._patched.bytes_at(stamp_s)


class HandSensorsTemplate:
    """sim_interfaces/HandSensors with fixed sensor names and frames; everything else patched.

    Raises:
        TemplateError: the layout could not be located or verified (or there are no sensors).
    """

    def __init__(self, names: Sequence[str], frame_ids: Sequence[str]) -> None:
        n = len(names)
        if n == 0 or len(frame_ids) != n:
            raise TemplateError("HandSensors template needs one frame per sensor, and at least one sensor")

        def build(stamp: Stamp, v: Values) -> HandSensors:
            return hand_sensors_message(names, frame_ids, stamp, v["wrenches"], v["linear_speeds"], v["angular_speeds"],
                                        v["in_contact"])

        runs = {"wrenches": ("<f8", 6 * n), "linear_speeds": ("<f8", n), "angular_speeds": ("<f8", n), "in_contact": ("?", n)}
        self._patched = _Patched("HandSensors", build, runs)
        views = self._patched.views
        self._wrenches = views["wrenches"].reshape(n, 6)
        self._linear, self._angular, self._contact = views["linear_speeds"], views["angular_speeds"], views["in_contact"]

    def serialize(self, stamp_s: float, wrenches: np.ndarray, linear_speeds: np.ndarray, angular_speeds: np.ndarray,
                  in_contact: np.ndarray) -> bytes:
        """The message bytes at sim time ``stamp_s`` [s]: wrenches (n, 6) force [N] then torque [N m] per sensor,
        speeds (n,) [m/s], [rad/s], in_contact (n,) bool, in the order of the names."""
        self._wrenches[:] = wrenches
        self._linear[:] = linear_speeds
        self._angular[:] = angular_speeds
        self._contact[:] = in_contact
        return self._patched.bytes_at(stamp_s)


class BatteryStateTemplate:
    """sensor_msgs/BatteryState of :func:`battery_message`; the stamp and the six numbers patched (float32).

    Raises:
        TemplateError: the layout could not be located or verified.
    """

    def __init__(self) -> None:
        def build(stamp: Stamp, v: Values) -> BatteryState:
            return battery_message(stamp, *(float(v[name][0]) for name in BATTERY_FIELDS))

        self._patched = _Patched("BatteryState", build, {name: ("<f4", 1) for name in BATTERY_FIELDS})
        self._views = [self._patched.views[name] for name in BATTERY_FIELDS]

    def serialize(self, stamp_s: float, voltage: float, current: float, charge: float, capacity: float,
                  design_capacity: float, percentage: float) -> bytes:
        """The message bytes at sim time ``stamp_s`` [s] (units as :func:`battery_message`)."""
        for view, value in zip(self._views, (voltage, current, charge, capacity, design_capacity, percentage), strict=True):
            view[0] = value
        return self._patched.bytes_at(stamp_s)


class OdometryTemplate:
    """nav_msgs/Odometry of :func:`odometry_message` in fixed frames; stamp, pose and twist patched.

    Raises:
        TemplateError: the layout could not be located or verified.
    """

    _RUNS: ClassVar[dict[str, tuple[str, int]]] = {  # in the message's order; the quaternion is x, y, z, w there
        "position": ("<f8", 3), "orientation_xyzw": ("<f8", 4), "linear": ("<f8", 3), "angular": ("<f8", 3)}

    def __init__(self, frame_id: str, child_frame_id: str) -> None:
        def build(stamp: Stamp, v: Values) -> Odometry:
            x, y, z, w = v["orientation_xyzw"]
            return odometry_message(frame_id, child_frame_id, stamp, v["position"], (w, x, y, z), v["linear"], v["angular"])

        self._patched = _Patched("Odometry", build, self._RUNS)
        views = self._patched.views
        self._position, self._orientation = views["position"], views["orientation_xyzw"]
        self._linear, self._angular = views["linear"], views["angular"]

    def serialize(self, stamp_s: float, position: np.ndarray, orientation_wxyz: np.ndarray, linear_velocity: np.ndarray,
                  angular_velocity: np.ndarray) -> bytes:
        """The message bytes at sim time ``stamp_s`` [s] (units as :func:`odometry_message`)."""
        self._position[:] = position
        self._orientation[:3] = orientation_wxyz[1:]
        self._orientation[3] = orientation_wxyz[0]
        self._linear[:] = linear_velocity
        self._angular[:] = angular_velocity
        return self._patched.bytes_at(stamp_s)


class TransformTemplate:
    """tf2_msgs/TFMessage of :func:`transform_message` (one transform between fixed frames); stamp, translation and
    rotation patched.

    Raises:
        TemplateError: the layout could not be located or verified.
    """

    def __init__(self, frame_id: str, child_frame_id: str) -> None:
        def build(stamp: Stamp, v: Values) -> TFMessage:
            x, y, z, w = v["rotation_xyzw"]
            return transform_message(frame_id, child_frame_id, stamp, v["translation"], (w, x, y, z))

        self._patched = _Patched("TFMessage", build, {"translation": ("<f8", 3), "rotation_xyzw": ("<f8", 4)})
        self._translation, self._rotation = self._patched.views["translation"], self._patched.views["rotation_xyzw"]

    def serialize(self, stamp_s: float, translation: np.ndarray, rotation_wxyz: np.ndarray) -> bytes:
        """The message bytes at sim time ``stamp_s`` [s] (translation [m], rotation w first)."""
        self._translation[:] = translation
        self._rotation[:3] = rotation_wxyz[1:]
        self._rotation[3] = rotation_wxyz[0]
        return self._patched.bytes_at(stamp_s)
