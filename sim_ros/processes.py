"""Launching project executables as child processes, and stopping them for sure."""

from __future__ import annotations

import collections
import contextlib
import os
import pathlib
import signal
import subprocess
import sys
import tempfile
import threading
import time
import typing
from collections.abc import Iterator
from contextlib import contextmanager

BIN = pathlib.Path(sys.executable).parent
LAST_LINES = 20  # lines of a relayed child's output kept to report when it dies


class ChildProcess:
    """An executable of this venv in its own process group, its output in a log file."""

    def __init__(self, args: list[str], log_dir: pathlib.Path | None = None, inherit_output: bool = False,
                 own_group: bool = True, relay_output: bool = False, env: dict[str, str] | None = None) -> None:
        """``env``: the process's environment (default: this one's)."""
        self.args = args
        environment = dict(os.environ) if env is None else env
        self._own_group = own_group
        self._log: typing.IO[bytes] | None = None
        self._relay: threading.Thread | None = None
        self._temporary_log = False  # the log is a file of its own in the temporary directory
        self.last_lines: collections.deque[str] = collections.deque(maxlen=LAST_LINES)
        if relay_output:  # output relayed line by line to the caller's stdout, its last lines kept
            self.log_path = pathlib.Path("/dev/null")
            self.process = subprocess.Popen(
                [str(BIN / args[0]), *args[1:]], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                start_new_session=own_group, env=environment)
            self._relay = threading.Thread(target=self._relay_lines, name=f"{args[0]}-output", daemon=True)
            self._relay.start()
            return
        if inherit_output:  # output goes where the caller's goes (a launcher in a terminal)
            self.log_path = pathlib.Path("/dev/null")
        elif log_dir is not None:
            log_dir.mkdir(parents=True, exist_ok=True)
            self.log_path = log_dir / f"{args[0]}.log"
            self._log = open(self.log_path, "wb")  # noqa: SIM115 - closed in stop()
        else:
            handle = tempfile.NamedTemporaryFile(  # noqa: SIM115 - the process writes to it; closed in stop()
                prefix=f"{args[0]}-", suffix=".log", delete=False)
            self.log_path = pathlib.Path(handle.name)
            self._log = handle
            self._temporary_log = True
        self.process = subprocess.Popen(
            [str(BIN / args[0]), *args[1:]], stdout=self._log, stderr=None if inherit_output else subprocess.STDOUT,
            start_new_session=own_group, env=environment,
        )

    def _relay_lines(self) -> None:
        assert self.process.stdout is not None
        for raw in self.process.stdout:
            line = raw.decode(errors="replace")
            self.last_lines.append(line.rstrip("\n"))
            sys.stdout.write(line)
            sys.stdout.flush()

    def output(self) -> str:
        if self._relay is not None:
            return "\n".join(self.last_lines)
        return self.log_path.read_text(errors="replace")

    def alive(self) -> bool:
        return self.process.poll() is None

    def send_signal(self, sig: int) -> None:
        try:
            if self._own_group:
                os.killpg(self.process.pid, sig)
            elif self.alive():
                self.process.send_signal(sig)
        except ProcessLookupError:
            pass

    def stop(self, timeout: float = 10.0, interrupt: bool = True) -> int:
        """SIGINT the process (its whole group when it has one); SIGKILL what is left after ``timeout`` s.

        Args:
            timeout: wall seconds to wait for a clean exit.
            interrupt: send SIGINT first (False when the caller already did).
        """
        if self.alive():
            if interrupt:
                self.send_signal(signal.SIGINT)
            try:
                self.process.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                self.send_signal(signal.SIGKILL)
                self.process.wait(timeout=timeout)
        self.send_signal(signal.SIGKILL)  # leftovers of the group, if any
        if self._log is not None:
            self._log.close()
        if self._relay is not None:
            self._relay.join(2.0)
        return int(self.process.returncode)

    def discard_log(self) -> None:
        """Remove the log file this process was given in the temporary directory (call after :meth:`stop`)."""
        if self._temporary_log:
            self.log_path.unlink(missing_ok=True)


@contextmanager
def running(args: list[str], log_dir: pathlib.Path | None = None) -> Iterator[ChildProcess]:
    """Run an executable for the duration of a ``with`` block."""
    child = ChildProcess(args, log_dir)
    try:
        yield child
    finally:
        code = child.stop()
        if code not in (0, -signal.SIGINT, 130):
            sys.stderr.write(f"--- {' '.join(args)} exited with {code}; last output:\n{child.output()[-3000:]}\n")
        child.discard_log()


def child_processes(parent: int) -> dict[str, int]:
    """Executable name -> pid of the processes ``parent`` started (read from /proc; e.g. bringup's nodes)."""
    found = {}
    for entry in pathlib.Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            cmdline = (entry / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue  # it ended meanwhile
        if int(stat.rsplit(")", 1)[1].split()[1]) == parent and len(cmdline) > 1:
            found[pathlib.Path(cmdline[1].decode(errors="replace")).name] = int(entry.name)
    return found


def tagged_processes(variable: str, tag_prefix: str) -> dict[int, str]:
    """pid -> tag of this user's processes whose environment has ``variable`` set to a value starting with
    ``tag_prefix`` (Linux /proc): what a tagged process started, at any depth. This process and its own
    children are left out."""
    entry = f"{variable}={tag_prefix}".encode()
    found = {}
    for proc in pathlib.Path("/proc").iterdir():
        if not proc.name.isdigit() or int(proc.name) == os.getpid():
            continue
        try:
            environ = (proc / "environ").read_bytes()
            parent = int((proc / "stat").read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue  # another user's process, or it ended meanwhile
        start = environ.find(entry)
        if start >= 0 and parent != os.getpid():
            found[int(proc.name)] = environ[start + len(variable) + 1: environ.find(b"\0", start)].decode()
    return found


def stop_tagged_processes(variable: str, tag_prefix: str, select: typing.Callable[[str], bool] = lambda tag: True,
                          grace_s: float = 5.0) -> list[int]:
    """SIGINT the tagged processes (see :func:`tagged_processes`) whose tag ``select`` accepts (a bring-up leaves the
    ROS graph cleanly on it), SIGKILL what is left after ``grace_s`` wall seconds. Returns the pids found."""

    def left() -> list[int]:
        return [pid for pid, tag in tagged_processes(variable, tag_prefix).items() if select(tag)]

    pids = left()
    for pid in pids:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGINT)
    deadline = time.monotonic() + grace_s
    while time.monotonic() < deadline and any(pathlib.Path(f"/proc/{pid}").exists() for pid in pids):
        time.sleep(0.05)  # polling the processes' end, bounded by the grace period
    for pid in left():
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)
    return pids
