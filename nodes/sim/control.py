"""What the services of ``/sim`` need from the node that steps the simulation: a narrow, typed interface.

The services (``/sim``'s own and the simulation standard's) change the simulation only through
:class:`SimControl`, under its lock, so each change is atomic with respect to stepping; they never
see the node's stepping loop or its publishers.
"""

from __future__ import annotations

from typing import Protocol

from nodes.sim.handoff import HandOffLock
from sim_bridge import SimError


class SteppingError(SimError):
    """A step failed (the physics diverged, a controller failed); the simulation was reset to its keyframe.

    Args:
        message: why the step failed.
        goals_ended: how many skill goals ended in the steps before the failure.
    """

    def __init__(self, message: str, goals_ended: int) -> None:
        super().__init__(message)
        self.goals_ended = goals_ended


class SimControl(Protocol):
    """Pause, reset and step the simulation of ``/sim``; each call takes the lock itself."""

    @property
    def lock(self) -> HandOffLock:
        """The lock every change of the simulation is made under (the physics thread steps under it)."""
        ...

    @property
    def paused(self) -> bool: ...

    @property
    def physics_running(self) -> bool:
        """Whether the physics thread runs (the node is active); paused or not."""
        ...

    def set_paused(self, paused: bool) -> bool:
        """Pause or resume the physics thread; returns whether it was paused before."""
        ...

    def reset_scene(self, keyframe: str | None = None, keep_time: bool = True) -> None:
        """Restore a keyframe, end the running goals and publish at once; sim time restarts at 0 unless ``keep_time``.

        Raises:
            UnknownNameError: no such keyframe (nothing is changed).
        """
        ...

    def publish_now(self) -> None:
        """Publish every stream at the present sim time (after the state was changed from outside)."""
        ...

    def step_while_paused(self, until_s: float, stop_at_goal_end: bool = False) -> int:
        """Step a paused simulation up to sim time ``until_s`` [s], publishing what falls due; returns goals ended.

        With ``stop_at_goal_end``, it stops at the first publication stop after a skill goal ended.

        Raises:
            SteppingError: a step failed; the simulation was reset to its keyframe.
        """
        ...

    def legs_busy(self) -> bool:
        """Whether a skill goal (Walk, NavigateToPose, ResetPose) drives the legs."""
        ...

    def robot_moved(self) -> None:
        """Under the lock, after the robot's base was moved: the walking controller starts again from there."""
        ...
