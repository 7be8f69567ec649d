"""Test-wide set-up: a ROS domain of this run's own, localhost discovery, headless rendering.

The environment is fixed before anything imports rclpy, so every process started by a test
(and the test's own clients) share this run's ``ROS_DOMAIN_ID`` and hear no other run. With
pytest-xdist each worker takes a domain of its own, ``WORKER_DOMAIN_STRIDE`` after the previous worker's (the
domains between are its sweeps'), so workers never hear each other either.
"""

from __future__ import annotations

import os
import uuid

# Domain ids 1..101 are safe for Fast DDS ports; 0 is everyone's default, so it is avoided.
os.environ.setdefault("SIM_TEST_DOMAIN_ID", str(1 + os.getpid() % 100))  # the run's base; workers inherit it
_worker = os.environ.get("PYTEST_XDIST_WORKER", "gw0").removeprefix("gw")
# Workers' domains are 5 apart: a sweep a test runs gives its Ray workers the domains after its own + 1
# (sim_client.scenario.running.sweep: D + 2, D + 3 for two), which were the next workers' domains when they were 1
# apart. With three workers a sweep's bring-up answered another worker's scenario ("/sim/reset failed: unknown keyframe
# 'home'; keyframes: stand": a Panda run's reset reached a G1) and put its camera frames in another worker's recording.
WORKER_DOMAIN_STRIDE = 5
_offset = WORKER_DOMAIN_STRIDE * int(_worker or 0)
os.environ["ROS_DOMAIN_ID"] = str(1 + (int(os.environ["SIM_TEST_DOMAIN_ID"]) - 1 + _offset) % 101)
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("MUJOCO_GL", "egl")
# One OpenBLAS thread in the tests' processes (numpy loads before the project's packages in a test module); the
# processes they start inherit it. See robot_models/__init__.py for what two threads cost on a busy machine.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
# Every process a worker starts inherits this tag: the processes of a worker that died are found by it and stopped.
os.environ.setdefault("SIM_TEST_RUN", uuid.uuid4().hex[:12])  # set by the controller, inherited by its workers
WORKER_TAG_VARIABLE = "SIM_TEST_WORKER_TAG"
os.environ[WORKER_TAG_VARIABLE] = f"{os.environ['SIM_TEST_RUN']}/{os.environ.get('PYTEST_XDIST_WORKER', 'main')}"

import collections  # noqa: E402  (after the environment above, which must come first)
import faulthandler  # noqa: E402
import pathlib  # noqa: E402
import resource  # noqa: E402
import shutil  # noqa: E402
import tempfile  # noqa: E402

import pytest  # noqa: E402
from xdist.scheduler import LoadFileScheduling  # noqa: E402
from xdist.workermanage import WorkerController  # noqa: E402

from sim_ros import processes  # noqa: E402

HANG_DIR_VARIABLE = "SIM_TEST_HANG_DIR"  # the folder where a hung test's stacks are written (workers inherit it)
TEST_WATCHDOG_S = float(os.environ.get("SIM_TEST_WATCHDOG_S", "600"))  # [s] wall: a test (set-up to tear-down) longer is hung

