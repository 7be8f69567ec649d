"""Reading a robot's sensors from the simulation: IMU, the soles' contact wrenches, wrist force/torque.

Everything is measured from the physics: the IMU and the wrist sensors are MuJoCo sensors
(:mod:`robot_models.sensors`) evaluated when read, the sole wrenches are the sums of the sole
geoms' contact forces. On top of the true values come what real sensors add, all seeded: IMU white
noise and a constant bias; wrist force/torque bias, a slow linear drift (as a real F/T sensor's
temperature drift) and white noise. Readings describe the state of the last physics step (MuJoCo
computes forces and accelerations before it integrates, so they lag the positions by one step).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from robot_models.sensors import SensorLayout
from robot_models.validation import check_range

_SENSOR_BIT = int(mujoco.mjtDisableBit.mjDSBL_SENSOR)


@dataclass(frozen=True)
class ImuNoise:
    """Seeded imperfections of the IMU; all zero = the true values.

    Attributes:
        gyro_noise: white-noise standard deviation of each angular-velocity axis [rad/s].
        accel_noise: white-noise standard deviation of each acceleration axis [m/s^2].
        gyro_bias: standard deviation of the constant bias drawn per axis [rad/s].
        accel_bias: standard deviation of the constant bias drawn per axis [m/s^2].
        seed: seed of the noise and bias draws.
    """

    gyro_noise: float = 0.0
    accel_noise: float = 0.0
    gyro_bias: float = 0.0
    accel_bias: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("gyro_noise", "accel_noise", "gyro_bias", "accel_bias"):
            check_range(f"IMU {name}", getattr(self, name), 0)


@dataclass(frozen=True)
class WristNoise:
    """Seeded imperfections of the wrist force/torque sensors.

    Attributes:
        force_bias, torque_bias: standard deviation of the constant offset drawn per axis [N], [N m].
        force_drift: rate of the slow linear drift of each force axis, in a seeded direction [N/min of sim time].
        force_noise, torque_noise: white-noise standard deviation per axis [N], [N m].
        seed: seed of the draws.
    """

    force_bias: float = 0.0
    torque_bias: float = 0.0
    force_drift: float = 0.0
    force_noise: float = 0.0
    torque_noise: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("force_bias", "torque_bias", "force_drift", "force_noise", "torque_noise"):
            check_range(f"wrist sensor {name}", getattr(self, name), 0)


@dataclass(frozen=True)
class ImuReading:
    """orientation_wxyz (4,) of the IMU frame in the world; angular_velocity (3,) [rad/s] and
    linear_acceleration (3,) [m/s^2] in the IMU frame; the acceleration is the proper one (at rest: +g up)."""

    orientation_wxyz: np.ndarray
    angular_velocity: np.ndarray
    linear_acceleration: np.ndarray


@dataclass(frozen=True)
class Wrench:
    """force (3,) [N] and torque (3,) [N m] in a sensor frame."""

    force: np.ndarray
    torque: np.ndarray


@dataclass(frozen=True)
class HandState:
    """What a wrist sensor's hand is doing: speed of the sensor frame [m/s], [rad/s]; whether it touches anything."""

    linear_speed: float
    angular_speed: float
    in_contact: bool


