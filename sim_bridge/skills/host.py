"""Runs skills inside the control step, in front of the controllers they command.

A :class:`SkillHost` takes the place of a controller in its simulation slot (as ros2_control chains
a controller in front of another): each control step it updates the running skills (which set the
inner controller's command), then the inner controller. It keeps one run per resource: starting a
goal on a busy resource preempts the goal running there. A reset of the simulation ends every
running goal (ABORTED, ``SIM_FAULT``) and counts an epoch, so whoever relays a goal knows of the
reset from the goal's own state instead of guessing it from the robot's motion.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field

import mujoco

from sim_bridge.controller import Controller
from sim_bridge.errors import InvalidGoalError, UnknownNameError
from sim_bridge.skills.base import INVALID_GOAL, PREEMPTED, SIM_FAULT, Skill, SkillOutcome, SkillStatus, Values


@dataclass
class SkillRun:
    """One goal on one resource, from its start to its outcome.

    Attributes:
        seq: the sender's goal number (echoed to it).
        skill: the skill (None when the goal was refused before it could be built).
        skill_name: the skill's name.
        resource: the resource it owns.
        epoch: the host's reset count when it started.
        started_at: sim time of its start [s].
        status: RUNNING until it ends.
        outcome: how it ended (None while running).
        ended_at: sim time of its end [s].
        final_feedback, final_result: progress and result values frozen at its end.
        cancel_requested: a cancel was asked for (it ends CANCELED once the robot is safe).
    """

    seq: int
    skill: Skill | None
    skill_name: str
    resource: str
    epoch: int
    started_at: float
    status: SkillStatus = SkillStatus.RUNNING
    outcome: SkillOutcome | None = None
    ended_at: float = 0.0
    final_feedback: Values = field(default_factory=dict)
    final_result: Values = field(default_factory=dict)
    cancel_requested: bool = False


def refused_run(seq: int, skill_name: str, resource: str, epoch: int, reason: str, now: float) -> SkillRun:
    """A goal that never started: ABORTED ``INVALID_GOAL`` with the reason, at sim time ``now`` [s]."""
    return SkillRun(seq, None, skill_name, resource, epoch, now, status=SkillStatus.ABORTED,
                    outcome=SkillOutcome.aborted(INVALID_GOAL, reason), ended_at=now)


class SkillHost:
    """A controller wrapper that runs goal skills before ``inner`` in the same control step.

    Args:
        inner: the controller the skills command (the walking controller, the arm controller).
    """

    def __init__(self, inner: Controller) -> None:
        self.inner = inner
        self.epoch = 0
        self._runs: dict[str, SkillRun] = {}
        self._running: list[SkillRun] = []
        self._changed: list[SkillRun] = []

    # ----- Controller ----------------------------------------------------------------------
    @property
    def active(self) -> bool:
        return bool(self._running) or self.inner.active

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """After the simulation was reset: end every running goal with SIM_FAULT, count the epoch."""
        for run in list(self._running):
            assert run.skill is not None
            run.skill.stop_now(model, data)
            self._end(run, SkillOutcome.aborted(SIM_FAULT, "the simulation was reset during the goal"), data)
        self.epoch += 1
        self.inner.reset(model, data)

    def release(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        release = getattr(self.inner, "release", None)
        if release is not None:
            release(model, data)

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> None:
        if self._running:
            for run in list(self._running):
                assert run.skill is not None
                outcome = run.skill.update(model, data, control_dt)
                if outcome is not None:
                    self._end(run, outcome, data)
        if self.inner.active:
            self.inner.update(model, data, control_dt)

    # ----- goals -----------------------------------------------------------------------------
    def start(self, seq: int, skill: Skill, model: mujoco.MjModel, data: mujoco.MjData) -> SkillRun:
        """Start ``skill`` as goal ``seq`` on its resource, preempting the goal running there.

        A skill that refuses to start (``InvalidGoalError``, ``UnknownNameError``: the goal cannot be run from this state)
        ends at once, ABORTED ``INVALID_GOAL`` with the reason; a goal it preempted has ended too.
        """
        now = float(data.time)
        self.preempt(skill.resource, model, data)
        try:
            skill.start(model, data)
        except (InvalidGoalError, UnknownNameError) as error:
            return self.refuse(seq, skill.name, skill.resource, str(error), now)
        run = SkillRun(seq, skill, skill.name, skill.resource, self.epoch, now)
        self._runs[skill.resource] = run
        self._running.append(run)
        self._changed.append(run)
        return run

    def preempt(self, resource: str, model: mujoco.MjModel, data: mujoco.MjData,
                reason: str = "preempted by a newer goal") -> None:
        """End the goal running on ``resource`` at once (ABORTED ``PREEMPTED``), if there is one."""
        previous = self.running(resource)
        if previous is not None:
            assert previous.skill is not None
            previous.skill.stop_now(model, data)
            self._end(previous, SkillOutcome.aborted(PREEMPTED, reason), data)

    def refuse(self, seq: int, skill_name: str, resource: str, reason: str, now: float) -> SkillRun:
        """Record a goal that could not start (ABORTED ``INVALID_GOAL``); the resource's running goal is untouched."""
        run = refused_run(seq, skill_name, resource, self.epoch, reason, now)
        if self.running(resource) is None:
            self._runs[resource] = run
        self._changed.append(run)
        return run

    def cancel(self, resource: str, seq: int) -> bool:
        """Ask goal ``seq`` to stop safely. False if it is not the running goal of ``resource``."""
        run = self._runs.get(resource)
        if run is None or run.seq != seq or run.status is not SkillStatus.RUNNING:
            return False
        assert run.skill is not None
        run.cancel_requested = True
        run.skill.request_cancel()
        self._changed.append(run)
        return True

    def update_settings(self, resource: str, seq: int, settings: Mapping[str, float]) -> bool:
        """New settings for goal ``seq`` (e.g. a changed ``walking_speed``). False if it is not running."""
        run = self._runs.get(resource)
        if run is None or run.seq != seq or run.status is not SkillStatus.RUNNING:
            return False
        assert run.skill is not None
        run.skill.update_settings(settings)
        return True

    def running(self, resource: str) -> SkillRun | None:
        run = self._runs.get(resource)
        return run if run is not None and run.status is SkillStatus.RUNNING else None

    def runs(self) -> Iterator[SkillRun]:
        """The latest goal of each resource (running or ended)."""
        return iter(self._runs.values())

    def take_changed(self) -> list[SkillRun]:
        """The goals that started, ended or were asked to cancel since the last call (publish them now)."""
        changed, self._changed = self._changed, []
        return changed

    def _end(self, run: SkillRun, outcome: SkillOutcome, data: mujoco.MjData) -> None:
        assert run.skill is not None
        run.final_feedback = dict(run.skill.feedback(data))
        run.final_result = dict(run.skill.result(data))
        run.status = outcome.status
        run.outcome = outcome
        run.ended_at = float(data.time)
        self._running.remove(run)
        self._changed.append(run)
