"""Which threads the operating system runs first: the physics step ahead of the threads that wait on it.

A lock-stepped run is as fast as ``/sim``'s physics thread, which steps, then publishes each stream. Every
publication wakes a thread somewhere: Fast DDS's event thread of ``/sim`` itself (its reliable writers' timers),
the receive threads of the runner, the recorder and the servers. Linux runs a woken thread at once, taking the
core from a thread that has used more CPU (the physics thread always has), so the physics thread was taken off
its core ~2000 times a second of wall time in a recorded walk_2m on 2 cores.

Every thread of the project's processes (the nodes, the scenario recorder) is made ``SCHED_BATCH``: it still
gets its fair share of the CPU, but its wake-up no longer takes a core from a running thread, it waits for
the next scheduler tick or a free core (a few milliseconds at most). ``/sim``'s stepping thread runs under the
normal policy (``SCHED_OTHER``) while it steps. Neither needs privileges; ros2_control gives its update loop a
real-time priority where it may, which a simulation stepping as fast as possible must not have (it would starve
the rest of the machine).

``SIM_SCHEDULING=fair`` leaves every thread under the normal policy (the comparison in ``make bench-scenario``).
Where the policies do not exist (not Linux) nothing changes.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator

SCHEDULING_VARIABLE = "SIM_SCHEDULING"  # "fair": no thread is made SCHED_BATCH


def enabled() -> bool:
    """Whether the project's background threads yield to the physics thread (``SIM_SCHEDULING`` is not ``fair``)."""
    return os.environ.get(SCHEDULING_VARIABLE, "").strip().lower() != "fair" and hasattr(os, "SCHED_BATCH")


def _set_policy(policy: int) -> bool:
    try:
        os.sched_setscheduler(0, policy, os.sched_param(0))  # the calling thread (Linux: per thread)
    except OSError:
        return False
    return True


def yield_to_physics() -> bool:
    """Make the calling thread ``SCHED_BATCH``, and with it every thread it starts from now on (Fast DDS's threads,
    if called before ``rclpy.init``); ``False`` if it could not be (disabled, or refused)."""
    return enabled() and _set_policy(os.SCHED_BATCH)


@contextlib.contextmanager
def physics_first() -> Iterator[None]:
    """The calling thread under the normal policy (``SCHED_OTHER``) for the ``with`` block, then as it was."""
    if not enabled():
        yield
        return
    before = os.sched_getscheduler(0)
    changed = before != os.SCHED_OTHER and _set_policy(os.SCHED_OTHER)
    try:
        yield
    finally:
        if changed:
            _set_policy(before)