class SensorSuite:
    """The sensors of one simulation, read on demand.

    Args:
        model: the compiled model (with the layout's sites and sensors).
        layout: which sensors the robot has.
    """

    def __init__(self, model: mujoco.MjModel, layout: SensorLayout) -> None:
        self._model = model
        self.layout = layout
        self._evaluated_at = -math.inf
        self._imu_noise = ImuNoise()
        self._imu_bias = (np.zeros(3), np.zeros(3))
        self._imu_rng = np.random.default_rng(0)
        self._wrist_noise = WristNoise()
        self._wrist_offsets: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self._wrist_rng = np.random.default_rng(0)
        imu = layout.imu
        if imu is not None:
            self._imu_adr = tuple(self._sensor_adr(name) for name in (imu.quat_sensor, imu.gyro_sensor, imu.accel_sensor))
        self._foot_index = {foot.name: k for k, foot in enumerate(layout.feet)}
        self._foot_geom_ids = np.array([model.geom(foot.geom).id for foot in layout.feet], dtype=int)
        self._foot_site_ids = np.array([model.site(foot.frame).id for foot in layout.feet], dtype=int)
        self._wrist_adr = {w.name: (self._sensor_adr(w.force_sensor), self._sensor_adr(w.torque_sensor)) for w in layout.wrists}
        self._wrist_sites = {w.name: model.site(w.frame).id for w in layout.wrists}
        # Per hand, which geoms belong to it (a geom of any body in the hand's subtree): a contact's look-up.
        self._hand_geoms = {w.name: np.isin(model.geom_bodyid, self._subtree(model.body(w.body).id))
                            for w in layout.wrists}
        self.set_imu_noise(self._imu_noise)
        self.set_wrist_noise(self._wrist_noise)

    def _sensor_adr(self, name: str) -> int:
        return int(self._model.sensor(name).adr[0])

    def _subtree(self, root: int) -> np.ndarray:
        model = self._model
        inside = [root]
        for body in range(root + 1, model.nbody):
            if int(model.body_parentid[body]) in inside:
                inside.append(body)
        return np.array(inside)

    # ----- configuration -------------------------------------------------------------------
    @property
    def imu_noise(self) -> ImuNoise:
        return self._imu_noise

    def set_imu_noise(self, noise: ImuNoise) -> None:
        """New noise settings; the bias is drawn again from the seed."""
        self._imu_noise = noise
        self._imu_rng = np.random.default_rng(noise.seed)
        self._imu_bias = (self._imu_rng.normal(0.0, noise.gyro_bias, 3), self._imu_rng.normal(0.0, noise.accel_bias, 3))

    def set_wrist_noise(self, noise: WristNoise) -> None:
        """New settings; each wrist's bias and drift direction are drawn again from the seed."""
        self._wrist_noise = noise
        self._wrist_rng = np.random.default_rng(noise.seed)
        offsets = {}
        for wrist in self.layout.wrists:
            force = self._wrist_rng.normal(0.0, noise.force_bias, 3)
            torque = self._wrist_rng.normal(0.0, noise.torque_bias, 3)
            direction = self._wrist_rng.normal(0.0, 1.0, 3)
            direction /= max(float(np.linalg.norm(direction)), 1e-12)
            offsets[wrist.name] = (force, torque, direction * noise.force_drift / 60.0)
        self._wrist_offsets = offsets

    def invalidate(self) -> None:
        """Forget the last evaluation (the state changed without time moving on: a reset)."""
        self._evaluated_at = -math.inf

    # ----- reading -------------------------------------------------------------------------
    def _evaluate(self, data: mujoco.MjData) -> None:
        """Evaluate MuJoCo's sensors on the state of the last step (once per instant)."""
        if data.time == self._evaluated_at:
            return
        model = self._model
        flags = model.opt.disableflags
        model.opt.disableflags = flags & ~_SENSOR_BIT
        try:
            mujoco.mj_sensorPos(model, data)
            mujoco.mj_sensorVel(model, data)
            mujoco.mj_sensorAcc(model, data)
        finally:
            model.opt.disableflags = flags
        self._evaluated_at = data.time

    def imu(self, data: mujoco.MjData) -> ImuReading:
        """The IMU now, with its noise and bias. Raises ValueError for a robot without an IMU."""
        if self.layout.imu is None:
            raise ValueError("this robot has no IMU")
        self._evaluate(data)
        quat, gyro, accel = self._imu_adr
        values = data.sensordata
        noise = self._imu_noise
        gyro_bias, accel_bias = self._imu_bias
        angular = values[gyro:gyro + 3] + gyro_bias
        linear = values[accel:accel + 3] + accel_bias
        if noise.gyro_noise > 0.0:
            angular = angular + self._imu_rng.normal(0.0, noise.gyro_noise, 3)
        if noise.accel_noise > 0.0:
            linear = linear + self._imu_rng.normal(0.0, noise.accel_noise, 3)
        return ImuReading(values[quat:quat + 4].copy(), np.array(angular), np.array(linear))

    def foot_wrenches(self, data: mujoco.MjData) -> tuple[Wrench, ...]:
        """Every sole's wrench (in the layout's order): what the floor, or anything touching it, exerts on the
        sole, in the sole frame, about its origin. One pass over the contacts for all the feet, in a few
        array operations (a contact between two soles counts for both, with opposite signs)."""
        model = self._model
        ncon = int(data.ncon)
        feet = self._foot_geom_ids
        if not ncon or not len(feet):
            return tuple(Wrench(np.zeros(3), np.zeros(3)) for _ in self._foot_site_ids)
        contact = data.contact
        pairs = contact.geom[:ncon]
        # signs[i, k]: +1 when contact i's geom2 is foot k's sole (MuJoCo's force acts on geom2), -1 for geom1.
        signs = (pairs[:, 1:2] == feet).astype(float) - (pairs[:, 0:1] == feet)
        rows = np.flatnonzero(signs.any(axis=1))
        n = len(rows)
        local = np.empty((n, 2, 3))  # each contact's force and torque in its contact frame (normal, tangents)
        for j, i in enumerate(rows.tolist()):
            mujoco.mj_contactForce(model, data, i, local[j].reshape(6))
        frames = contact.frame[rows].reshape(n, 3, 3)  # rows of each frame: normal (geom1 -> geom2), tangents
        on_geom2 = np.matmul(local, frames)  # (n, 2, 3) in world axes: frame.T @ force, frame.T @ torque
        signs = signs[rows].T  # (feet, n)
        force = signs @ on_geom2[:, 0]  # (feet, 3)
        # About each sole's origin o: sum s (p x f + m) - o x sum s f, with p each contact's position.
        positions = contact.pos[rows]
        origins = data.site_xpos[self._foot_site_ids]
        in_world = np.empty((len(feet), 2, 3))
        in_world[:, 0] = force
        in_world[:, 1] = signs @ (_cross(positions, on_geom2[:, 0]) + on_geom2[:, 1]) - _cross(origins, force)
        rotations = data.site_xmat[self._foot_site_ids].reshape(-1, 3, 3)  # sole frame -> world
        in_sole = np.matmul(in_world, rotations)  # (feet, 2, 3): R.T @ force, R.T @ torque
        return tuple(Wrench(w[0], w[1]) for w in in_sole)

    def foot_wrench(self, data: mujoco.MjData, name: str) -> Wrench:
        """One sole's wrench (see :meth:`foot_wrenches`; reading several feet, call that once instead)."""
        return self.foot_wrenches(data)[self._foot_index[name]]

    def wrist_wrench(self, data: mujoco.MjData, name: str) -> Wrench:
        """A wrist sensor's reading in its frame: the true wrench + bias + drift + noise (not calibrated)."""
        self._evaluate(data)
        force_adr, torque_adr = self._wrist_adr[name]
        values = data.sensordata
        bias_force, bias_torque, drift = self._wrist_offsets[name]
        noise = self._wrist_noise
        force = values[force_adr:force_adr + 3] + bias_force + drift * float(data.time)
        torque = values[torque_adr:torque_adr + 3] + bias_torque
        if noise.force_noise > 0.0:
            force = force + self._wrist_rng.normal(0.0, noise.force_noise, 3)
        if noise.torque_noise > 0.0:
            torque = torque + self._wrist_rng.normal(0.0, noise.torque_noise, 3)
        return Wrench(np.array(force), np.array(torque))

    def hand_state(self, data: mujoco.MjData, name: str) -> HandState:
        """How fast a wrist sensor's hand moves and whether any of its bodies touches something."""
        velocity = np.empty(6)  # world frame: angular, then linear
        mujoco.mj_objectVelocity(self._model, data, mujoco.mjtObj.mjOBJ_SITE, self._wrist_sites[name], velocity, 0)
        angular, linear = velocity[:3], velocity[3:]
        ncon = int(data.ncon)
        touching = bool(ncon) and bool(self._hand_geoms[name][data.contact.geom[:ncon]].any())
        # sqrt(v . v) is what np.linalg.norm computes for a vector, without its overhead.
        return HandState(math.sqrt(float(linear.dot(linear))), math.sqrt(float(angular.dot(angular))), touching)


_NEXT, _PREVIOUS = np.array([1, 2, 0]), np.array([2, 0, 1])


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of two (n, 3) arrays: the products np.cross forms, in four array operations."""
    return a[:, _NEXT] * b[:, _PREVIOUS] - a[:, _PREVIOUS] * b[:, _NEXT]
