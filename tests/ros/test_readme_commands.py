"""The README's commands are true: each shell line of README.md is run here, in order.

Node starters (``sim_node``, ``bringup``, ``sim up``, ``ros2 run sim ...``) replace whatever the
previous one started. ``ros2`` verbs are not on PyPI (no ros2cli here), so each is carried out with
the rclpy calls ros2cli makes for it: the type loaded by its name, the YAML given on the line filled
into the request or goal, the same service or action. ``sim`` and ``scenario`` lines run as they are
(a ``scenario run`` or ``sweep`` line is validated here; the scenarios themselves run in
``tests/scenarios`` and ``make demo``). Set-up lines (make, sourcing, export, cp) are the shell's.
A line of a kind this file does not know fails the test, so a new README command needs a check.
Blocks fenced ``sh`` are the commands; a recipe that installs software from elsewhere (ros2cli) is
fenced ``bash`` and not run.

A starter that names no real-time factor of its own runs here at ``FAST_RTF``: the lines check outcomes, poses
and paces in sim time, and at real time the suite's longest test spent two thirds of its 3-4 min waiting for
the clock on the wall. A start whose goal is changed while it runs (``walking_speed`` set during a walk) keeps the
README's pace: the change lands where a user typing it would land it.
"""

from __future__ import annotations

import importlib
import math
import os
import pathlib
import re
import shlex
import signal
import subprocess
import sys
from typing import Any

import pytest
import yaml
from action_msgs.msg import GoalStatus
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import DescribeParameters, SetParameters

from sim_client.scenario.model import schema
from sim_client.scenario.running.sweep import parse_grid, points
from sim_ros.processes import BIN, ChildProcess
from sim_ros.session import RosSession, WaitTimeout
from tests.ros.actions import ready_client, result, send, wait_feedback

pytestmark = pytest.mark.slow

ROOT = pathlib.Path(__file__).resolve().parents[2]
SHELL_ONLY = ("make ", ". ", "export ", "cp ")
STARTERS = ("sim_node", "bringup", "ros2 run sim ", "sim up")
READY_S = 90.0
GOAL_WALL_S = 400.0
FAST_RTF = 3.0  # the pace of a start that names none (see the module's docstring); /sim runs as fast as it can below it


def readme_commands() -> list[str]:
    """Every command of the README's ``sh`` blocks: continuations joined, comments and ``&`` removed."""
    text = (ROOT / "README.md").read_text()
    commands = []
    for block in re.findall(r"```sh\n(.*?)```", text, flags=re.S):
        joined = block.replace("\\\n", " ")
        for line in joined.splitlines():
            code = _strip_comment(line).strip()
            if code:
                commands.append(code.removesuffix("&").strip())
    return commands


def _strip_comment(line: str) -> str:
    quote = ""
    for i, char in enumerate(line):
        if quote:
            quote = "" if char == quote else quote
        elif char in "\"'":
            quote = char
        elif char == "#" and (i == 0 or line[i - 1].isspace()):
            return line[:i]
    return line


def kind(command: str) -> str:
    if command.startswith(SHELL_ONLY):
        return "shell"
    if command.startswith(STARTERS):
        return "start"
    for prefix in ("ros2 param set", "ros2 param describe", "ros2 service call", "ros2 topic echo", "ros2 action send_goal",
                   "scenario list", "scenario run", "scenario sweep", "sim "):
        if command.startswith(prefix):
            return prefix
    return "unknown"


def test_every_readme_command_is_of_a_kind_this_test_runs():
    commands = readme_commands()
    assert len(commands) > 20
    unknown = [command for command in commands if kind(command) == "unknown"]
    assert not unknown, f"README commands this test cannot run (add a check for them): {unknown}"


def load_type(name: str) -> Any:
    package, sub, type_name = name.split("/")
    return getattr(importlib.import_module(f"{package}.{sub}"), type_name)


def fill(message: Any, values: dict[str, Any], where: str = "") -> Any:
    """Set a message's fields from a YAML mapping, as ros2cli's set_message_fields does."""
    for key, value in (values or {}).items():
        if not hasattr(message, key):
            raise AssertionError(f"{type(message).__name__} has no field {where}{key}")
        current = getattr(message, key)
        if isinstance(value, dict):
            fill(current, value, f"{where}{key}.")
        elif isinstance(current, float):
            setattr(message, key, float(value))
        else:
            setattr(message, key, value)
    return message


