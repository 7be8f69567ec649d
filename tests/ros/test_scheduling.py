"""The physics thread ahead of the threads its publications wake (sim_ros.scheduling), each call in a thread of its own."""

from __future__ import annotations

import os
import threading
from collections.abc import Callable

import pytest

from sim_ros import scheduling

pytestmark = pytest.mark.skipif(not hasattr(os, "SCHED_BATCH"), reason="Linux scheduling policies")


def in_thread(body: Callable[[], object]) -> object:
    """``body()`` run in a new thread (a policy is a thread's own: the test's thread keeps its own)."""
    answer: list[object] = []
    thread = threading.Thread(target=lambda: answer.append(body()))
    thread.start()
    thread.join(10.0)
    assert answer, "the thread did not finish"
    return answer[0]


def test_a_thread_that_yields_to_physics_is_batch_and_so_are_the_threads_it_starts(monkeypatch):
    monkeypatch.delenv(scheduling.SCHEDULING_VARIABLE, raising=False)

    def body() -> tuple[bool, int, int]:
        yielded = scheduling.yield_to_physics()
        child = in_thread(lambda: os.sched_getscheduler(0))
        return yielded, os.sched_getscheduler(0), child

    assert in_thread(body) == (True, os.SCHED_BATCH, os.SCHED_BATCH)


def test_physics_first_runs_its_block_under_the_normal_policy_and_then_restores_batch(monkeypatch):
    monkeypatch.delenv(scheduling.SCHEDULING_VARIABLE, raising=False)

    def body() -> tuple[int, int]:
        scheduling.yield_to_physics()
        with scheduling.physics_first():
            inside = os.sched_getscheduler(0)
        return inside, os.sched_getscheduler(0)

    assert in_thread(body) == (os.SCHED_OTHER, os.SCHED_BATCH)


def test_sim_scheduling_fair_leaves_every_thread_under_the_normal_policy(monkeypatch):
    monkeypatch.setenv(scheduling.SCHEDULING_VARIABLE, "fair")

    def body() -> tuple[bool, int]:
        yielded = scheduling.yield_to_physics()
        with scheduling.physics_first():
            return yielded, os.sched_getscheduler(0)

    assert in_thread(body) == (False, os.SCHED_OTHER)
