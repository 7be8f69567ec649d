"""Recorded state over sim time: what measures evaluate and what the video and the plots draw.

A :class:`Series` holds time-stamped rows; the functions below build one from recorded messages
(``/odom``, ``/objects``, ``/joint_states``), read by attribute, so any message with those fields will do.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass
class Series:
    """Time-stamped samples [s of sim time] of one quantity, columns in ``values`` (n, k)."""

    t: np.ndarray
    values: np.ndarray

    def at(self, time: float) -> np.ndarray | None:
        """The last sample at or before ``time`` (the first one if all are later)."""
        if len(self.t) == 0:
            return None
        i = int(np.searchsorted(self.t, time + 1e-6, side="right")) - 1
        return self.values[max(i, 0)]

    def window(self, start: float, end: float) -> Series:
        mask = (self.t >= start - 1e-6) & (self.t <= end + 1e-6)
        return Series(self.t[mask], self.values[mask])


def stamp_s(stamp: Any) -> float:
    """A ``builtin_interfaces/Time`` in seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


def yaw_of(q: Any) -> float:
    """The yaw [rad] of a quaternion (fields w, x, y, z)."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def odom_series(messages: list[Any]) -> Series:
    """Columns x, y, z [m], yaw [rad], qw, qx, qy, qz."""
    rows = [(stamp_s(m.header.stamp), p.position.x, p.position.y, p.position.z, yaw_of(p.orientation),
             p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z)
            for m in messages for p in (m.pose.pose,)]
    return _series(rows, 8)


def object_series(messages: list[Any], name: str) -> Series:
    """Columns x, y, z [m], qw, qx, qy, qz of one object."""
    rows = []
    for m in messages:
        if name in m.names:
            p = m.poses[list(m.names).index(name)]
            rows.append((stamp_s(m.header.stamp), p.position.x, p.position.y, p.position.z,
                         p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z))
    return _series(rows, 7)


def joint_series(messages: list[Any]) -> tuple[list[str], Series]:
    """The joint names of the last message and their positions over time."""
    if not messages:
        return [], _series([], 0)
    names = list(messages[-1].name)
    rows = [(stamp_s(m.header.stamp), *m.position) for m in messages if len(m.position) == len(names)]
    return names, _series(rows, len(names))


def _series(rows: list[tuple], width: int) -> Series:
    if not rows:
        return Series(np.zeros(0), np.zeros((0, width)))
    array = np.array(sorted(rows, key=lambda r: r[0]), dtype=float)
    return Series(array[:, 0], array[:, 1:])
