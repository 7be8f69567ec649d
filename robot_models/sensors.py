"""Where a robot's sensors sit: the IMU, the soles' contact wrenches, the wrists' force/torque sensors.

Each robot module describes its sensors with a :class:`SensorLayout` (names only) and calls
:func:`add_sensors` on its spec before compiling: that adds one site per sensor frame and the MuJoCo
sensors (``framequat``, ``gyro``, ``accelerometer`` at the IMU site; ``force`` and ``torque`` at each
wrist site). The soles' contact wrenches are summed from the contacts of the sole geoms, so they need
no MuJoCo sensor. Sensors change nothing of the physics.

MuJoCo evaluates its sensors at every physics step unless they are disabled; the model is compiled
with sensors disabled (``mjDSBL_SENSOR``) and the simulation evaluates them only when they are read
(``sim_bridge.sensors``), so an unread sensor costs nothing.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # mujoco is imported where a spec is edited: the layouts are read without it
    import mujoco


Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class ImuLayout:
    """An IMU at a site: orientation, angular velocity and proper acceleration (gravity included).

    Attributes:
        frame: name of the site and of its frame in /tf (a child of ``body``).
        body: the body it is mounted on.
        position_in_body: [m].
    """

    frame: str
    body: str
    position_in_body: Vec3

    @property
    def quat_sensor(self) -> str:
        return f"{self.frame}_quat"

    @property
    def gyro_sensor(self) -> str:
        return f"{self.frame}_gyro"

    @property
    def accel_sensor(self) -> str:
        return f"{self.frame}_accel"


@dataclass(frozen=True)
class FootLayout:
    """A sole whose contact wrench is measured.

    Attributes:
        name: sensor name (the topic is ``/<name>/wrench``), e.g. ``"left_foot"``.
        frame: the sole site, also the wrench's frame in /tf (a child of ``body``).
        body: the foot body.
        geom: the sole geom whose contacts are summed.
    """

    name: str
    frame: str
    body: str
    geom: str


@dataclass(frozen=True)
class WristLayout:
    """A six-axis force/torque sensor between a hand and its arm.

    Attributes:
        name: sensor name (the topic is ``/<name>/wrench``), e.g. ``"right_wrist"``.
        arm: the arm it belongs to (a key of the spec's ``end_effector_sites``).
        frame: the sensor site, also the wrench's frame in /tf (a child of ``body``).
        body: the first body of the hand (MuJoCo measures what this body's subtree exerts on its parent).
        position_in_body: [m].
    """

    name: str
    arm: str
    frame: str
    body: str
    position_in_body: Vec3 = (0.0, 0.0, 0.0)

    @property
    def force_sensor(self) -> str:
        return f"{self.frame}_force"

    @property
    def torque_sensor(self) -> str:
        return f"{self.frame}_torque"


@dataclass(frozen=True)
class BatteryLayout:
    """The robot's battery pack (a robot on mains power has none).

    Attributes:
        capacity_wh: usable energy when full [Wh].
        idle_power_w: always-on draw of its computers and electronics [W].
        voltage_full_v, voltage_empty_v: pack voltage at 100 % and 0 % [V].
    """

    capacity_wh: float
    idle_power_w: float
    voltage_full_v: float
    voltage_empty_v: float


@dataclass(frozen=True)
class SensorLayout:
    """Every sensor of a robot, and its battery (the defaults: none)."""

    imu: ImuLayout | None = None
    feet: tuple[FootLayout, ...] = ()
    wrists: tuple[WristLayout, ...] = ()
    battery: BatteryLayout | None = None

    def frames(self) -> tuple[tuple[str, str], ...]:
        """(parent body, sensor frame) of every sensor frame, for /tf_static."""
        pairs = [(self.imu.body, self.imu.frame)] if self.imu is not None else []
        pairs += [(foot.body, foot.frame) for foot in self.feet]
        pairs += [(wrist.body, wrist.frame) for wrist in self.wrists]
        return tuple(pairs)


def add_sensors(spec: mujoco.MjSpec, layout: SensorLayout) -> None:
    """Add the layout's sites (those that do not exist yet) and MuJoCo sensors to ``spec``; disable sensor evaluation
    in the physics step (they are evaluated when read)."""
    import mujoco

    existing = {site.name for site in spec.sites}

    def site(body: str, name: str, position: Vec3) -> None:
        if name not in existing:
            spec.body(body).add_site(name=name, pos=list(position), size=[0.01] * 3)
            existing.add(name)

    site_type = mujoco.mjtObj.mjOBJ_SITE
    if layout.imu is not None:
        imu = layout.imu
        site(imu.body, imu.frame, imu.position_in_body)
        spec.add_sensor(name=imu.quat_sensor, type=mujoco.mjtSensor.mjSENS_FRAMEQUAT, objtype=site_type, objname=imu.frame)
        spec.add_sensor(name=imu.gyro_sensor, type=mujoco.mjtSensor.mjSENS_GYRO, objtype=site_type, objname=imu.frame)
        spec.add_sensor(name=imu.accel_sensor, type=mujoco.mjtSensor.mjSENS_ACCELEROMETER, objtype=site_type,
                        objname=imu.frame)
    for wrist in layout.wrists:
        site(wrist.body, wrist.frame, wrist.position_in_body)
        spec.add_sensor(name=wrist.force_sensor, type=mujoco.mjtSensor.mjSENS_FORCE, objtype=site_type, objname=wrist.frame)
        spec.add_sensor(name=wrist.torque_sensor, type=mujoco.mjtSensor.mjSENS_TORQUE, objtype=site_type,
                        objname=wrist.frame)
    spec.option.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
