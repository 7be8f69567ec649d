"""Typed description of a robot scene: the compiled model plus the names that matter."""

from __future__ import annotations

import math
import pathlib
import sys
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from robot_models.biped import BipedDescription
from robot_models.cameras import CameraLayout
from robot_models.hands import HandLayout
from robot_models.sensors import SensorLayout
from robot_models.validation import check_range

if TYPE_CHECKING:  # mujoco is imported where a spec is edited: the types and errors are read without it
    import mujoco


class RobotModelError(Exception):
    """Base error of the robot model layer."""


class UnknownRobotError(RobotModelError, KeyError):
    """Raised by :func:`robot_models.load` for a name that is not registered."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


@dataclass(frozen=True)
class JointLimits:
    """Position limits [rad or m] and effort limits [N m or N] of one joint."""

    lower: float
    upper: float
    effort: float


@dataclass(frozen=True)
class Obstacle:
    """A static part of the scene standing on the floor, whose box footprint is on the navigation map.

    Attributes:
        name: name of its main geom in the model (its pose is the obstacle's).
        center_xy: centre of its footprint in the world frame [m].
        half_size_xy: half lengths of its footprint along its own axes [m].
        height: [m].
        yaw: rotation about world z [rad].
        geoms: every geom it is made of when more than the one named ``name`` (e.g. a table's top
            and legs); empty = just that one.
    """

    name: str
    center_xy: tuple[float, float]
    half_size_xy: tuple[float, float]
    height: float
    yaw: float = 0.0
    geoms: tuple[str, ...] = ()

    @property
    def geom_names(self) -> tuple[str, ...]:
        """The geoms it is made of, its main geom first."""
        return self.geoms or (self.name,)

    def __post_init__(self) -> None:
        if self.geoms and self.geoms[0] != self.name:
            raise ValueError(f"obstacle {self.name!r}: its geoms must start with its main geom, got {self.geoms}")


class UnknownSceneError(RobotModelError, KeyError):
    """Raised by :func:`robot_models.load` for a scene the robot does not have."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


@dataclass(frozen=True)
class ArmScene:
    """What the arms of a robot scene carry and must keep away from (IK, grippers, pick-and-place).

    The defaults describe arms without grippers and with nothing to avoid.

    Attributes:
        grippers: arm name -> finger joint names (each actuated by a position servo).
        gripper_open_width: widest gripper opening [m] (sum of both finger travels).
        obstacle_geoms: geoms the arm links must keep away from.
        obstacle_bodies: bodies whose geoms the arm links must keep away from.
        collision_from_joint: index in the arm's joint list of the first joint whose body
            subtree is checked against the obstacles (links near the shoulder are skipped).
        make_visuals_collide: the obstacle and arm geoms are visual-only in the physics model;
            enable them in the IK model so mink's collision limit uses them.
        objects_table_top_z: height of the surface objects rest on, world z [m] (None when no table).
        object_half_size: half edge of the graspable boxes [m].
        table_xy_bounds: (x_min, x_max, y_min, y_max) of the table top in the world frame [m]
            (None when no table).
    """

    grippers: dict[str, tuple[str, ...]] = field(default_factory=dict)
    gripper_open_width: float = 0.0
    obstacle_geoms: tuple[str, ...] = ()
    obstacle_bodies: tuple[str, ...] = ()
    collision_from_joint: int = 3
    make_visuals_collide: bool = False
    objects_table_top_z: float | None = None
    object_half_size: float = 0.0
    table_xy_bounds: tuple[float, float, float, float] | None = None


@dataclass(frozen=True)
class WalkingLimits:
    """Defaults and limits of the walking skills (Walk, NavigateToPose, fall detection) of a legged robot.

    Attributes:
        speed_range_mps: (lowest, highest) walking speed a goal or the ``walking_speed`` parameter
            may ask for [m/s].
        default_speed_mps: walking speed used when nobody asks for one [m/s].
        max_walk_distance_m: largest absolute distance of one Walk goal [m].
        fall_height_m: height of the base body's origin above the floor (world z) below which the
            robot counts as fallen [m].
        fall_tilt_rad: tilt of the base body's z axis from the world's vertical beyond which the
            robot counts as fallen [rad].
    """

    speed_range_mps: tuple[float, float]
    default_speed_mps: float
    max_walk_distance_m: float
    fall_height_m: float
    fall_tilt_rad: float

    def __post_init__(self) -> None:
        low, high = self.speed_range_mps
        if not 0.0 < low <= self.default_speed_mps <= high:
            raise ValueError(f"walking speeds must satisfy 0 < low <= default <= high, got {low}, "
                             f"{self.default_speed_mps}, {high} m/s")
        check_range("max_walk_distance_m", self.max_walk_distance_m, 0, low_open=True, unit="m")
        check_range("fall_height_m", self.fall_height_m, 0, low_open=True, unit="m")
        check_range("fall_tilt_rad", self.fall_tilt_rad, 0, math.pi, low_open=True, high_open=True, unit="rad")


@dataclass(frozen=True)
class GraspLimits:
    """Defaults and limits of grasping with the robot's grippers (PickPlace, gripper commands).

    Attributes:
        max_force_n: largest squeeze force per finger [N]; the finger actuators' force limit.
        default_force_n: squeeze force per finger used when nobody asks for one [N].
    """

    max_force_n: float
    default_force_n: float

    def __post_init__(self) -> None:
        if not 0.0 < self.default_force_n <= self.max_force_n:
            raise ValueError(f"grasp forces must satisfy 0 < default <= max, got {self.default_force_n}, "
                             f"{self.max_force_n} N")


@dataclass(frozen=True)
class RobotSpec:
    """A robot scene ready to simulate.

    Attributes:
        name: registry name (``"g1"``, ``"panda"``).
        mjspec: the editable MuJoCo spec the model was compiled from, itself never compiled: copy it
            to edit or compile it (:func:`compile_copy`). A compiled spec keeps its meshes' processed
            data (~185 MB for the G1), which a process holding the spec would carry for its whole life.
        model: the compiled model (physics timestep in ``model.opt.timestep`` [s]).
        joint_groups: named groups of actuated joint names, e.g. ``"left_leg"``.
        actuated_joints: every actuated joint, in actuator order.
        end_effector_sites: arm name -> site name of its tool point.
        default_end_effector: arm name used when a goal leaves it empty.
        feet_sites: sole sites (empty for a fixed-base arm).
        base_body: the floating base body, or the fixed root link.
        floating_base: whether ``base_body`` has a free joint.
        keyframes: names of the keyframes in the model.
        default_keyframe: keyframe used at start-up and by reset.
        joint_limits: joint name -> limits.
        control_decimation: physics steps per control step (control period = decimation * timestep).
        objects: names of free bodies a user may manipulate (boxes).
        scene: name of the scene variant (e.g. ``"open"`` or ``"course"`` for the G1).
        obstacles: static obstacles of the scene (for path planning).
        arm_scene: what the arms carry (grippers) and must keep away from; the core's arm
            controllers read it instead of branching on the robot's name.
        walking: defaults and limits of the walking skills (None for a robot that does not walk).
        grasp: defaults and limits of grasping (None for a robot without grippers).
        sensors: the IMU, sole and wrist sensors (names, frames); none by default.
        cameras: the scene's cameras (names, optical frames, field of view, tilt mounts); none by default.
        biped: what the walking controller needs to know of a biped (None for a robot that does not walk).
        palms: arm -> site at the centre of its palm's contact face, z axis along the face's outward
            normal (into what the hand holds); arms that can squeeze an object between them. Empty
            when the robot's hands cannot.
        palm_hand_pose: joint -> position [rad] the hands hold while their palms squeeze (fingers out
            of the palm faces' way); empty: the hands need none.
        hands: arm -> its hand, for grasps of a small object with the fingers; empty: none grasps.
        visuals: whether ``model`` has the visual-only geoms and their meshes (rendering, the URDF's
            meshes, arms whose IK avoids visual meshes: ``ArmScene.make_visuals_collide``). Without
            them it is a light model for processes that validate goals and resolve frames: the same
            bodies, joints, masses, sites and keyframes.
    """

    name: str
    mjspec: mujoco.MjSpec
    model: mujoco.MjModel
    joint_groups: dict[str, tuple[str, ...]]
    actuated_joints: tuple[str, ...]
    end_effector_sites: dict[str, str]
    default_end_effector: str
    feet_sites: tuple[str, ...]
    base_body: str
    floating_base: bool
    keyframes: tuple[str, ...]
    default_keyframe: str
    joint_limits: dict[str, JointLimits]
    control_decimation: int
    objects: tuple[str, ...] = field(default=())
    scene: str = "default"
    obstacles: tuple[Obstacle, ...] = field(default=())
    arm_scene: ArmScene = field(default_factory=ArmScene)
    walking: WalkingLimits | None = None
    grasp: GraspLimits | None = None
    sensors: SensorLayout = field(default_factory=SensorLayout)
    cameras: tuple[CameraLayout, ...] = ()
    biped: BipedDescription | None = None
    palms: dict[str, str] = field(default_factory=dict)
    palm_hand_pose: dict[str, float] = field(default_factory=dict)
    hands: dict[str, HandLayout] = field(default_factory=dict)
    visuals: bool = True

    def __post_init__(self) -> None:
        if self.arm_scene.grippers and self.grasp is None:
            raise ValueError(f"robot {self.name!r} has grippers ({', '.join(self.arm_scene.grippers)}) but no grasp limits")
        if self.walking is not None and not self.floating_base:
            raise ValueError(f"robot {self.name!r} has walking limits but no floating base")
        for camera in self.cameras:
            if camera.tilt_joint is not None and camera.tilt_joint not in self.actuated_joints:
                raise ValueError(f"robot {self.name!r}: the tilt joint {camera.tilt_joint!r} of camera {camera.name!r} "
                                 "is not an actuated joint")
        if not set(self.palm_hand_pose) <= set(self.actuated_joints):
            raise ValueError(f"robot {self.name!r}: the palm hand pose moves joints that are not actuated: "
                             f"{sorted(set(self.palm_hand_pose) - set(self.actuated_joints))}")
        if not set(self.hands) <= set(self.end_effector_sites):
            raise ValueError(f"robot {self.name!r}: hands of arms without an end-effector site: "
                             f"{sorted(set(self.hands) - set(self.end_effector_sites))}")

    @property
    def physics_timestep(self) -> float:
        """Physics step [s]."""
        return float(self.model.opt.timestep)

    @property
    def control_timestep(self) -> float:
        """Control step [s], a whole multiple of the physics step."""
        return self.physics_timestep * self.control_decimation


def example_robot_data_root() -> pathlib.Path:
    """Folder holding example-robot-data's ``robots/`` tree (installed by the cmeel wheel)."""
    for site in map(pathlib.Path, sys.path):
        candidate = site / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
        if candidate.is_dir():
            return candidate
    raise RobotModelError(
        "example-robot-data is not installed: no cmeel.prefix/share/example-robot-data/robots on sys.path"
    )


def read_urdf(relative_path: str, keep_visuals: bool) -> str:
    """Read a URDF from example-robot-data with its mesh paths made absolute.

    Args:
        relative_path: path below ``robots/``.
        keep_visuals: keep visual-only geoms (MuJoCo's URDF importer drops them by default).
    """
    root = example_robot_data_root()
    text = (root / relative_path).read_text()
    text = text.replace("package://example-robot-data/robots/", f"{root}/")
    text = text.replace("package://", f"{root}/")
    if keep_visuals:
        text = text.replace("</robot>", '<mujoco><compiler discardvisual="false"/></mujoco></robot>')
    return text


def compile_copy(spec: mujoco.MjSpec, visuals: bool = True) -> mujoco.MjModel:
    """Compile a copy of ``spec``, which stays uncompiled (small: it names its mesh files, holds none of their data).

    Args:
        visuals: keep the visual-only geoms (contype = conaffinity = 0) and the meshes only they use;
            without them the bodies, joints, masses, sites, actuators and keyframes are the same
            (the G1's model: 0.1 MB instead of 85 MB, mostly its meshes' bounding volume trees). A model
            with visuals is kept compiled on disk (:mod:`robot_models.model_cache`).
    """
    copy = spec.copy()
    if not visuals:
        copy.compiler.discardvisual = True
        return copy.compile()  # milliseconds: no meshes to process
    from robot_models.model_cache import compile_cached

    return compile_cached(copy)  # the meshes' hulls and trees take most of a second: read from the cache


def joint_limits_of(model: mujoco.MjModel, joints: tuple[str, ...]) -> dict[str, JointLimits]:
    """Position and effort limits of the named joints, read from a compiled model."""
    limits = {}
    for name in joints:
        joint = model.joint(name)
        lower, upper = (float(v) for v in joint.range)
        effort = float(max(abs(model.jnt_actfrcrange[joint.id][0]), abs(model.jnt_actfrcrange[joint.id][1])))
        limits[name] = JointLimits(lower=lower, upper=upper, effort=effort)
    return limits


def add_position_actuator(
    spec: mujoco.MjSpec, joint: str, kp: float, kv: float, force_limit: float | None
) -> None:
    """Add a position servo on ``joint`` with an unlimited control range.

    The control range is left unlimited on purpose: a controller may add a feed-forward torque
    through the servo as ``ctrl = q_des + tau_ff / kp``; torque stays limited by the force range
    (or the joint's actuator force range from the URDF effort limit).
    """
    import mujoco

    actuator = spec.add_actuator(name=joint, target=joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
    actuator.set_to_position(kp=kp, kv=kv)
    actuator.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
    if force_limit is not None:
        actuator.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        actuator.forcerange = [-force_limit, force_limit]
