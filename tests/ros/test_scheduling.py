"""A lock-stepped bring-up's threads yield to /sim's stepping thread (sim_ros.scheduling); other starts keep the normal
policy. The policies are set in processes of their own: the test's process keeps its own."""

from __future__ import annotations

import os
import pathlib
import subprocess
import sys
import textwrap
import time

import pytest

from sim_ros import scheduling
from sim_ros.processes import ChildProcess

pytestmark = pytest.mark.skipif(not hasattr(os, "SCHED_BATCH"), reason="Linux scheduling policies")


def policies_in_a_process(value: str | None, body: str) -> list[int]:
    """Run ``body`` (Python; it appends policies to ``out``) in a new process with ``SIM_SCHEDULING`` set to ``value``
    (``None``: unset): a policy set for a whole process would stay with this test process."""
    env = {k: v for k, v in os.environ.items() if k != scheduling.SCHEDULING_VARIABLE}
    if value is not None:
        env[scheduling.SCHEDULING_VARIABLE] = value
    code = ("import os, threading\nfrom sim_ros import scheduling\nout = []\n" + textwrap.dedent(body)
            + "\nprint(' '.join(str(int(v)) for v in out))")
    finished = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=60)
    assert finished.returncode == 0, finished.stderr
    return [int(v) for v in finished.stdout.split()]


EARLY_THREAD = """
    started, stop = threading.Event(), threading.Event()
    def early():  # a thread started before (as an import might)
        started.set()
        stop.wait()
    thread = threading.Thread(target=early)
    thread.start()
    started.wait()
"""


def test_with_batch_every_thread_of_the_process_is_batch_and_so_are_the_threads_started_later():
    got = policies_in_a_process("batch", EARLY_THREAD + """
    out.append(scheduling.yield_to_physics())
    out.append(os.sched_getscheduler(0))
    out.append(os.sched_getscheduler(thread.native_id))
    later = []
    child = threading.Thread(target=lambda: later.append(os.sched_getscheduler(0)))
    child.start()
    child.join()
    out.extend(later)
    stop.set()
""")
    assert got == [True, os.SCHED_BATCH, os.SCHED_BATCH, os.SCHED_BATCH]


def test_physics_first_runs_its_block_under_the_normal_policy_and_then_restores_batch():
    got = policies_in_a_process("batch", """
    scheduling.yield_to_physics()
    with scheduling.physics_first():
        out.append(os.sched_getscheduler(0))
    out.append(os.sched_getscheduler(0))
""")
    assert got == [os.SCHED_OTHER, os.SCHED_BATCH]


@pytest.mark.parametrize("value", [None, "", "fair"])
def test_unless_asked_for_batch_every_thread_keeps_the_normal_policy(value):
    got = policies_in_a_process(value, EARLY_THREAD + """
    out.append(scheduling.yield_to_physics())
    with scheduling.physics_first():
        out.append(os.sched_getscheduler(0))
    out.append(os.sched_getscheduler(0))
    out.append(os.sched_getscheduler(thread.native_id))
    stop.set()
""")
    assert got == [False, os.SCHED_OTHER, os.SCHED_OTHER, os.SCHED_OTHER]


def test_a_lock_stepped_bring_up_asks_for_batch_unless_a_policy_is_named():
    assert scheduling.lock_step_environment({"A": "1"}) == {"A": "1", "SIM_SCHEDULING": "batch"}
    assert scheduling.lock_step_environment({"SIM_SCHEDULING": ""})["SIM_SCHEDULING"] == "batch"
    assert scheduling.lock_step_environment({"SIM_SCHEDULING": "fair"})["SIM_SCHEDULING"] == "fair"


def test_in_a_sim_node_asked_for_batch_only_the_physics_thread_runs_under_the_normal_policy():
    """Fast DDS's threads and the executor's are SCHED_BATCH: their wake-ups wait for a free core instead of taking
    the stepping thread's (free-running here: the physics thread steps all the time)."""
    env = scheduling.lock_step_environment({k: v for k, v in os.environ.items() if k != scheduling.SCHEDULING_VARIABLE})
    child = ChildProcess(["sim_node", "--ros-args", "-p", "robot:=panda"], env=env)
    try:
        tasks = pathlib.Path(f"/proc/{child.process.pid}/task")

        def policies() -> dict[str, int]:
            found = {}
            for task in tasks.iterdir():
                try:
                    found[f"{(task / 'comm').read_text().strip()}/{task.name}"] = os.sched_getscheduler(int(task.name))
                except OSError:  # a thread that ended meanwhile
                    continue
            return found

        deadline = time.monotonic() + 60.0
        seen = policies()
        while not (any(name.startswith("dds.") for name in seen) and os.SCHED_OTHER in seen.values()):
            assert child.alive() and time.monotonic() < deadline, (seen, child.output())
            time.sleep(0.05)
            seen = policies()
        dds = {name: policy for name, policy in seen.items() if name.startswith("dds.")}
        assert set(dds.values()) == {os.SCHED_BATCH}, seen
        assert seen[f"{(tasks / str(child.process.pid) / 'comm').read_text().strip()}/{child.process.pid}"] == os.SCHED_BATCH
        assert list(seen.values()).count(os.SCHED_OTHER) == 1, seen  # the physics thread
    finally:
        child.stop()
        child.discard_log()