# The files that keep a worker busy longest, longest first: their wall time in a whole `make test` on a fresh clone
# (2 cores, four workers; 29 November: 15-160 s each, the ten slowest tests are printed at the end of every run).
# `make test` hands whole files to its workers in collection order (--dist loadfile --no-loadscope-reorder): a long
# file handed out last keeps one worker running alone while the others have finished (test_watchdog, mostly waiting,
# was handed out last and ran alone for its last 25 s). Every other file follows in its usual order.
LONGEST_FIRST = (
    "tests/ros/test_readme_commands.py",
    "tests/scenarios/test_determinism.py",
    "tests/scenarios/test_runs.py",
    "tests/scenarios/test_sweep.py",
    "tests/ros/test_respawn.py",
    "tests/test_watchdog.py",
    "tests/ros/test_server_faults.py",
    "tests/ros/test_g1_fetch.py",
    "tests/ros/test_locomotion_server.py",
    "tests/core/test_one_hand_fetch.py",
    "tests/scenarios/test_cli.py",
    "tests/ros/test_arm_server.py",
    "tests/core/test_one_hand_cancel.py",
    "tests/scenarios/test_pictures.py",
    "tests/ros/test_namespaces.py",
    "tests/core/test_fetch.py",
    "tests/ros/test_reset_during_goals.py",
    "tests/ros/test_bursts.py",
    "tests/ros/test_humanoid_sensors.py",
    "tests/ros/test_sim_node.py",
    "tests/ros/test_g1_tables.py",
    "tests/ros/test_navigation.py",
    "tests/ros/test_console_scripts.py",
    "tests/ros/test_walking_speed_live.py",
    "tests/core/test_locomotion.py",
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


def stop_tagged_processes(tag_prefix: str, worker: str | None = None, grace_s: float = 5.0) -> list[int]:
    """Stop the processes workers left (those of ``worker``, e.g. "gw0", when given); returns the pids found."""
    return processes.stop_tagged_processes(WORKER_TAG_VARIABLE, tag_prefix,
                                           lambda tag: worker is None or tag.endswith(f"/{worker}"), grace_s)


FROZEN_RUNS: list[str] = []  # the controller's: tests whose worker the watchdog ended, each run once more


def pytest_handlecrashitem(crashitem: str, report: pytest.TestReport, sched: object) -> None:
    """A test whose worker froze runs once more, on a new worker; any other crash, or a second freeze, fails it.

    A freeze is a test the watchdog ended (its stacks are in the hang folder). Every freeze seen in this suite was
    the Fast DDS 2.14 deadlock of eProsima/Fast-DDS#6502 (a timer's unregistering waits for the event thread,
    whose callback waits for a lock the first thread holds), which stops every thread of the process with the
    GIL held: in rclpy's ``destroy_publisher`` closing a client, or in a wait the executor could not serve. It
    cannot be fixed from Python, and the PyPI wheels carry only Fast DDS 2.14.5. The test's assertions are not
    touched: the second run must pass all of them, and the summary prints the freeze's stacks and says that the
    test ran again. xdist hands the rest of the frozen file (the frozen test first) to a new worker (``make test``
    allows two); the frozen worker's processes (its bring-ups) are stopped here first.
    """
    worker = getattr(getattr(getattr(report, "node", None), "gateway", None), "id", "")
    stopped = stop_tagged_processes(f"{os.environ['SIM_TEST_RUN']}/", worker) if worker else []
    folder = pathlib.Path(os.environ.get(HANG_DIR_VARIABLE) or tempfile.gettempdir())
    # The file is written at each test's start; faulthandler adds "Timeout (...)!" and the stacks only when it fires.
    frozen = any(text.startswith(f"{crashitem} ran longer") and "\nTimeout (" in text
                 for text in (path.read_text() for path in folder.glob(f"{worker}-*.txt")))
    note = f"; {len(stopped)} of its processes were stopped" if stopped else ""
    if frozen and crashitem not in FROZEN_RUNS:
        FROZEN_RUNS.append(crashitem)
        report.outcome = "rerun"  # type: ignore[assignment]  # neither passed nor failed: the new run decides
        report.longrepr = f"{report.longrepr}: the watchdog ended it (a freeze), so it runs again on a new worker{note}"
    else:
        report.longrepr = f"{report.longrepr}{note}"


class FileSchedulingThatRecovers(LoadFileScheduling):
    """xdist's ``--dist loadfile``, with a crashed worker's unfinished files handed on to the new worker.

    xdist 3.8 puts every file the crashed worker was given back on the queue, finished ones too: a new worker handed
    a finished file is sent no test and never another. And a new worker is handed a single file: when that holds
    one test, the worker waits for a second (it runs a test only once it knows the next one, or is told to stop)
    that never comes. Both left ``make test`` waiting for ever after a freeze. Here the crashed worker's unfinished
    files go back first in the queue and the finished ones are dropped, and a worker that joins later is handed work
    twice, as the first workers are.
    """

    def remove_node(self, node: WorkerController) -> str | None:
        workload = self.assigned_work.pop(node)
        unfinished = {scope: tests for scope, tests in workload.items() if not all(tests.values())}
        if not unfinished:
            return None
        crashitem = next(nodeid for tests in unfinished.values() for nodeid, done in tests.items() if not done)
        for scope in reversed(unfinished):
            self.workqueue[scope] = unfinished[scope]
            self.workqueue.move_to_end(scope, last=False)
        for other in self.assigned_work:
            self._reschedule(other)
        return crashitem

    def schedule(self) -> None:
        joined_later = self.collection is not None
        super().schedule()
        if joined_later:
            for node in self.nodes:
                self._reschedule(node)


def pytest_xdist_make_scheduler(config: pytest.Config, log: object) -> LoadFileScheduling | None:
    """``--dist loadfile`` (``make test``) schedules with :class:`FileSchedulingThatRecovers`; others as xdist does."""
    return FileSchedulingThatRecovers(config, log) if config.getvalue("dist") == "loadfile" else None  # type: ignore[arg-type]


def pytest_report_teststatus(report: pytest.TestReport, config: pytest.Config) -> tuple[str, str, str] | None:
    """A frozen test that runs again is counted as "rerun", not as a pass or a failure."""
    if report.outcome == "rerun":
        return "rerun", "R", "RERUN"
    return None


@pytest.hookimpl(trylast=True)  # after the fixtures' tear-down
def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """The controller (or a run without workers) stops any process a worker of this run left behind."""
    if "PYTEST_XDIST_WORKER" not in os.environ:
        stop_tagged_processes(f"{os.environ['SIM_TEST_RUN']}/")


CPU_PROPERTY = "cpu_s"  # a test's CPU [s], set-up to tear-down: its worker's and the processes it started and waited for
CPU_BY_FILE: collections.Counter[str] = collections.Counter()  # the controller's: CPU [s] of each test file
_CPU_AT_SETUP = pytest.StashKey[float]()


def _cpu_s() -> float:
    """CPU [s] of this process and of its children that ended and were waited for (a bring-up stopped by a fixture)."""
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


@pytest.hookimpl(tryfirst=True)  # before the test's fixtures are set up
def pytest_runtest_setup(item: pytest.Item) -> None:
    item.stash[_CPU_AT_SETUP] = _cpu_s()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]):
    """The tear-down report carries the test's CPU (a module's last test also stops the module's bring-up: its CPU
    counts for the file); added before the report is made, which copies the item's properties."""
    if call.when == "teardown" and _CPU_AT_SETUP in item.stash:
        item.user_properties.append((CPU_PROPERTY, _cpu_s() - item.stash[_CPU_AT_SETUP]))
    yield


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    """The controller adds up each file's CPU from its tests' tear-down reports."""
    if report.when == "teardown":
        CPU_BY_FILE[report.nodeid.split("::", 1)[0]] += sum(v for k, v in report.user_properties if k == CPU_PROPERTY)


