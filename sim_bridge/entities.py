"""The scene's entities as the simulation standard sees them: the robot, the free objects, the static parts.

An entity is something a user can name and query as a whole: the robot (named after its scene,
e.g. ``g1``; its state is its base body's), each free object (``box_0``, ...), each fixture welded
to the world (the Panda's ``table``) and each static obstacle of the scene (``obstacle_wall``, ...).
States are ground truth in the world frame: the pose of the entity's canonical frame (the base
body, the object's body, the fixture's body, the obstacle's geom), the velocity of that frame's
origin and its angular velocity, both expressed in world axes.

Only free bodies (the objects, a floating base) can be moved; a fixed base, the fixtures and the
obstacles (part of the compiled scene, and of the navigation map) cannot. Nothing here knows about ROS.
"""

from __future__ import annotations

import enum
import math
import re
from dataclasses import dataclass

import mujoco
import numpy as np

from sim_bridge.core import Simulation
from sim_bridge.errors import SimError, UnknownNameError
from sim_bridge.state import Pose

QUATERNION_NORM_TOLERANCE = 1e-3  # |q| may differ from 1 by this much; it is normalised
MAX_ABS_POSITION_M = 1000.0  # the world's extent, each axis [m]
MAX_LINEAR_SPEED_MPS = 100.0
MAX_ANGULAR_SPEED_RADPS = 100.0


class EntityKind(enum.Enum):
    ROBOT = "robot"
    OBJECT = "object"
    OBSTACLE = "obstacle"


class EntityStateError(SimError, ValueError):
    """A state that can never be set (a velocity not finite or too large, a bad name filter)."""


class InvalidPoseError(EntityStateError):
    """A pose that can never be set (not finite, not a rotation, out of the world)."""


class FixedEntityError(SimError):
    """The entity is fixed in the scene: its state cannot be set."""


@dataclass(frozen=True)
class Entity:
    """One entity of the scene.

    Attributes:
        name: unique name.
        kind: robot, object or static obstacle.
        description: one line for people.
        tags: labels for filtering.
        movable: whether its state can be set (a free joint).
    """

    name: str
    kind: EntityKind
    description: str
    tags: tuple[str, ...]
    movable: bool


@dataclass(frozen=True)
class EntityState:
    """Ground truth of an entity in the world frame.

    Attributes:
        pose: pose of its canonical frame.
        linear_velocity: of the frame's origin, world axes [m/s], shape (3,).
        angular_velocity: world axes [rad/s], shape (3,).
        linear_acceleration: of the frame's origin over the last physics step, world axes [m/s^2].
        angular_acceleration: over the last physics step, world axes [rad/s^2].
    """

    pose: Pose
    linear_velocity: np.ndarray
    angular_velocity: np.ndarray
    linear_acceleration: np.ndarray
    angular_acceleration: np.ndarray


@dataclass(frozen=True)
class _Handle:
    body_id: int  # -1 for an obstacle (geoms of the world body)
    geom_id: int  # the obstacle's main geom (its pose is the obstacle's), else -1
    qpos_adr: int  # free joint's qpos address, -1 when fixed
    dof_adr: int
    geom_ids: tuple[int, ...] = ()  # every geom of the obstacle (its bounds), its main geom first


