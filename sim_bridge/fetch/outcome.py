"""How a fetch ends: the outcomes judged from the measured state (placement, a drop, a walk's failure), and
what it draws."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from sim_bridge.fetch.goal import FetchPlan
from sim_bridge.skills.base import GoalVisuals, Skill, SkillOutcome, visuals_of

PASSED_ON = ("FELL", "TIMEOUT", "BATTERY_LOW")  # a walk's failures the fetch ends with as they are


def walk_failure(outcome: SkillOutcome, phase: str) -> SkillOutcome:
    """A walk of the fetch failed: FELL, TIMEOUT and BATTERY_LOW are passed on; a walk that finds no way (no path,
    its goal inside an obstacle) leaves the object UNREACHABLE."""
    code = outcome.code if outcome.code in PASSED_ON else "UNREACHABLE"
    return SkillOutcome.aborted(code, f"{phase}: {outcome.message}")


def dropped(name: str, stage: str, position: np.ndarray) -> SkillOutcome:
    """OBJECT_DROPPED, saying where the object lies (world [m])."""
    x, y, z = (float(v) for v in position)
    return SkillOutcome.aborted("OBJECT_DROPPED", f"{name!r} slipped out of the palms in stage {stage}; it lies at "
                                f"({x:.2f}, {y:.2f}, {z:.2f}) m")


def placement(error_m: float, tilt_rad: float, tolerance_m: float, max_tilt_rad: float) -> SkillOutcome:
    """SUCCEEDED when the object rests within ``tolerance_m`` of the place and level within ``max_tilt_rad``."""
    text = f"placed {error_m * 1e3:.1f} mm from the place"
    if error_m <= tolerance_m and tilt_rad <= max_tilt_rad:
        return SkillOutcome.succeeded(f"{text}, tilted {math.degrees(tilt_rad):.1f} deg")
    return SkillOutcome.aborted("PLACEMENT_FAILED", f"{text} (tolerance {tolerance_m * 1e3:.0f} mm), tilted "
                                f"{math.degrees(tilt_rad):.1f} deg")


class Lasting:
    """Whether a condition has held for ``duration_s`` [s of sim time] without a break."""

    def __init__(self, duration_s: float) -> None:
        self.duration_s = duration_s
        self._since: float | None = None

    def update(self, now: float, holds: bool) -> bool:
        """Note the condition at ``now`` [s]; True once it has held since at least ``duration_s`` ago."""
        if not holds:
            self._since = None
            return False
        self._since = now if self._since is None else self._since
        return now - self._since >= self.duration_s

    def clear(self) -> None:
        self._since = None


def fetch_visuals(plan: FetchPlan | None, walk: Skill | None) -> GoalVisuals:
    """A fetch's drawing: its place (world frame), and while it walks the walk's own path, goal pose and footsteps."""
    inner = visuals_of(walk) if walk is not None else None
    target = None
    if plan is not None:
        x, y, z = (float(v) for v in plan.place_center)
        target = (x, y, z)
    if inner is None:
        return GoalVisuals(target_xyz=target)
    return replace(inner, target_xyz=target)
