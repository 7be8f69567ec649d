"""The `sim` command line against a running sim node (parameters, watch) and the arm server (a goal)."""

from __future__ import annotations

import signal
import subprocess
import threading

import pytest
from rosgraph_msgs.msg import Clock

from sim_ros.processes import BIN, running


def sim(*args: str, timeout: float = 90.0) -> subprocess.CompletedProcess:
    return subprocess.run([str(BIN / "sim"), *args], capture_output=True, text=True, timeout=timeout)


class LiveCommand:
    """A ``sim`` command left running, its output lines collected as they come."""

    def __init__(self, *args: str) -> None:
        self.process = subprocess.Popen([str(BIN / "sim"), *args], stdout=subprocess.PIPE,
                                        stderr=subprocess.STDOUT, text=True)
        self.lines: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            self.lines.append(line.rstrip("\n"))

    @property
    def output(self) -> str:
        return "\n".join(self.lines)

    def interrupt_when(self, client, ready, what: str, timeout: float, exit_timeout: float) -> int:
        """Once ``ready()`` holds, Ctrl-C the command; its exit code (killed if it is still running after)."""
        try:
            client.wait_for(lambda: ready() or self.process.poll() is not None, timeout, what)
            assert self.process.poll() is None, self.output
            self.process.send_signal(signal.SIGINT)
            code = self.process.wait(exit_timeout)
            self._reader.join(exit_timeout)
            return code
        finally:
            if self.process.poll() is None:
                self.process.kill()
                self.process.wait()


@pytest.fixture(scope="module")
def panda(client):
    args = ["bringup", "--robot", "panda", "--rtf", "2"]
    with running(args) as process:
        clock = client.record(Clock, "/clock", keep=5)
        client.wait_for(lambda: clock.count > 0 or not process.alive(), 60.0, "first /clock of the panda bringup")
        assert process.alive(), process.output()
        yield process


def test_param_describe_get_set_list(panda):
    described = sim("param", "describe", "sim", "real_time_factor")
    assert described.returncode == 0, described.stderr
    assert "Type: double" in described.stdout and "0.0 .. 1000.0" in described.stdout
    assert sim("param", "set", "sim", "real_time_factor", "3").returncode == 0  # an integer is sent as a double
    got = sim("param", "get", "sim", "real_time_factor")
    assert "3.0" in got.stdout
    refused = sim("param", "set", "sim", "real_time_factor", "-2")
    assert refused.returncode == 1 and "out of range" in refused.stdout
    listed = sim("param", "list", "sim")
    assert "joint_state_rate" in listed.stdout.split()
    missing = sim("param", "get", "sim", "no_such_parameter")
    assert missing.returncode == 2 and "no parameter" in missing.stderr
    assert sim("param", "set", "sim", "real_time_factor", "2.0").returncode == 0


def test_watch_once_shows_sim_time_and_the_base(panda):
    shown = sim("watch", "--once")
    assert shown.returncode == 0, shown.stderr
    assert "sim time" in shown.stdout and "panda_link0" in shown.stdout


def test_move_arm_streams_feedback_until_the_result(panda):
    moved = sim("move-arm", "0.4", "0.1", "0.35")
    assert moved.returncode == 0, moved.stdout + moved.stderr
    lines = moved.stdout.splitlines()
    assert any("position_error=" in line for line in lines), moved.stdout
    assert "SUCCEEDED (SUCCESS)" in lines[-2] or "SUCCEEDED (SUCCESS)" in moved.stdout


def test_ctrl_c_cancels_the_running_goal(panda, client):
    assert sim("param", "set", "arm", "max_velocity_scaling", "0.05").returncode == 0  # a slow move to interrupt
    try:
        command = LiveCommand("move-arm", "0.3", "-0.3", "0.5")
        code = command.interrupt_when(client, lambda: any("position_error=" in line for line in command.lines),
                                      "feedback of the move", 60.0, 30.0)
    finally:
        assert sim("param", "set", "arm", "max_velocity_scaling", "0.5").returncode == 0
    assert code == 1, command.output
    assert "canceling the goal" in command.output
    assert "CANCELED (CANCELED)" in command.output and "the arm holds" in command.output


def test_watch_runs_until_ctrl_c(panda, client):
    command = LiveCommand("watch")
    def shows_sim_time() -> bool:
        return any("sim time" in line and " s " in line for line in command.lines)

    code = command.interrupt_when(client, shows_sim_time, "a watch view with the sim time (one per second when piped)",
                                  30.0, 15.0)
    assert code == 0, command.output
    assert shows_sim_time(), command.output


def test_push_is_applied_or_refused_with_the_allowed_values(panda):
    pushed = sim("push", "0", "0", "1", "--duration", "0.05")
    assert pushed.returncode == 0 and "pushing panda_link0 until t=" in pushed.stdout, pushed.stdout + pushed.stderr
    refused = sim("push", "0", "0", "1", "--duration", "20")
    assert refused.returncode == 1 and "refused: duration must be in (0, 10]" in refused.stdout, refused.stdout