class SceneEntities:
    """Names, states and bounding boxes of the entities of one simulation.

    Args:
        sim: the simulation; every call reads or writes its current state (hold its lock).
    """

    def __init__(self, sim: Simulation) -> None:
        self._sim = sim
        robot = sim.robot
        model = sim.model
        entities: list[Entity] = []
        handles: dict[str, _Handle] = {}
        base = model.body(robot.base_body).id
        base_free = _free_joint(model, base)
        entities.append(Entity(
            robot.name, EntityKind.ROBOT,
            f"the {robot.name} robot ({'floating base' if robot.floating_base else 'fixed base'} {robot.base_body})",
            ("robot", robot.name, "floating_base" if robot.floating_base else "fixed_base"),
            movable=base_free is not None))
        handles[robot.name] = _Handle(base, -1, *(base_free or (-1, -1)))
        for name in robot.objects:
            body = model.body(name).id
            free = _free_joint(model, body)
            entities.append(Entity(name, EntityKind.OBJECT, f"free object {name}", ("object", "graspable"),
                                   movable=free is not None))
            handles[name] = _Handle(body, -1, *(free or (-1, -1)))
        camera_frames = {camera.optical_frame for camera in robot.cameras}
        for body in range(1, model.nbody):  # fixtures: bodies welded to the world, e.g. the Panda's table
            name = model.body(body).name
            if int(model.body_parentid[body]) != 0 or int(model.body_jntnum[body]) or not name or name in handles:
                continue
            if body == base or name in robot.objects or name in camera_frames:  # a camera's frame is no fixture
                continue
            entities.append(Entity(name, EntityKind.OBSTACLE, f"fixture {name}, welded to the world", ("fixture", "static"),
                                   movable=False))
            handles[name] = _Handle(body, -1, -1, -1)
        for obstacle in robot.obstacles:
            geoms = tuple(model.geom(name).id for name in obstacle.geom_names)
            entities.append(Entity(obstacle.name, EntityKind.OBSTACLE,
                                   f"static obstacle {obstacle.name} ({obstacle.height:.2f} m high, on the navigation map)",
                                   ("obstacle", "static"), movable=False))
            handles[obstacle.name] = _Handle(-1, geoms[0], -1, -1, geoms)
        self.entities: tuple[Entity, ...] = tuple(entities)
        self._by_name = {entity.name: entity for entity in entities}
        self._handles = handles

    # ----- names -------------------------------------------------------------------------
    @property
    def names(self) -> tuple[str, ...]:
        return tuple(entity.name for entity in self.entities)

    def get(self, name: str) -> Entity:
        """The entity of that name.

        Raises:
            UnknownNameError: no such entity; the message lists the entities.
        """
        entity = self._by_name.get(name)
        if entity is None:
            shown = name if len(name) <= 80 else name[:77] + "..."
            raise UnknownNameError(f"unknown entity {shown!r}; entities: {', '.join(self.names)}")
        return entity

    def matching(self, pattern: str) -> list[Entity]:
        """Entities whose name contains a match of a regular expression (``""`` matches all).

        Raises:
            EntityStateError: the pattern is not a valid regular expression.
        """
        if not pattern:
            return list(self.entities)
        try:
            compiled = re.compile(pattern)
        except re.error as error:
            raise EntityStateError(f"name filter {pattern!r} is not a valid regular expression: {error}") from None
        return [entity for entity in self.entities if compiled.search(entity.name)]

    # ----- state -------------------------------------------------------------------------
    def state(self, name: str) -> EntityState:
        """Ground-truth state of an entity (see the module's frame convention).

        Raises:
            UnknownNameError: no such entity.
        """
        self.get(name)
        handle = self._handles[name]
        data = self._sim.data
        zero = np.zeros(3)
        if handle.geom_id >= 0:
            quat = np.empty(4)
            mujoco.mju_mat2Quat(quat, data.geom_xmat[handle.geom_id])
            return EntityState(Pose(data.geom_xpos[handle.geom_id].copy(), quat), zero, zero.copy(), zero.copy(), zero.copy())
        body = handle.body_id
        if handle.qpos_adr < 0:  # welded: xpos is exact (it does not move)
            return EntityState(Pose(data.xpos[body].copy(), data.xquat[body].copy()), zero, zero.copy(), zero.copy(),
                               zero.copy())
        # A free joint, read from qpos (xpos lags one physics step behind after mj_step): translational
        # dofs in world axes, rotational dofs in the body's axes.
        q = data.qpos[handle.qpos_adr : handle.qpos_adr + 7]
        pose = Pose(q[:3].copy(), q[3:] / np.linalg.norm(q[3:]))
        flat = np.empty(9)
        mujoco.mju_quat2Mat(flat, pose.orientation_wxyz)
        rotation = flat.reshape(3, 3)
        v = data.qvel[handle.dof_adr : handle.dof_adr + 6]
        a = data.qacc[handle.dof_adr : handle.dof_adr + 6]
        return EntityState(pose, v[:3].copy(), rotation @ v[3:], a[:3].copy(), rotation @ a[3:])

    def set_state(self, name: str, pose: Pose | None = None,
                  linear_velocity: np.ndarray | None = None, angular_velocity: np.ndarray | None = None) -> None:
        """Move an entity at once: its pose and/or its velocity (world frame, world axes).

        Velocities not given are kept when only the pose changes; give both to set a twist. Every
        value is checked before anything is written, so a refused call changes nothing.

        Raises:
            UnknownNameError: no such entity.
            FixedEntityError: the entity cannot be moved (a fixed base, a static obstacle).
            InvalidPoseError: the pose is not finite, its quaternion is not a rotation, or its
                position is outside the world.
            EntityStateError: a velocity is not finite or too large.
        """
        entity = self.get(name)
        handle = self._handles[name]
        if not entity.movable:
            what = "fixed to the world" if entity.kind is EntityKind.ROBOT \
                else "a static part of the compiled scene (obstacles are also on the navigation map)"
            movable = [e.name for e in self.entities if e.movable]
            raise FixedEntityError(f"{name} is {what} and cannot be moved; movable entities: {', '.join(movable) or 'none'}")
        position = quaternion = None
        if pose is not None:
            position, quaternion = _checked_pose(pose)
        linear = _checked_vector(linear_velocity, MAX_LINEAR_SPEED_MPS, "linear velocity", "m/s")
        angular = _checked_vector(angular_velocity, MAX_ANGULAR_SPEED_RADPS, "angular velocity", "rad/s")
        data = self._sim.data
        if position is not None and quaternion is not None:
            data.qpos[handle.qpos_adr : handle.qpos_adr + 3] = position
            data.qpos[handle.qpos_adr + 3 : handle.qpos_adr + 7] = quaternion
        if linear is not None:
            data.qvel[handle.dof_adr : handle.dof_adr + 3] = linear
        if angular is not None:
            body_rotation = np.empty(9)
            orientation = data.qpos[handle.qpos_adr + 3 : handle.qpos_adr + 7]
            mujoco.mju_quat2Mat(body_rotation, orientation)
            data.qvel[handle.dof_adr + 3 : handle.dof_adr + 6] = body_rotation.reshape(3, 3).T @ angular
        mujoco.mj_forward(self._sim.model, data)

    # ----- volumes -----------------------------------------------------------------------
    def world_box(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper corners [m] of the entity's world-axis-aligned bounding box, shape (3,) each."""
        self.get(name)
        return self._box(self._geoms(name), np.zeros(3), np.eye(3))

    def local_box(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper corners [m] of the entity's bounding box in its canonical frame's axes."""
        state = self.state(name)
        rotation = np.empty(9)
        mujoco.mju_quat2Mat(rotation, state.pose.orientation_wxyz)
        return self._box(self._geoms(name), state.pose.position, rotation.reshape(3, 3))

    def _geoms(self, name: str) -> list[int]:
        handle = self._handles[name]
        model = self._sim.model
        if handle.geom_id >= 0:
            return list(handle.geom_ids)
        root = int(model.body_rootid[handle.body_id])
        if self.get(name).kind is EntityKind.ROBOT:
            bodies = {b for b in range(1, model.nbody) if int(model.body_rootid[b]) == root}
        else:
            bodies = {b for b in range(1, model.nbody) if descends(model, b, handle.body_id)}
        geoms = [g for g in range(model.ngeom) if int(model.geom_bodyid[g]) in bodies]
        colliding = [g for g in geoms if model.geom_contype[g] or model.geom_conaffinity[g]]
        return colliding or geoms

    def _box(self, geoms: list[int], origin: np.ndarray, rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Bounding box of geoms in the frame at ``origin`` with axes ``rotation`` (world)."""
        model, data = self._sim.model, self._sim.data
        lower = np.full(3, math.inf)
        upper = np.full(3, -math.inf)
        for g in geoms:
            aabb = model.geom_aabb[g]  # centre then half sizes, in the geom's frame
            geom_rotation = rotation.T @ data.geom_xmat[g].reshape(3, 3)
            centre = rotation.T @ (data.geom_xpos[g] + data.geom_xmat[g].reshape(3, 3) @ aabb[:3] - origin)
            half = np.abs(geom_rotation) @ aabb[3:]
            lower = np.minimum(lower, centre - half)
            upper = np.maximum(upper, centre + half)
        return lower, upper


def box_overlaps_sphere(lower: np.ndarray, upper: np.ndarray, centre: np.ndarray, radius: float) -> bool:
    """Whether a box [lower, upper] and a sphere overlap (touching counts)."""
    nearest = np.clip(centre, lower, upper)
    return bool(np.linalg.norm(nearest - centre) <= radius)


def boxes_overlap(lower_a: np.ndarray, upper_a: np.ndarray, lower_b: np.ndarray, upper_b: np.ndarray) -> bool:
    """Whether two axis-aligned boxes overlap (touching counts)."""
    return bool(np.all(lower_a <= upper_b) and np.all(lower_b <= upper_a))


def _free_joint(model: mujoco.MjModel, body: int) -> tuple[int, int] | None:
    """(qpos address, dof address) of the body's free joint, or None when it has none."""
    if int(model.body_jntnum[body]) < 1:
        return None
    joint = int(model.body_jntadr[body])
    if int(model.jnt_type[joint]) != int(mujoco.mjtJoint.mjJNT_FREE):
        return None
    return int(model.jnt_qposadr[joint]), int(model.jnt_dofadr[joint])


def descends(model: mujoco.MjModel, body: int, ancestor: int) -> bool:
    """Whether ``body`` is ``ancestor`` or below it in the model's tree."""
    while body > 0:
        if body == ancestor:
            return True
        body = int(model.body_parentid[body])
    return False


def _checked_pose(pose: Pose) -> tuple[np.ndarray, np.ndarray]:
    position = np.asarray(pose.position, dtype=float).reshape(3)
    quaternion = np.asarray(pose.orientation_wxyz, dtype=float).reshape(4)
    if not (np.all(np.isfinite(position)) and np.all(np.isfinite(quaternion))):
        raise InvalidPoseError("pose must be finite numbers")
    norm = float(np.linalg.norm(quaternion))
    if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
        raise InvalidPoseError(f"orientation must be a unit quaternion (|q| = 1 within {QUATERNION_NORM_TOLERANCE:g}), "
                               f"got |q| = {norm:.4g}")
    if np.any(np.abs(position) > MAX_ABS_POSITION_M):
        raise InvalidPoseError(f"position {position.tolist()} is outside the world: each coordinate within "
                               f"+-{MAX_ABS_POSITION_M:g} m")
    return position, quaternion / norm


def _checked_vector(value: np.ndarray | None, limit: float, what: str, unit: str) -> np.ndarray | None:
    if value is None:
        return None
    vector = np.asarray(value, dtype=float).reshape(3)
    if not np.all(np.isfinite(vector)):
        raise EntityStateError(f"{what} must be finite numbers")
    if float(np.linalg.norm(vector)) > limit:
        raise EntityStateError(f"{what} {np.linalg.norm(vector):.1f} {unit} is too large; allowed: up to {limit:g} {unit}")
    return vector
