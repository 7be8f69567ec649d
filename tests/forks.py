"""Branches of one simulation: a check run in a forked copy of the test's process, from the state it has now.

Tests that share a long prefix (the G1 walking to a table and reaching for an object) run it once and
branch where they differ. ``os.fork`` copies the simulation, its controllers and their solvers exactly,
nothing rebuilt or serialized, so a branch goes on as a fresh run to the same point would (the core is
deterministic), and what it does never reaches the trunk. The branch's failure comes back as its traceback.
The core's tests hold no ROS and no threads of their own, which is what makes the copy whole.
"""

from __future__ import annotations

import gc
import os
import sys
import traceback
from collections.abc import Callable
from dataclasses import dataclass


def in_fork(check: Callable[[], None]) -> str | None:
    """Run ``check()`` in a forked copy of this process; None when it passed, else why not (its traceback).

    The branch writes its output where the test's goes (pytest captures it); it ends with ``os._exit``, so
    nothing of the test's own tear-down runs twice.
    """
    sys.stdout.flush()
    sys.stderr.flush()
    # The garbage of earlier tests of this worker is collected here, not in the branch: on 29 November a branch
    # crashed its worker with a segfault while "Garbage-collecting" (building its arm model), i.e. while freeing
    # something it had only inherited, such as an earlier ROS test's handles, made with threads a fork does not
    # copy. The branch then never collects what it was given (gc.freeze), only its own garbage.
    gc.collect()
    read_fd, write_fd = os.pipe()
    pid = os.fork()
    if pid == 0:  # the branch
        gc.freeze()
        code = 0
        try:
            os.close(read_fd)
            try:
                check()
                report = b""
            except BaseException:  # noqa: BLE001 - every failure of the branch is the test's failure
                report = traceback.format_exc().encode()
            with os.fdopen(write_fd, "wb") as pipe:
                pipe.write(report)
            sys.stdout.flush()
            sys.stderr.flush()
        except BaseException:  # noqa: BLE001 - the report could not be written: the exit code says so
            code = 1
        finally:
            os._exit(code)
    os.close(write_fd)
    with os.fdopen(read_fd, "rb") as pipe:
        report = pipe.read()
    _, status = os.waitpid(pid, 0)
    if report:
        return report.decode(errors="replace")
    if status != 0:
        return f"the branch's process ended without a report (wait status {status})"
    return None


@dataclass
class Branch:
    """A check that branches off a run (:func:`in_fork`) at the first step where ``when()`` holds."""

    when: Callable[[], bool]
    check: Callable[[], None]
    failure: str | None = None  # why the check failed in its branch (None: it passed, or has not run)
    ran: bool = False

    def verdict(self, what: str) -> None:
        """Fail, naming ``what``, unless the branch ran and its check passed."""
        assert self.ran, f"{what}: the run never came to its moment"
        assert self.failure is None, f"{what}, in its branch of the run:\n{self.failure}"


def fire_due(waiting: list[Branch]) -> None:
    """Run (each in a fork) the branches of ``waiting`` that are due now, and take them off the list."""
    for branch in [branch for branch in waiting if branch.when()]:
        branch.failure, branch.ran = in_fork(branch.check), True
        waiting.remove(branch)
