"""The one shape every skill has: start -> update in the control step -> progress -> outcome.

A skill is a goal-directed closed loop (walk a distance, navigate to a pose, move an arm, pick and
place) that runs inside the simulation's control step, on the measured state, at the control rate.
It commands the in-loop controllers (the walking controller, the arm controller) and decides by
itself when it succeeded, failed or was safely canceled. Nothing here knows about ROS: progress
and results are plain values named like the fields of the action that carries them.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Protocol

import mujoco

from sim_bridge.state import Pose

# Progress and result values, keyed by the field names of the action's Feedback and Result.
# Floats are in SI units; a Pose is in the skill's ``pose_frame``; ``elapsed`` and other durations
# are seconds of sim time.
Values = Mapping[str, "float | int | str | Pose"]


class SkillStatus(enum.IntEnum):
    """Where a skill's goal stands. The terminal ones are SUCCEEDED, ABORTED and CANCELED."""

    IDLE = 0
    RUNNING = 1
    SUCCEEDED = 2
    ABORTED = 3
    CANCELED = 4

    @property
    def terminal(self) -> bool:
        return self in (SkillStatus.SUCCEEDED, SkillStatus.ABORTED, SkillStatus.CANCELED)


@dataclass(frozen=True)
class SkillOutcome:
    """How a goal ended.

    Attributes:
        status: SUCCEEDED, ABORTED or CANCELED.
        code: the name of the action's result code (``"SUCCESS"``, ``"FELL"``, ``"TIMEOUT"``...);
            the ROS side looks the number up in the action definition.
        message: what happened, for a person.
    """

    status: SkillStatus
    code: str
    message: str

    @staticmethod
    def succeeded(message: str) -> SkillOutcome:
        return SkillOutcome(SkillStatus.SUCCEEDED, "SUCCESS", message)

    @staticmethod
    def aborted(code: str, message: str) -> SkillOutcome:
        return SkillOutcome(SkillStatus.ABORTED, code, message)

    @staticmethod
    def canceled(message: str) -> SkillOutcome:
        return SkillOutcome(SkillStatus.CANCELED, "CANCELED", message)


@dataclass(frozen=True)
class GoalVisuals:
    """What a running goal shows a viewer, in the world frame.

    A skill may have a ``visuals()`` method returning one (see :func:`visuals_of`); it changes only when the
    goal's plan does (a replan, a new stage), so a publisher can compare it with the last one it sent.

    Attributes:
        path_xy: the planned path's points [m], start to goal (empty without a path).
        goal_pose: where the robot is to end, (x [m], y [m], yaw [rad]) (None without one).
        target_xyz: a point the goal acts on, e.g. where an object is to be placed [m] (None without one).
        footsteps: the footsteps the walker plans ahead, (x [m], y [m], yaw [rad]) of each sole, next first.
        keep_out_xy: centres [m] of the map cells the robot's centre must keep out of: the obstacles grown
            by their clearance (robot radius + detection threshold).
        keep_out_cell_m: the side of those cells [m].
    """

    path_xy: tuple[tuple[float, float], ...] = ()
    goal_pose: tuple[float, float, float] | None = None
    target_xyz: tuple[float, float, float] | None = None
    footsteps: tuple[tuple[float, float, float], ...] = ()
    keep_out_xy: tuple[tuple[float, float], ...] = ()
    keep_out_cell_m: float = 0.0


def visuals_of(skill: object) -> GoalVisuals | None:
    """The skill's :class:`GoalVisuals` now, or None for a skill that shows nothing."""
    visuals = getattr(skill, "visuals", None)
    return visuals() if callable(visuals) else None


PREEMPTED = "PREEMPTED"
SIM_FAULT = "SIM_FAULT"
INVALID_GOAL = "INVALID_GOAL"


class Skill(Protocol):
    """A goal-directed loop run in the control step. Built from a validated goal, then driven by a host.

    Attributes:
        name: the skill's name (``"walk"``, ``"navigate_to_pose"``, ``"move_arm"``, ``"pick_place"``).
        resource: what it owns while it runs (``"legs"``, an arm name); one goal per resource.
        pose_frame: the frame of the poses in its progress and result values.

    A skill may also have an integer ``milestone`` (PickPlace: its stage): each change of it is
    reported as feedback whatever the feedback rate, and a tuple ``also_holds`` of the resources it
    moves besides its own (the G1's fetch: both arms): while it runs, goals on those are refused, and
    its start preempts theirs.
    """

    name: str
    resource: str
    pose_frame: str

    def start(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Begin from the current state (called between control steps, with the state current).

        Raises:
            InvalidGoalError: the goal cannot be run from this state (nothing was commanded).
        """
        ...

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> SkillOutcome | None:
        """One control step, before the controllers it commands run. Returns the outcome once it ended."""
        ...

    def request_cancel(self) -> None:
        """Stop safely; :meth:`update` returns CANCELED once the robot is safe."""
        ...

    def stop_now(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Stop commanding at once (preempted by a newer goal, or the simulation was reset)."""
        ...

    def update_settings(self, settings: Mapping[str, float]) -> None:
        """Settings that may change while the goal runs (e.g. ``walking_speed``); unknown names are ignored."""
        ...

    def feedback(self, data: mujoco.MjData) -> Values:
        """Progress measured now, keyed by the action's Feedback fields."""
        ...

    def result(self, data: mujoco.MjData) -> Values:
        """Result values measured now (other than the code and message), keyed by the action's Result fields."""
        ...
