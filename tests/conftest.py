"""Test-wide set-up: a ROS domain of this run's own, localhost discovery, headless rendering.

The environment is fixed before anything imports rclpy, so every process started by a test
(and the test's own clients) share this run's ``ROS_DOMAIN_ID`` and hear no other run. With
pytest-xdist each worker takes the next domain after the run's base, so workers never hear each
other either.
"""

from __future__ import annotations

import os

# Domain ids 1..101 are safe for Fast DDS ports; 0 is everyone's default, so it is avoided.
os.environ.setdefault("SIM_TEST_DOMAIN_ID", str(1 + os.getpid() % 100))  # the run's base; workers inherit it
_worker = os.environ.get("PYTEST_XDIST_WORKER", "gw0").removeprefix("gw")
os.environ["ROS_DOMAIN_ID"] = str(1 + (int(os.environ["SIM_TEST_DOMAIN_ID"]) - 1 + int(_worker or 0)) % 101)
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("MUJOCO_GL", "egl")

import faulthandler  # noqa: E402  (after the environment above, which must come first)
import pathlib  # noqa: E402
import shutil  # noqa: E402
import tempfile  # noqa: E402

import pytest  # noqa: E402

HANG_DIR_VARIABLE = "SIM_TEST_HANG_DIR"  # the folder where a hung test's stacks are written (workers inherit it)
TEST_WATCHDOG_S = float(os.environ.get("SIM_TEST_WATCHDOG_S", "900"))  # [s] wall: a test (set-up to tear-down) longer is hung

# The files that keep a worker busy longest, longest first (45 s to 8 min each, measured one at a time on a loaded
# 2-core machine; the ten slowest tests are printed at the end of every run). `make test` hands whole files to its two workers in
# collection order (--dist loadfile --no-loadscope-reorder): a long file handed out last keeps one worker running
# alone while the other has finished. Every other file follows in its usual order.
LONGEST_FIRST = (
    "tests/scenarios/test_runs.py",
    "tests/ros/test_readme_commands.py",
    "tests/scenarios/test_determinism.py",
    "tests/core/test_fetch.py",
    "tests/ros/test_g1_fetch.py",
    "tests/scenarios/test_pictures.py",
    "tests/ros/test_locomotion_server.py",
    "tests/ros/test_reset_during_goals.py",
    "tests/scenarios/test_cli.py",
    "tests/ros/test_g1_tables.py",
    "tests/scenarios/test_sweep.py",
    "tests/ros/test_namespaces.py",
    "tests/core/test_one_hand.py",
)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The longest files first (a stable sort: the tests of a file keep their order and stay together)."""
    rank = {path: index for index, path in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.nodeid.split("::", 1)[0], len(rank)))


def pytest_configure(config: pytest.Config) -> None:
    """The controller (or a run without workers) makes the folder for hung tests' stacks, before workers start."""
    if "PYTEST_XDIST_WORKER" not in os.environ:
        os.environ[HANG_DIR_VARIABLE] = tempfile.mkdtemp(prefix="sim-test-hangs-")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    """A hung test ends its worker with every thread's stack written out instead of holding the run until CI's limit.

    A Fast DDS deadlock can freeze a whole process with the GIL held (see sim_ros/fastdds_profiles.xml); a timer
    in Python could not fire then, faulthandler's watchdog thread needs no GIL. Armed from the test's set-up to its
    tear-down (which may close a module's client). The stacks go to a file, not to stderr: a worker's stderr is
    captured and lost with it. The run's summary prints them (:func:`pytest_terminal_summary`).
    """
    folder = pathlib.Path(os.environ.get(HANG_DIR_VARIABLE) or tempfile.gettempdir())
    path = folder / f"{os.environ.get('PYTEST_XDIST_WORKER', 'main')}-{os.getpid()}.txt"
    with open(path, "w") as stacks:
        stacks.write(f"{item.nodeid} ran longer than {TEST_WATCHDOG_S:.0f} s; its worker was ended. Its threads:\n")
        stacks.flush()
        faulthandler.dump_traceback_later(TEST_WATCHDOG_S, exit=True, file=stacks)
        try:
            yield
        finally:
            faulthandler.cancel_dump_traceback_later()
    path.unlink()


def pytest_terminal_summary(terminalreporter, exitstatus: int, config: pytest.Config) -> None:
    """The stacks of every test the watchdog ended (the controller's summary), then the folder is removed."""
    if "PYTEST_XDIST_WORKER" in os.environ or not os.environ.get(HANG_DIR_VARIABLE):
        return
    folder = pathlib.Path(os.environ[HANG_DIR_VARIABLE])
    for path in sorted(folder.glob("*.txt")):
        terminalreporter.section(f"hung test ({path.stem})", sep="=", red=True)
        terminalreporter.write(path.read_text())
    shutil.rmtree(folder, ignore_errors=True)