def parameter_value(text: str) -> ParameterValue:
    value = yaml.safe_load(text)
    if isinstance(value, bool):
        return ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=value)
    if isinstance(value, int):
        return ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=value)
    if isinstance(value, float):
        return ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value)
    return ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=str(value))


def feedback_timeline(feedback: list[Any]) -> str:
    """One line per change of a goal's stage or phase: its fields then (a failed fetch says where it went wrong)."""
    lines, last = [], None
    for message in feedback:
        key = (getattr(message, "stage", None), getattr(message, "phase", None))
        if key != last or message is feedback[-1]:
            lines.append(str(message))
            last = key
    return "\n".join(lines[-40:]) or "(none)"


class Shell:
    """Runs README commands one after another against the nodes the last starter brought up."""

    def __init__(self, client: Any, log_dir: pathlib.Path) -> None:
        self.client = client
        self.first_client = client  # the module's: the commands before the first start
        self.log_dir = log_dir
        self.nodes: ChildProcess | None = None
        self.sessions: list[RosSession] = []  # the current start's own (see close_session)
        self.running_goal: Any = None
        self.count = 0

    def stop(self) -> None:
        if self.nodes is not None:
            self.nodes.stop(timeout=30.0)
            self.nodes = None

    def close_session(self) -> None:
        """Close the current start's session while its bring-up still runs, before the bring-up is stopped.

        A participant deleted while Fast DDS removes another can deadlock (eProsima/Fast-DDS#6502, see the
        README's Known limits). A session closed right after its bring-up stopped hung two workers so; all
        sessions closed at the end, after six bring-ups had come and gone, hung one in ``destroy_publisher``
        (a fresh clone of 9afadde). Closed before its bring-up stops, only one session lives at a time and it
        is deleted while nothing it knows is leaving.
        """
        while self.sessions:
            self.sessions.pop().close()
        self.client = self.first_client

    def _new_session(self) -> None:
        """The commands after a start talk to its nodes through a client of their own, as a user's new
        terminal would (each ``ros2`` command there is a new process): a client kept across the README's
        bring-ups carries every earlier bring-up's discovery and subscriptions, and once got no answer at
        all from a new bring-up's /pick_place for 90 s."""
        for recorder in self.client.recorders:
            recorder.stop()
        self.sessions.append(RosSession("readme_shell", use_sim_time=False))
        self.client = self.sessions[-1]

    def run(self, command: str, following: str) -> None:
        handler = {
            "shell": lambda c: None, "start": self.start, "ros2 param set": self.param_set,
            "ros2 param describe": self.param_describe, "ros2 service call": self.service_call,
            "ros2 topic echo": self.topic_echo, "ros2 action send_goal": lambda c: self.send_goal(c, following),
            "scenario list": self.scenario_list, "scenario run": self.scenario_run, "scenario sweep": self.scenario_sweep,
            "sim ": self.sim,
        }[kind(command)]
        handler(command)

    def start(self, command: str, paced: bool = False) -> None:
        """Replace the running nodes with ``command``'s, at ``FAST_RTF`` unless ``paced`` or the line names a pace."""
        self.close_session()
        self.stop()
        args = shlex.split(command)
        if args[:3] == ["ros2", "run", "sim"]:  # what ros2 run does: the package's executable in lib/sim
            executable = pathlib.Path(sys.prefix) / "lib" / "sim" / args[3]
            assert os.access(executable, os.X_OK), f"ros2 run would not find {executable}"
            args = [args[3], *args[4:]]
        if not paced:
            args = faster(args)
        self.count += 1
        self.nodes = ChildProcess(args, self.log_dir / f"{self.count:02d}")
        # As a user would, the next command comes once the sim is up (and a signal never lands mid start-up).
        nodes = self.nodes
        self.client.wait_for(lambda: "active: physics running" in nodes.output() or not nodes.alive(), READY_S,
                             f"{command!r} to bring /sim up")
        self._new_session()

    def _require_nodes(self, command: str) -> None:
        last_output = self.nodes.output()[-2000:] if self.nodes is not None else ""
        assert self.nodes is not None and self.nodes.alive(), f"nothing runs for {command!r}: {last_output}"

    def param_set(self, command: str) -> None:
        self._require_nodes(command)
        _, _, _, node, name, value = shlex.split(command)
        request = SetParameters.Request(parameters=[Parameter(name=name, value=parameter_value(value))])
        # sent again until answered (RosSession.call: SetParameters is of SENT_AGAIN)
        answer = self.client.call(SetParameters, f"{node}/set_parameters", request, timeout=READY_S)
        assert answer.results[0].successful, f"{command}: {answer.results[0].reason}"
        if self.running_goal is not None and name == "walking_speed":
            self.check_pace(float(value))

    def check_pace(self, speed: float) -> None:
        """The running walk reaches the new pace within 2 s of sim time (measured on /odom over the 2 s after that)."""
        odom = self.client.record(Odometry, "/odom", qos=1000, keep=100_000)  # deep: a starved reader loses nothing
        self.client.wait_for(lambda: odom.count > 0, 30.0, "/odom")
        t0 = _stamp(odom.latest)

        def at(t: float) -> Any:
            return min(odom.messages(), key=lambda m: abs(_stamp(m) - t))

        self.client.wait_for(lambda: _stamp(odom.latest) >= t0 + 4.0, 120.0, "4 s of sim time after the change")
        a, b = at(t0 + 2.0).pose.pose.position, at(t0 + 4.0).pose.pose.position
        pace = math.dist((a.x, a.y), (b.x, b.y)) / 2.0
        assert pace == pytest.approx(speed, rel=0.10), f"pace {pace:.3f} m/s 2 s after walking_speed {speed}"

    def param_describe(self, command: str) -> None:
        self._require_nodes(command)
        _, _, _, node, name = shlex.split(command)
        self.client.wait_for(lambda: self._service_up(f"{node}/describe_parameters"), READY_S, f"{node}")
        answer = self.client.call(DescribeParameters, f"{node}/describe_parameters",
                                  DescribeParameters.Request(names=[name]), timeout=READY_S)
        assert answer.descriptors[0].type != ParameterType.PARAMETER_NOT_SET, f"{command}: not declared"
        assert answer.descriptors[0].description

    def _service_up(self, name: str) -> bool:
        return any(service == name for service, _ in self.client.node.get_service_names_and_types())

    def service_call(self, command: str) -> None:
        self._require_nodes(command)
        _, _, _, name, type_name, values = shlex.split(command)
        service_type = load_type(type_name)
        request = fill(service_type.Request(), yaml.safe_load(values))
        answer = self.client.call(service_type, name, request, timeout=READY_S)
        assert getattr(answer, "success", True), f"{command}: {answer}"
        outcome = getattr(answer, "result", None)  # simulation_interfaces answers with a Result (1 = RESULT_OK)
        assert getattr(outcome, "result", 1) == 1, f"{command}: {outcome}"

    def topic_echo(self, command: str) -> None:
        self._require_nodes(command)
        _, _, _, topic, type_name = shlex.split(command)[:5]
        recorder = self.client.record(load_type(type_name), topic, keep=10)
        try:
            self.client.wait_for(lambda: recorder.count > 0, READY_S, f"a message on {topic}")
        finally:
            recorder.stop()  # the user's Ctrl-C: left subscribed, every later message would still be taken

    def send_goal(self, command: str, following: str) -> None:
        self._require_nodes(command)
        args = [arg for arg in shlex.split(command) if arg != "--feedback"]
        _, _, _, name, type_name, values = args
        action_type = load_type(type_name)
        goal = fill(action_type.Goal(), yaml.safe_load(values))
        try:
            action = ready_client(self.client, action_type, name, timeout=READY_S)
        except WaitTimeout as timeout:
            raise AssertionError(f"{command}: {timeout}; the nodes' last output:\n{self.nodes.output()[-4000:]}") from timeout
        sent = send(self.client, action, goal)
        assert sent.handle.accepted, f"{command}: rejected"
        if following.startswith("ros2 param set"):  # "meanwhile": the next line acts on the running goal
            wait_feedback(self.client, sent, lambda f: True, READY_S, f"feedback of {name}")
            self.running_goal = sent
            return
        self.finish(sent, command)

    def finish(self, sent: Any, command: str) -> None:
        outcome = result(self.client, sent, timeout=GOAL_WALL_S)
        if outcome.status != GoalStatus.STATUS_SUCCEEDED:  # what a person needs to see where it went wrong
            output = self.nodes.output()[-6000:] if self.nodes is not None else ""
            raise AssertionError(f"{command}: {outcome.result}\nits feedback, where it changed:\n"
                                 f"{feedback_timeline(sent.feedback)}\nthe nodes' last output:\n{output}")

    def finish_running(self) -> None:
        if self.running_goal is not None:
            sent, self.running_goal = self.running_goal, None
            self.finish(sent, "the running goal")

    def scenario_list(self, command: str) -> None:
        done = _run(command)
        assert "walk_2m" in done.stdout

    def scenario_run(self, command: str) -> None:
        assert schema.load(schema.find(shlex.split(command)[2])).name

    def scenario_sweep(self, command: str) -> None:
        args = shlex.split(command)
        grid = parse_grid([args[i + 1] for i, arg in enumerate(args) if arg == "--grid"])
        seeds = [int(s) for i, arg in enumerate(args) if arg == "--seeds" for s in args[i + 1].split(",")] or [0]
        assert points(schema.find(args[2]), grid, seeds)

    def sim(self, command: str) -> None:
        self._require_nodes(command)
        if command.startswith("sim watch"):
            self.sim_watch(command)
            return
        done = _run(command)
        assert done.returncode == 0, f"{command}: exit {done.returncode}\n{done.stdout[-2000:]}{done.stderr[-2000:]}"

    def sim_watch(self, command: str) -> None:
        """Piped into a file it prints a snapshot per second; Ctrl-C ends it cleanly."""
        watch = subprocess.Popen([str(BIN / "sim"), *shlex.split(command)[1:]], stdout=subprocess.PIPE,
                                 stderr=subprocess.STDOUT, text=True, env=dict(os.environ))
        try:
            assert watch.stdout is not None
            first = watch.stdout.readline()  # blocks until a snapshot (bounded by the wait below on failure)
            assert "t=" in first or "sim" in first.lower(), first
        finally:
            watch.send_signal(signal.SIGINT)
            try:
                code = watch.wait(timeout=30.0)
            except subprocess.TimeoutExpired:
                watch.kill()
                code = watch.wait()
        assert code in (0, 130, -signal.SIGINT), f"sim watch exited with {code}"


