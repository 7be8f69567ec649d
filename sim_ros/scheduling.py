"""Which threads the operating system runs first: a lock-stepped simulation's stepping thread ahead of the rest.

A lock-stepped run is as fast as ``/sim``'s physics thread, which steps, then publishes each stream. Every
publication wakes a thread somewhere: Fast DDS's event thread of ``/sim`` itself (its reliable writers' timers),
the receive threads of the runner, the recorder and the servers. Linux runs a woken thread at once, taking the
core from a thread that has used more CPU (the physics thread always has), so the physics thread was taken off
its core ~2000 times a second of wall time in a recorded walk_2m on 2 cores.

With ``SIM_SCHEDULING=batch`` every thread of the project's nodes is made ``SCHED_BATCH``: it keeps its fair share
of the CPU, but its wake-up no longer takes a core from a running thread; it waits for a free core or the next
scheduler tick. ``/sim``'s stepping thread runs under the normal policy (``SCHED_OTHER``) while it steps. Neither
needs privileges. The scenario runner starts its bring-ups so (:func:`lock_step_environment`): they are
lock-stepped, nothing waits on them but the runner. A bring-up that runs free keeps the normal policy (the
default, ``fair``): overloaded (four G1 bring-ups at rtf 0 with storms of goals on 2 cores), its servers answered
late with batch threads (4 of 24 storm tests failed against 1 of 20). ros2_control gives its update loop a
real-time priority where it may, which a simulation stepping as fast as possible must not have (it would starve
the rest of the machine). Where the policies do not exist (not Linux) nothing changes.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator, Mapping

SCHEDULING_VARIABLE = "SIM_SCHEDULING"  # "batch": the nodes' threads SCHED_BATCH but /sim's stepping; "fair" (default)
BATCH = "batch"


def enabled() -> bool:
    """Whether this process's threads yield to the stepping thread (``SIM_SCHEDULING=batch``, on Linux)."""
    return os.environ.get(SCHEDULING_VARIABLE, "").strip().lower() == BATCH and hasattr(os, "SCHED_BATCH")


def lock_step_environment(environment: Mapping[str, str]) -> dict[str, str]:
    """``environment`` for a lock-stepped bring-up: ``SIM_SCHEDULING=batch`` unless it names a policy already."""
    chosen = dict(environment)
    if not chosen.get(SCHEDULING_VARIABLE, "").strip():
        chosen[SCHEDULING_VARIABLE] = BATCH
    return chosen


def _set_policy(policy: int, thread_id: int = 0) -> bool:
    try:
        os.sched_setscheduler(thread_id, policy, os.sched_param(0))  # one thread (Linux: 0 = the calling one)
    except OSError:
        return False
    return True


def yield_to_physics() -> bool:
    """With ``SIM_SCHEDULING=batch``, make every thread of this process ``SCHED_BATCH`` (those imports started too),
    and with them every thread started from now on (Fast DDS's, if called before ``rclpy.init``); ``False`` if the
    calling thread was not made so (not asked, or refused)."""
    if not enabled() or not _set_policy(os.SCHED_BATCH):
        return False
    with contextlib.suppress(OSError):
        for task in os.listdir("/proc/self/task"):
            _set_policy(os.SCHED_BATCH, int(task))
    return True


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
