"""``recording.mcap`` written by a process of its own, as ``ros2 bag record`` writes a bag.

In the runner's process, every message of every topic (~7000 for walk_2m, 9.4 s of sim time) went through the
runner's Python executor, which rebuilds its wait set on each wake-up: 1.4 s of CPU, on the runner's thread.
Here a child takes them on rclpy's C++ events executor (0.6-0.7 s of CPU for the same run), and the runner's
executor handles only what the run reads. It halved the recording's CPU; the wall time of a lock-stepped run
barely moved, both cores being busy either way (see the README's timings). The child looks for new topics by
itself; the runner only asks it to look at once where topics are known to appear (once the nodes answer).

The runner holds a :class:`RecordingProcess`; the child (``python -m sim_client.scenario.outputs.recorder_process``)
runs :class:`~sim_client.scenario.outputs.recording.McapRecorder` on a session of its own and answers one JSON line
per command read from its stdin:

- ``status``: ``{"counts": {topic: n}, "latest_stamp_s": {topic: s}, "skipped": {topic: why}, "matched": {topic: n}}``
  (``matched``: the publishers each topic's subscription has matched);
- ``discover``: looks for new topics now (it also looks every ``DISCOVER_EVERY_S`` by itself); no answer;
- ``close``: finishes the file, answers its status and exits. End of input (the runner is gone) closes it too.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import pathlib
import select
import subprocess
import sys
import time
from dataclasses import dataclass, field
from typing import Any

from sim_ros.scheduling import lock_step_environment

DISCOVER_EVERY_S = 0.5  # [s of wall time] the child looks for new topics this often
ANSWER_WALL_S = 30.0  # [s of wall time] the runner waits this long for an answer (a close writes the file's index)
EXIT_WALL_S = 10.0  # [s of wall time] ... and this long for the child to exit after closing


@dataclass
class RecordingStatus:
    """What the recording holds: messages per topic, the newest leading stamp [s] of stamped topics, and the topics
    it could not record with the reason."""

    counts: dict[str, int] = field(default_factory=dict)
    latest_stamp_s: dict[str, float] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)
    matched: dict[str, int] = field(default_factory=dict)  # topic -> publishers its subscription has matched


class RecordingError(RuntimeError):
    """The recording process did not answer, or exited; the message says how and where its log is."""


class RecordingProcess:
    """The runner's handle on a recorder child process writing ``path``.

    Args:
        path: the MCAP file to write.
        exclude: topics (full names) not to record.
        namespace: the bring-up's namespace ("" = the root); only its topics are recorded.
        log_path: where the child's stderr goes.
        lock_step: the run is lock-stepped: the child's threads are SCHED_BATCH (``sim_ros.scheduling``).
    """

    def __init__(self, path: pathlib.Path, exclude: tuple[str, ...] = (), namespace: str = "",
                 log_path: pathlib.Path | None = None, lock_step: bool = False) -> None:
        self.path = path
        self.log_path = log_path or path.with_name("recorder.log")
        args = [sys.executable, "-m", __name__, "--out", str(path), "--namespace", namespace]
        for topic in exclude:
            args += ["--exclude", topic]
        with open(self.log_path, "wb") as log:
            # Lock-stepped, a consumer nobody waits on mid-run: its threads yield to /sim's stepping (sim_ros.scheduling).
            env = lock_step_environment(os.environ) if lock_step else dict(os.environ)
            self._process = subprocess.Popen(args, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=log, env=env)
        self._buffer = b""
        self.final: RecordingStatus | None = None  # the status answered by close()

    def discover(self) -> None:
        """Ask the child to look for new topics now."""
        self._send("discover")

    def status(self) -> RecordingStatus:
        """What the child has recorded so far (its final status once closed).

        Raises:
            RecordingError: the child did not answer within ``ANSWER_WALL_S`` or has exited.
        """
        if self.final is not None:
            return self.final
        self._send("status")
        return self._answer()

    def close(self) -> RecordingStatus:
        """Finish the file and end the child; returns what the file holds.

        Raises:
            RecordingError: the child did not answer or exit in time (it is killed then).
        """
        if self.final is not None:
            return self.final
        try:
            self._send("close")
            self.final = self._answer()
            self._process.wait(timeout=EXIT_WALL_S)
        except (RecordingError, subprocess.TimeoutExpired) as error:
            self._process.kill()
            self._process.wait()
            raise RecordingError(f"the recorder did not close {self.path} cleanly: {error}; see {self.log_path}") from None
        finally:
            for pipe in (self._process.stdin, self._process.stdout):
                if pipe is not None:
                    with contextlib.suppress(OSError):  # a write the dead child never read fails its flush
                        pipe.close()
        return self.final

    def _send(self, command: str) -> None:
        stdin = self._process.stdin
        assert stdin is not None
        try:
            stdin.write(f"{command}\n".encode())
            stdin.flush()
        except (OSError, ValueError):  # the child is gone (a broken pipe), or the pipe closed
            raise RecordingError(f"the recorder exited with code {self._process.poll()}; see {self.log_path}") from None

    def _answer(self) -> RecordingStatus:
        stdout = self._process.stdout
        assert stdout is not None
        deadline = time.monotonic() + ANSWER_WALL_S
        while b"\n" not in self._buffer:
            left = deadline - time.monotonic()
            if left <= 0:
                raise RecordingError(f"the recorder did not answer within {ANSWER_WALL_S:g} s; see {self.log_path}")
            ready, _, _ = select.select([stdout], [], [], left)
            if ready:
                chunk = os.read(stdout.fileno(), 1 << 16)
                if not chunk:
                    raise RecordingError(f"the recorder exited with code {self._process.wait()}; see {self.log_path}")
                self._buffer += chunk
        line, _, self._buffer = self._buffer.partition(b"\n")
        answer = json.loads(line)
        return RecordingStatus(answer["counts"], answer["latest_stamp_s"], answer["skipped"], answer["matched"])


# ----- the child -------------------------------------------------------------------------
POLL_S = 0.02  # [s of wall time] the child reads the runner's commands this often


class _Child:
    """The child's node, spun on rclpy's C++ events executor on one thread: a message costs its callback only (on
    rclpy's Python executor every wake-up rebuilds a wait set of ~40 subscriptions: 1.4 s of CPU for walk_2m's
    ~7000 messages, on a machine whose other core steps /sim). Commands are read by a steady-clock timer of the same
    executor, so subscriptions are made and destroyed on the thread that spins them."""

    def __init__(self, out: pathlib.Path, namespace: str, exclude: tuple[str, ...], answers: Any) -> None:
        import rclpy
        from rclpy.clock import Clock, ClockType
        from rclpy.experimental import EventsExecutor
        from rclpy.node import Node

        from sim_client.scenario.outputs.recording import McapRecorder  # (imports sim_ros: Fast DDS settings before rclpy.init)
        from sim_ros.scheduling import yield_to_physics

        namespace = namespace.strip("/")
        yield_to_physics()  # a consumer: its wake-ups wait for a free core, not take /sim's (sim_ros.scheduling)
        rclpy.init()
        # On its wall clock: the recording's times are the messages' own stamps (McapRecorder), so this node needs no
        # /clock subscription of its own (every /clock message would wake this process once more).
        self.node = Node("scenario_recorder", namespace=f"/{namespace}" if namespace else None)
        self.namespace = f"/{namespace}" if namespace else ""
        self.executor = EventsExecutor()
        self.executor.add_node(self.node)
        self.recorder = McapRecorder(self, out, exclude=exclude, namespace=self.namespace)
        self.done = False
        self._answers = answers  # the runner reads one JSON line per answer here
        self._line = b""
        self._last_discover = 0.0
        self.node.create_timer(POLL_S, self._poll, clock=Clock(clock_type=ClockType.STEADY_TIME))

    def destroy_subscription(self, subscription: Any) -> None:  # what McapRecorder asks of its session
        self.node.destroy_subscription(subscription)

    def _poll(self) -> None:
        if time.monotonic() - self._last_discover >= DISCOVER_EVERY_S:
            self._last_discover = time.monotonic()
            self.recorder.discover()
        stdin = sys.stdin.buffer
        while not self.done and select.select([stdin], [], [], 0.0)[0]:
            chunk = os.read(stdin.fileno(), 4096)
            if not chunk:  # the runner is gone: close the file as it stands
                self.recorder.close()
                self.done = True
                return
            self._line += chunk
            while b"\n" in self._line and not self.done:
                command, _, self._line = self._line.partition(b"\n")
                self._command(command.decode().strip())

    def _command(self, text: str) -> None:
        if text == "discover":
            self.recorder.discover()
        elif text == "status":
            self._answer()
        elif text == "close":
            self.recorder.close()
            self._answer()
            self.done = True
        else:
            print(f"recorder: unknown command {text!r}", file=sys.stderr)

    def _answer(self) -> None:
        recorder = self.recorder
        status = {"counts": dict(recorder.counts), "latest_stamp_s": dict(recorder.latest_stamp_s),
                  "skipped": dict(recorder.skipped), "matched": recorder.matched()}
        self._answers.write((json.dumps(status) + "\n").encode())
        self._answers.flush()


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description="Record every topic of a bring-up into an MCAP file (the scenario "
                                                 "runner's recorder; commands on stdin, see the module's docstring).")
    parser.add_argument("--out", type=pathlib.Path, required=True)
    parser.add_argument("--namespace", default="")
    parser.add_argument("--exclude", action="append", default=[])
    options = parser.parse_args(argv)
    # The answers keep stdout's pipe to themselves: what else writes to file descriptor 1 goes to the log instead (Fast
    # DDS prints its errors there, e.g. "Failed init_port ... open_and_lock_file failed" where a killed process left
    # its shared-memory port locked, which the runner once read as an answer and failed on).
    answers = os.fdopen(os.dup(sys.stdout.fileno()), "wb")
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())
    import rclpy  # imported here: the runner's side above needs neither rclpy nor mcap

    child = _Child(options.out, options.namespace, tuple(options.exclude), answers)
    try:
        child.recorder.discover()
        while not child.done and rclpy.ok():
            child.executor.spin_once(timeout_sec=0.2)
    except KeyboardInterrupt:  # Ctrl-C reaches the runner's whole process group: the file is still closed
        pass
    finally:
        child.recorder.close()
        child.node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