def faster(args: list[str]) -> list[str]:
    """A starter's arguments with ``FAST_RTF`` added, unless they name a real-time factor already."""
    if "--rtf" in args or any(arg.startswith("real_time_factor:=") for arg in args):
        return args
    if args[0] == "sim_node":
        return [*args, "-p", f"real_time_factor:={FAST_RTF!r}"] if "--ros-args" in args else \
            [*args, "--ros-args", "-p", f"real_time_factor:={FAST_RTF!r}"]
    return [*args, "--rtf", f"{FAST_RTF!r}"]  # bringup, sim up


def changes_a_running_goal(commands: list[str], start: int) -> bool:
    """Whether the commands after the start at ``start`` (until the next start) change a goal while it runs."""
    for i in range(start + 1, len(commands) - 1):
        if kind(commands[i]) == "start":
            return False
        if kind(commands[i]) == "ros2 action send_goal" and commands[i + 1].startswith("ros2 param set"):
            return True
    return False


def test_a_start_runs_fast_unless_it_names_a_pace_or_a_goal_is_changed_while_it_runs():
    assert faster(["bringup", "--robot", "g1"]) == ["bringup", "--robot", "g1", "--rtf", "3.0"]
    assert faster(["bringup", "--robot", "panda", "--rtf", "2"]) == ["bringup", "--robot", "panda", "--rtf", "2"]
    assert faster(["sim_node", "--ros-args", "-p", "robot:=g1"])[-2:] == ["-p", "real_time_factor:=3.0"]
    assert faster(["sim_node", "--ros-args", "-p", "real_time_factor:=0"]).count("-p") == 1
    commands = ["bringup --robot g1", "ros2 action send_goal /walk sim_interfaces/action/Walk '{}'",
                "ros2 param set /locomotion walking_speed 0.5", "bringup --robot panda", "sim pick box_1"]
    assert changes_a_running_goal(commands, 0) and not changes_a_running_goal(commands, 3)


def _stamp(msg: Any) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def _run(command: str) -> subprocess.CompletedProcess[str]:
    args = shlex.split(command)
    return subprocess.run([str(BIN / args[0]), *args[1:]], capture_output=True, text=True, timeout=GOAL_WALL_S,
                          env=dict(os.environ))


def test_the_readme_commands_run_in_order(client, tmp_path):
    commands = readme_commands()
    shell = Shell(client, tmp_path)
    try:
        for i, command in enumerate(commands):
            following = commands[i + 1] if i + 1 < len(commands) else ""
            if kind(command) == "start":
                shell.finish_running()
                shell.start(command, paced=changes_a_running_goal(commands, i))
                continue
            shell.run(command, following)
            if shell.running_goal is not None and not following.startswith("ros2 param set"):
                shell.finish_running()
        shell.finish_running()
    finally:
        shell.close_session()
        shell.stop()
