"""Sim time in ROS stamps and durations [s] (builtin_interfaces only: a device node needs no more)."""

from __future__ import annotations

from builtin_interfaces.msg import Duration, Time

NANOSECONDS_PER_SECOND = 1_000_000_000


def set_time(stamp: Time, seconds: float) -> None:
    """Write a sim time [s] into an existing stamp in place (cheaper than a new message)."""
    total = round(seconds * NANOSECONDS_PER_SECOND)
    stamp.sec = total // NANOSECONDS_PER_SECOND
    stamp.nanosec = total % NANOSECONDS_PER_SECOND


def duration_msg(seconds: float) -> Duration:
    total = round(max(0.0, seconds) * NANOSECONDS_PER_SECOND)
    return Duration(sec=total // NANOSECONDS_PER_SECOND, nanosec=total % NANOSECONDS_PER_SECOND)


def seconds_of(stamp: Time | Duration) -> float:
    return stamp.sec + stamp.nanosec / NANOSECONDS_PER_SECOND
