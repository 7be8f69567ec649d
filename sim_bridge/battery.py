"""A battery drained by the simulated actuators: integrated where the physics runs, so it is deterministic.

Electrical power = idle draw + sum over actuators of |tau * qdot| / drive efficiency (a motor
draws power for negative work too; no regeneration). :class:`BatteryMeter` integrates it over the sim
time since its last sample, from the actuator forces and velocities of the physics: at every control
step while a controller of its slot runs (walking), and at the end of each stretch of batched physics
steps otherwise (standing, the power is the idle draw plus ~0 work), whatever rate anyone reads it at.
It writes no command, so it never makes the simulation step control step by control step.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from robot_models.sensors import BatteryLayout
from robot_models.validation import check_range
from sim_bridge.controller import Controller

FULL_PERCENT = 100  # [%] (a whole number, so that messages read [0, 100])
SMOOTHING_S = 0.5  # time constant of the reported power [s]


@dataclass(frozen=True)
class BatteryConfig:
    """The battery model's settings (the first four have a ROS parameter with this range on /power).

    Attributes:
        capacity_wh: usable energy of a full battery [Wh], 10..10000.
        idle_power_w: draw of the computers and electronics, always on [W], 0..2000.
        drive_efficiency: mechanical power out per electrical power in of the drives, 0.05..1.
        low_threshold_percent: below this level Walk and NavigateToPose refuse to start and abort, 0..100 [%].
        voltage_full_v, voltage_empty_v: open-circuit voltage at 100 % and 0 % (linear between) [V].
    """

    capacity_wh: float = 432.0  # the G1's 9 Ah pack at 48 V nominal
    idle_power_w: float = 60.0
    drive_efficiency: float = 0.6
    low_threshold_percent: float = 20.0
    voltage_full_v: float = 54.6
    voltage_empty_v: float = 42.0

    @staticmethod
    def of(pack: BatteryLayout) -> BatteryConfig:
        """The defaults of a robot's battery pack."""
        return BatteryConfig(capacity_wh=pack.capacity_wh, idle_power_w=pack.idle_power_w,
                             voltage_full_v=pack.voltage_full_v, voltage_empty_v=pack.voltage_empty_v)

    def __post_init__(self) -> None:
        check_range("battery capacity_wh", self.capacity_wh, 10, 10000, unit="Wh")
        check_range("battery idle_power_w", self.idle_power_w, 0, 2000, unit="W")
        check_range("battery drive_efficiency", self.drive_efficiency, 0.05, 1)
        check_range("battery low_threshold_percent", self.low_threshold_percent, 0, FULL_PERCENT, unit="%")


class Battery:
    """State of charge, drained by :meth:`drain`. Starts full; :meth:`reset` fills it again."""

    def __init__(self, config: BatteryConfig | None = None) -> None:
        self.config = config or BatteryConfig()
        self._energy_j = self._capacity_j
        self.power_w = self.config.idle_power_w  # electrical power, smoothed [W]
        self.consumed_j = 0.0  # since the last reset [J]
        self.mechanical_j = 0.0  # actuators' |tau * qdot| integrated since the last reset [J]

    @property
    def _capacity_j(self) -> float:
        return self.config.capacity_wh * 3600.0

    @property
    def level_percent(self) -> float:
        """State of charge [%], 0..100."""
        return FULL_PERCENT * self._energy_j / self._capacity_j

    @property
    def low(self) -> bool:
        return self.level_percent < self.config.low_threshold_percent

    @property
    def voltage_v(self) -> float:
        c = self.config
        return c.voltage_empty_v + (c.voltage_full_v - c.voltage_empty_v) * self.level_percent / FULL_PERCENT

    @property
    def energy_wh(self) -> float:
        return self._energy_j / 3600.0

    def configure(self, config: BatteryConfig) -> None:
        """New settings; the level [%] is kept."""
        level = self.level_percent
        self.config = config
        self.set_level(level)

    def set_level(self, percent: float) -> None:
        """Set the state of charge [%].

        Raises:
            ValueError: outside 0..100 or not finite.
        """
        check_range("battery level", percent, 0, FULL_PERCENT, unit="%")
        self._energy_j = self._capacity_j * percent / FULL_PERCENT

    def reset(self) -> None:
        """Full again; the counters restart."""
        self._energy_j = self._capacity_j
        self.consumed_j = self.mechanical_j = 0.0
        self.power_w = self.config.idle_power_w

    def drain(self, mechanical_power_w: float, dt: float) -> None:
        """Draw the idle power plus ``mechanical_power_w`` [W] through the drives for ``dt`` [s]."""
        electrical = self.config.idle_power_w + mechanical_power_w / self.config.drive_efficiency
        used = electrical * dt
        self._energy_j = max(0.0, self._energy_j - used)
        self.consumed_j += used
        self.mechanical_j += mechanical_power_w * dt
        self.power_w += (electrical - self.power_w) * min(1.0, dt / SMOOTHING_S)


class BatteryMeter:
    """Drains a battery by the actuators' mechanical power over the sim time since its last sample.

    Power is taken as sum |actuator_force * actuator_velocity| at the sample, held over the time since the
    previous one (the whole span is counted, however the calls split it: the energy is deterministic for a
    given stepping). It commands nothing.
    """

    def __init__(self, battery: Battery) -> None:
        self.battery = battery
        self._sampled_at = 0.0  # sim time of the last sample [s]

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self.battery.reset()
        self._sampled_at = float(data.time)

    def sample(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Drain for the sim time since the last sample at the power of the physics now."""
        now = float(data.time)
        elapsed = now - self._sampled_at
        self._sampled_at = now
        if elapsed > 0.0:
            power = float(np.abs(data.actuator_force * data.actuator_velocity).sum())
            self.battery.drain(power, elapsed)


class Metered:
    """A controller slot's occupant with a battery meter in front (the simulation keeps one controller per slot).

    Active when ``inner`` is: while it runs, the meter is sampled at every control step before it; otherwise
    the simulation steps in batches and samples the meter at the end of each (:meth:`sample`).
    """

    def __init__(self, inner: Controller, meter: BatteryMeter) -> None:
        self.inner = inner
        self.meter = meter

    @property
    def active(self) -> bool:
        return self.inner.active

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self.meter.reset(model, data)
        self.inner.reset(model, data)

    def release(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        release = getattr(self.inner, "release", None)
        if release is not None:
            release(model, data)

    def sample(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Bring the meter up to the current sim time (the simulation calls it after each stretch of stepping)."""
        self.meter.sample(model, data)

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, control_dt: float) -> None:
        self.meter.sample(model, data)
        self.inner.update(model, data, control_dt)