def pytest_terminal_summary(terminalreporter, exitstatus: int, config: pytest.Config) -> None:
    """The files that took the most CPU, then the stacks of every test the watchdog ended (the controller's summary);
    then that folder is removed."""
    if "PYTEST_XDIST_WORKER" in os.environ:
        return
    if CPU_BY_FILE:
        total = sum(CPU_BY_FILE.values())
        terminalreporter.section(f"CPU by test file: {total:.0f} s in all (the tests' processes and those they started)")
        for path, cpu_s in CPU_BY_FILE.most_common(10):
            terminalreporter.write_line(f"{cpu_s:8.1f} s  {100 * cpu_s / total:4.1f} %  {path}")
    if not os.environ.get(HANG_DIR_VARIABLE):
        return
    folder = pathlib.Path(os.environ[HANG_DIR_VARIABLE])
    for path in sorted(folder.glob("*.txt")):
        terminalreporter.section(f"hung test ({path.stem})", sep="=", red=True)
        terminalreporter.write(path.read_text())
    if FROZEN_RUNS:
        terminalreporter.section("frozen tests that ran again", sep="=", yellow=True)
        terminalreporter.write_line("The watchdog ended these tests' workers (their stacks are above); each ran once more:")
        for nodeid in FROZEN_RUNS:
            terminalreporter.write_line(f"  {nodeid}")
    shutil.rmtree(folder, ignore_errors=True)
