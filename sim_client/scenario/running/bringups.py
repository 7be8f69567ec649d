"""One bring-up for consecutive runs of the same robot and pace: started once, reset between runs, and for a run in
another scene, that scene loaded (``/sim/load_world``; the action servers follow it).

A run on a reused bring-up gives the report a run on fresh nodes gives (apart from wall times): the
parameters a run changed (``set_param`` steps) are set back to the values they had before the first
change at the end of that run, through its session (which has found their nodes: a new session took
1.5-4 s to find a node's parameter services), and before the next run ``/sim/reset_simulation``
(SCOPE_ALL) puts the scene back to its keyframe, ends the goals still running in ``/sim`` and restarts
sim time, and with it the publication grid, at 0: the state of a bring-up just started paused. The
runs on a bring-up share one client session and its clients (found by the nodes once); each run
subscribes to its recordings anew, so they start empty. A bring-up is not reused after a run
that ended in an error (a failed step, not a failed expectation), nor when it has exited: the next run
starts its own.
"""

from __future__ import annotations

import os
import pathlib
import shutil
import signal
import sys
import tempfile
from dataclasses import dataclass, field
from typing import Any, TextIO

from rcl_interfaces.msg import Parameter as ParameterMsg, ParameterValue
from rclpy.parameter import Parameter

import robot_models
from sim_client.scenario.model.schema import Scenario
from sim_client.scenario.running.run_clients import RunClients
from sim_client.scenario.running.sim_time import SERVICE_WALL_S, StepFailure
from sim_ros.processes import ChildProcess
from sim_ros.scheduling import lock_step_environment
from sim_ros.session import RosSession, WaitTimeout
from simulation_interfaces.msg import Result
from simulation_interfaces.srv import LoadWorld, ResetSimulation

BringupKey = tuple[str, str, float]  # robot, scene, real-time factor
# /clock of a scenario's bring-up [Hz of sim time]: what its nodes on sim time need, and /sim's default (100 until 28
# November), named here because a run's settle depends on it. Their timers on sim time run at 10 Hz (the servers' resend
# watchdog); action feedback and skill progress go by the stamps of /sim's messages, not by a node's clock. Every node
# of a bring-up (and the runner and the recorder) handles every /clock message in Python, and each wakes a process /sim
# shares 2 cores with: walk_2m recorded, lock-stepped, went from wall/sim 0.192 at 50 Hz to 0.164 at 20 Hz (medians of
# 4, alternated; 10 Hz gave no more, 0.169 against 0.168).
CLOCK_RATE_HZ = 20.0
# /joint_states of a scenario's bring-up [Hz of sim time]: what its recording, plots and video read (a 20 fps video
# of a run played at most twice as fast reads 40 per sim second), not /sim's default 200.
JOINT_STATE_RATE_HZ = 100.0


@dataclass
class ParameterKeeper:
    """The values a bring-up's nodes had before a run first changed them, to set them back between runs.

    A node is read (every parameter) just before a run sets one of its parameters for the first time on
    this bring-up: until then it has its start-up values, as set back after every run.
    """

    kept: dict[str, dict[str, ParameterValue]] = field(default_factory=dict)  # node -> name -> value at start-up
    changed: bool = False  # a run may have changed a parameter since the last restore
    last_restored: list[str] = field(default_factory=list)  # what the last restore set back ("node name")

    def remember(self, session: RosSession, node: str) -> None:
        """Read every parameter of ``node`` (``"locomotion"`` or ``"/locomotion"``), once per bring-up; call it
        before each change a run makes."""
        self.changed = True
        node = node if node.startswith("/") else f"{session.namespace}/{node}"
        if node in self.kept:
            return
        client = session.parameters(node)
        session.wait_for(client.services_are_ready, SERVICE_WALL_S, f"parameter services of {node}")
        names = sorted(session.wait_future(client.list_parameters([], 0), SERVICE_WALL_S, f"list of {node}").result.names)
        values = session.wait_future(client.get_parameters(names), SERVICE_WALL_S, f"parameters of {node}").values
        self.kept[node] = dict(zip(names, values, strict=True))

    def restore(self, session: RosSession) -> list[str]:
        """Set back every kept parameter that differs now; returns ``node name`` of each one set back.

        Nothing is asked when no run changed a parameter since the last restore.

        Raises:
            StepFailure: a node refused its own start-up value.
        """
        if not self.changed:
            return []
        restored = []
        for node, kept in self.kept.items():
            client = session.parameters(node)
            session.wait_for(client.services_are_ready, SERVICE_WALL_S, f"parameter services of {node}")
            names = list(kept)
            now = session.wait_future(client.get_parameters(names), SERVICE_WALL_S, f"parameters of {node}").values
            changed = [Parameter.from_parameter_msg(ParameterMsg(name=name, value=kept[name]))
                       for name, value in zip(names, now, strict=True) if value != kept[name]]
            if not changed:
                continue
            results = session.wait_future(client.set_parameters(changed), SERVICE_WALL_S, f"set back {node}").results
            refused = [f"{p.name}: {r.reason}" for p, r in zip(changed, results, strict=True) if not r.successful]
            if refused:
                raise StepFailure(f"{node} refused its start-up values: {'; '.join(refused)}")
            restored += [f"{node} {p.name}" for p in changed]
        self.changed = False
        self.last_restored = restored
        return restored


