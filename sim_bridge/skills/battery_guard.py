"""A battery guard around a locomotion skill: no walking on a low battery.

Below the battery's low threshold a guarded goal does not start (it ends at once, ABORTED
``BATTERY_LOW``); a goal running when the level falls below it stops safely (the robot closes its
feet and stands, as after a cancel) and then ends ABORTED ``BATTERY_LOW``. The check runs in the
control step, on the battery the control step drains.
"""

from __future__ import annotations

from collections.abc import Mapping

import mujoco

from sim_bridge.battery import Battery
from sim_bridge.skills.base import GoalVisuals, Skill, SkillOutcome, SkillStatus, Values, visuals_of

BATTERY_LOW = "BATTERY_LOW"


class BatteryGuard:
    """Wraps ``inner`` (same name, resource and values); see the module's text.

    Args:
        inner: the guarded skill (Walk, NavigateToPose).
        battery: the battery the control step drains.
    """

    def __init__(self, inner: Skill, battery: Battery) -> None:
        self.inner = inner
        self.name = inner.name
        self.resource = inner.resource
        self.also_holds: tuple[str, ...] = getattr(inner, "also_holds", ())
        self.pose_frame = inner.pose_frame
        self._battery = battery
        self._refused: SkillOutcome | None = None
        self._ran_low: SkillOutcome | None = None
        self._canceled = False

    def _reason(self) -> str:
        battery = self._battery
        return f"battery low: {battery.level_percent:.1f} % is below the threshold of {battery.config.low_threshold_percent:g} %"

    def start(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self.inner.start(model, data)  # raises on a goal that cannot run at all; values are measured from here
        if self._battery.low:
            self.inner.stop_now(model, data)
            self._refused = SkillOutcome.aborted(BATTERY_LOW, f"{self._reason()}: not starting; charge the battery "
                                                              "(or /sim/set_battery_level) and send the goal again")

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> SkillOutcome | None:
        if self._refused is not None:
            return self._refused
        if self._ran_low is None and not self._canceled and self._battery.low:
            self._ran_low = SkillOutcome.aborted(BATTERY_LOW, f"{self._reason()}: the robot stopped and stands")
            self.inner.request_cancel()  # the inner skill's safe stop
        outcome = self.inner.update(model, data, control_dt)
        if outcome is not None and self._ran_low is not None and outcome.status is SkillStatus.CANCELED:
            return self._ran_low
        return outcome

    def request_cancel(self) -> None:
        self._canceled = True
        self.inner.request_cancel()

    def stop_now(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self.inner.stop_now(model, data)

    def update_settings(self, settings: Mapping[str, float]) -> None:
        self.inner.update_settings(settings)

    def feedback(self, data: mujoco.MjData) -> Values:
        return self.inner.feedback(data)

    def result(self, data: mujoco.MjData) -> Values:
        return self.inner.result(data)

    def visuals(self) -> GoalVisuals | None:
        return visuals_of(self.inner)
