"""The suite's watchdog: a test that freezes with the GIL held runs once more on a new worker, a second freeze fails
it, and no process a frozen worker started is left behind.

The freeze is a C call that keeps the GIL (``ctypes.PyDLL``), as Fast DDS's deadlock does inside rclpy: nothing in
Python can run in that process any more, only faulthandler's watchdog thread.
"""

from __future__ import annotations

import os
import pathlib
import subprocess
import sys
import textwrap

ROOT = pathlib.Path(__file__).resolve().parents[1]

FROZEN_FILE = textwrap.dedent('''
    import ctypes, os, pathlib, subprocess

    def test_before():
        pass

    def test_freezes():
        pathlib.Path(os.environ["CHILD_PIDS"]).open("a").write(f"{subprocess.Popen(['sleep', '300']).pid}\\n")
        mark = pathlib.Path(os.environ["FREEZE_MARK"])
        if os.environ.get("FREEZE_EVERY_TIME") or not mark.exists():
            mark.write_text("froze")
            ctypes.PyDLL(None).sleep(120)  # holds the GIL for 120 s

    def test_after():
        pass
''')


def _run_frozen_suite(tmp_path: pathlib.Path, every_time: bool, workers: int = 2,
                      files_around: int = 0) -> tuple[subprocess.CompletedProcess[str], list[int]]:
    """The frozen file between ``files_around`` files of one passing test before it and as many after it."""
    (tmp_path / "test_frozen.py").write_text(FROZEN_FILE)
    files = [str(tmp_path / "test_frozen.py")]
    for index in range(files_around):
        for side in ("before", "after"):
            (tmp_path / f"test_{side}_{index}.py").write_text("def test_passes():\n    pass\n")
        files = [str(tmp_path / f"test_before_{index}.py"), *files, str(tmp_path / f"test_after_{index}.py")]
    env = dict(os.environ, SIM_TEST_WATCHDOG_S="3", FREEZE_MARK=str(tmp_path / "mark"),
               CHILD_PIDS=str(tmp_path / "children"), FREEZE_EVERY_TIME="1" if every_time else "")
    env.pop("SIM_TEST_RUN", None)  # a run of its own, with its own tag for its workers' processes
    env.pop("PYTEST_XDIST_WORKER", None)
    env.pop("SIM_TEST_HANG_DIR", None)
    command = [sys.executable, "-m", "pytest", "-p", "tests.conftest", "-c", os.devnull, "--rootdir", str(tmp_path),
               "-p", "no:cacheprovider", "-n", str(workers), "--dist", "loadfile", "--no-loadscope-reorder",
               "--max-worker-restart", "2", *files]
    finished = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True, timeout=240)
    children = [int(line) for line in (tmp_path / "children").read_text().split()]
    return finished, children


def _alive(pid: int) -> bool:
    try:
        return pathlib.Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def test_a_test_that_freezes_once_runs_again_and_passes_and_its_workers_processes_are_stopped(tmp_path):
    finished, children = _run_frozen_suite(tmp_path, every_time=False)
    summary = finished.stdout.strip().splitlines()[-1]
    assert finished.returncode == 0, finished.stdout[-3000:]
    assert "3 passed, 1 rerun" in summary, summary
    assert "ran longer than 3 s" in finished.stdout  # the freeze's stacks are printed
    assert "test_frozen.py::test_freezes" in finished.stdout.split("frozen tests that ran again", 1)[1]
    assert len(children) == 2 and not any(_alive(pid) for pid in children), children


def test_a_worker_that_froze_after_finishing_other_files_hands_only_its_unfinished_ones_to_the_new_worker(tmp_path):
    # One worker runs every file: the frozen one comes after finished files and before an unstarted one. xdist 3.8
    # alone handed the new worker a finished file (no test) and waited for ever (tests/conftest.py says why).
    finished, children = _run_frozen_suite(tmp_path, every_time=False, workers=1, files_around=2)
    summary = finished.stdout.strip().splitlines()[-1]
    assert finished.returncode == 0, finished.stdout[-3000:]
    assert "7 passed, 1 rerun" in summary, summary
    assert not any(_alive(pid) for pid in children), children


def test_a_test_that_freezes_again_fails_the_run(tmp_path):
    finished, children = _run_frozen_suite(tmp_path, every_time=True)
    assert finished.returncode != 0, finished.stdout[-3000:]
    assert "FAILED" in finished.stdout and "test_frozen.py::test_freezes" in finished.stdout
    assert not any(_alive(pid) for pid in children), children


def test_a_test_whose_worker_crashes_without_freezing_fails_at_once(tmp_path):
    (tmp_path / "test_crash.py").write_text("import os\n\ndef test_crashes():\n    os.abort()\n")
    env = dict(os.environ, SIM_TEST_WATCHDOG_S="60")
    for name in ("SIM_TEST_RUN", "PYTEST_XDIST_WORKER", "SIM_TEST_HANG_DIR"):
        env.pop(name, None)
    command = [sys.executable, "-m", "pytest", "-p", "tests.conftest", "-c", os.devnull, "--rootdir", str(tmp_path),
               "-p", "no:cacheprovider", "-n", "1", "--max-worker-restart", "0", str(tmp_path / "test_crash.py")]
    finished = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    assert finished.returncode != 0
    assert "rerun" not in finished.stdout.strip().splitlines()[-1], finished.stdout[-2000:]