@dataclass
class Bringup:
    """A running ``bringup`` process, the runs it served and the parameters they changed."""

    key: BringupKey
    process: ChildProcess
    session: RosSession  # the runs' client session: its nodes found once (a new one per run took 1-3.5 s)
    clients: RunClients  # ... and its clients
    runs: int = 0
    trusted: bool = True  # False after a run that ended in an error: not reused
    parameters: ParameterKeeper = field(default_factory=ParameterKeeper)
    _log_offset: int = 0
    _last_folder: pathlib.Path | None = None

    @property
    def scene(self) -> str:
        return self.key[1]

    def prepare(self, session: RosSession, scene: str) -> list[str]:
        """Make a bring-up that served runs look just started in ``scene``: parameters, world, goals, sim time.

        Returns:
            ``node name`` of each parameter set back.

        Raises:
            StepFailure, WaitTimeout: it could not be brought back (the caller starts a fresh one).
        """
        if self.runs == 0 and scene == self.scene:
            return []
        restored = self.parameters.restore(session) or self.parameters.last_restored  # (set back after the last run)
        self.parameters.last_restored = []
        if scene != self.scene:
            self._load_world(session, scene)
        request = ResetSimulation.Request(scope=ResetSimulation.Request.SCOPE_ALL)
        response = session.call(ResetSimulation, "sim/reset_simulation", request, timeout=SERVICE_WALL_S)
        if response.result.result != Result.RESULT_OK:
            raise StepFailure(f"/sim/reset_simulation: {response.result.error_message}")
        return restored

    def _load_world(self, session: RosSession, scene: str) -> None:
        """``/sim/load_world`` ``scene``, then wait until the action servers validate goals on it."""
        request = LoadWorld.Request()
        request.world_resource.uri = scene
        response = session.call(LoadWorld, "sim/load_world", request, timeout=SERVICE_WALL_S)
        if response.result.result != Result.RESULT_OK:
            raise StepFailure(f"/sim/load_world {scene}: {response.result.error_message}")
        robot = self.key[0]
        for node in ("arm", *(("locomotion",) if robot_models.walks(robot) else ())):
            client = session.parameters(f"{session.namespace}/{node}")
            session.wait_for(client.services_are_ready, SERVICE_WALL_S, f"parameter services of /{node}")

            def loaded(client: Any = client) -> bool:
                values = session.wait_future(client.get_parameters(["scene"]), SERVICE_WALL_S, "the scene of a server")
                return bool(values.values) and values.values[0].string_value == scene

            session.wait_for(loaded, SERVICE_WALL_S, f"/{node} to follow /sim into the scene {scene!r}", poll=0.05)
        self.key = (robot, scene, self.key[2])

    def copy_log(self, folder: pathlib.Path) -> pathlib.Path:
        """Write what the nodes logged since the last copy to ``folder/bringup.log`` (the run's share)."""
        target = folder / "bringup.log"
        self._last_folder = folder
        with open(self.process.log_path, "rb") as log, open(target, "ab") as out:
            log.seek(self._log_offset)
            shutil.copyfileobj(log, out)
            self._log_offset = log.tell()
        return target

    def stop(self) -> None:
        """Close the runs' session, then stop the nodes; their last output goes to the log of the last run (and to
        stderr after a crash)."""
        try:
            self.clients.close()
        finally:
            self.session.close()
        code = self.process.stop()
        if self._last_folder is not None:
            self.copy_log(self._last_folder)
        if code not in (0, -signal.SIGINT, 130):
            sys.stderr.write(f"--- {' '.join(self.process.args)} exited with {code}; last output:\n"
                             f"{self.process.output()[-3000:]}\n")


