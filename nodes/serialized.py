"""Messages serialized once, with their numbers patched into the bytes at each publish.

rclpy converts a Python message to C and serializes it on every publish; for a JointState that
means copying every joint name again. The sim node publishes the same names thousands of times
per second, so it serializes a template once, finds where the stamp and the arrays sit in the
CDR bytes, and at each publish writes only the numbers there and hands rclpy the bytes
(``Publisher.publish(bytes)`` publishes them as they are).

The offsets are found by serializing sentinel values, and every template checks itself at
construction by deserializing a patched buffer; :class:`TemplateError` means "publish normally".
"""

from __future__ import annotations

import struct

import numpy as np
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

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


def _write_stamp(buffer: bytearray, offset: int, seconds: float) -> None:
    total = round(seconds * NANOSECONDS_PER_SECOND)
    struct.pack_into("<iI", buffer, offset, total // NANOSECONDS_PER_SECOND, total % NANOSECONDS_PER_SECOND)


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