class Bringups:
    """Starts bring-ups for runs and keeps the last one for the next run of the same robot and pace (any scene).

    Use with ``with``: the bring-up still running is stopped at the end. ``started`` counts the bring-ups.

    Args:
        stream: where to say when a bring-up is started, reused or stopped.
        quiet: say nothing.
    """

    def __init__(self, stream: TextIO = sys.stdout, quiet: bool = False) -> None:
        self._stream = stream
        self._quiet = quiet
        self._logs = tempfile.TemporaryDirectory(prefix="bringups-")
        self.current: Bringup | None = None
        self.started = 0

    def __enter__(self) -> Bringups:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _say(self, text: str) -> None:
        if not self._quiet:
            self._stream.write(text + "\n")
            self._stream.flush()

    def acquire(self, scenario: Scenario, rtf: float, namespace: str = "") -> Bringup:
        """The bring-up for a run of ``scenario`` at ``rtf`` under ``namespace``: the running one, reset, or a new one
        (with a client session of its own, which the runs on it share)."""
        key: BringupKey = (scenario.robot, scenario.scene, rtf)
        current = self.current
        same = (current is not None and (current.key[0], current.key[2]) == (scenario.robot, rtf)  # any scene: loaded
                and current.session.namespace == (f"/{namespace.strip('/')}" if namespace.strip("/") else ""))
        if current is not None and same and not current.trusted:
            self._say("the last run on the running bring-up ended in an error: starting a new one")
        elif current is not None and same and not current.process.alive():
            self._say(f"the running bring-up exited (code {current.process.process.returncode}): starting a new one")
        elif current is not None and same:
            try:
                was = current.scene
                restored = current.prepare(current.session, scenario.scene)
                world = f"the {scenario.scene} scene loaded, " if scenario.scene != was else ""
                self._say(f"reusing the bring-up of {scenario.robot}/{was} (run {current.runs + 1} on it): {world}reset, "
                          f"sim time 0{', set back: ' + ', '.join(restored) if restored else ''}")
                return current
            except (StepFailure, WaitTimeout) as error:
                self._say(f"the running bring-up could not be reset ({error}): starting a new one")
        self.stop()
        args = ["bringup", "--robot", scenario.robot, "--scene", scenario.scene, "--rtf", f"{rtf:g}", "--paused",
                "--clock-rate", f"{CLOCK_RATE_HZ:g}", "--joint-state-rate", f"{JOINT_STATE_RATE_HZ:g}"]
        if namespace.strip("/"):
            args += ["--namespace", namespace.strip("/")]
        self.started += 1
        log_dir = pathlib.Path(self._logs.name) / str(self.started)
        self._say(f"starting bring-up {self.started}: {' '.join(args)}")
        # Lock-stepped: its nodes' threads yield to /sim's stepping thread (sim_ros.scheduling).
        process = ChildProcess(args, log_dir, env=lock_step_environment(os.environ))
        session = RosSession("scenario_runner", use_sim_time=True, namespace=namespace)
        self.current = Bringup(key, process, session, RunClients(session))
        return self.current

    def stop(self) -> None:
        """Stop the running bring-up, if any."""
        if self.current is not None:
            bringup, self.current = self.current, None
            bringup.stop()

    def close(self) -> None:
        self.stop()
        self._logs.cleanup()
