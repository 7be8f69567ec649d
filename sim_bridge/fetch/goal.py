"""A fetch goal (an object and a place on a table top) and its plan, judged where the facts are known.

The plan is made from the measured state when the goal starts: the object's box, where it rests, the
table under it, the stances at the object and at the place. A goal that no plan serves is refused
with the reason (:class:`~sim_bridge.errors.InvalidGoalError`, or
:class:`~sim_bridge.errors.UnknownNameError` for an unknown object).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import mujoco
import numpy as np

from robot_models import RobotSpec
from robot_models.hands import HandLayout
from robot_models.spec import Obstacle
from robot_models.validation import check_range, is_number
from sim_bridge.errors import InvalidGoalError, UnknownNameError
from sim_bridge.fetch.bimanual import tilt_of, yaw_of
from sim_bridge.fetch.stance import Feet, KeepOut, Stance, StanceConfig, plan_stance, table_under, wrap
from sim_bridge.navigation import OccupancyGrid

REST_TOLERANCE_M = 0.02  # an object this close to resting height on a table top rests on it
MAX_REST_TILT_RAD = math.radians(10.0)
GRIP_SAFETY = 2.0  # the palms must hold this many times the object's weight by friction
MIN_GRIP_WIDTH_M = 0.15  # the palms meet across the chest no closer than this
MAX_GRIP_WIDTH_M = 0.40  # nor farther apart than this
NAVIGATION_INFLATION_M = 0.40  # obstacles grow by this for the navigation (robot radius + margin)
ONE_HAND_MAX_WIDTH_M = 0.07  # one hand closes its thumb and fingers around an object this wide at most
ONE_HAND_MAX_MASS_KG = 0.5  # ... this heavy at most (the fingers' servos squeeze with a bounded torque)


@dataclass(frozen=True)
class FetchGoal:
    """Carry an object with both hands to a place on a table top.

    Attributes:
        object_name: an object of the scene (``RobotSpec.objects``), a box.
        place_x, place_y: where its centre goes, world frame [m], on a table top.
        place_yaw: its yaw there [rad] (a box: modulo a half turn); None = facing the table's edge squarely.
        grip_force_n: squeeze force per palm [N].
        lift_height_m: how far it is lifted off the table [m].
        walking_speed_mps: pace of the walks [m/s].
        placement_tolerance_m: largest distance from the place counted as success [m].
        timeout_s: [s] of sim time for the whole task.
    """

    object_name: str
    place_x: float
    place_y: float
    place_yaw: float | None = None
    grip_force_n: float = 25.0
    # 5 cm: lifting 10 cm from the squeeze drove the elbows to their limit and the arms onto an elbows-out
    # branch (shoulder roll 0.3 -> 1.2 rad), from which lowering at the place ran into the wrists' limits.
    lift_height_m: float = 0.05
    walking_speed_mps: float = 0.3
    placement_tolerance_m: float = 0.02
    timeout_s: float = 240.0

    def __post_init__(self) -> None:
        values = {"place_x": self.place_x, "place_y": self.place_y}
        if self.place_yaw is not None:
            values["place_yaw"] = self.place_yaw
        bad = [name for name, value in values.items() if not is_number(value)]
        if bad:
            raise InvalidGoalError(f"{', '.join(bad)} must be finite numbers")
        check_range("grip_force", self.grip_force_n, 0.0, 80.0, low_open=True, unit="N", error=InvalidGoalError)
        check_range("lift_height", self.lift_height_m, 0.02, 0.25, unit="m", error=InvalidGoalError)
        check_range("walking_speed", self.walking_speed_mps, 0.1, 0.5, unit="m/s", error=InvalidGoalError)
        check_range("placement_tolerance", self.placement_tolerance_m, 0.0, low_open=True, unit="m", error=InvalidGoalError)
        check_range("timeout", self.timeout_s, 0.0, low_open=True, unit="s", error=InvalidGoalError)


@dataclass(frozen=True)
class FetchPlan:
    """What a fetch does, measured and planned when it starts.

    Attributes:
        body: the object's body id.
        half_size: its box's half sizes along its own x, y, z [m], shape (3,).
        mass_kg: [kg].
        pick: the stance at the object (the place's, for an object already in the palms).
        place: the stance at the place.
        place_center: where the object's centre rests at the end, world frame [m], shape (3,).
        place_top_z: the place table's top height [m].
        pick_top_z: the height of the table the object rests on [m].
    """

    body: int
    half_size: np.ndarray
    mass_kg: float
    pick: Stance
    place: Stance
    place_center: np.ndarray
    place_top_z: float
    pick_top_z: float


def _extent_of(model: mujoco.MjModel, body: int, name: str) -> tuple[np.ndarray, bool]:
    """The half sizes of the object's one geom along its own x, y, z [m] (a cylinder's: radius, radius, half
    height), and whether it is a box."""
    geoms = [g for g in range(model.ngeom) if int(model.geom_bodyid[g]) == body]
    kind = int(model.geom_type[geoms[0]]) if len(geoms) == 1 else -1
    if kind == int(mujoco.mjtGeom.mjGEOM_BOX):
        return model.geom_size[geoms[0]].copy(), True
    if kind == int(mujoco.mjtGeom.mjGEOM_CYLINDER):
        radius, half_height = (float(v) for v in model.geom_size[geoms[0]][:2])
        return np.array([radius, radius, half_height]), False
    raise InvalidGoalError(f"object {name!r} is neither a box nor a cylinder: the palms squeeze a box, one hand "
                           "holds a small box or cylinder")


def for_one_hand(robot: RobotSpec, name: str) -> bool:
    """Whether the robot takes object ``name`` with one hand: it has hands and the object is at most
    ``ONE_HAND_MAX_WIDTH_M`` across both horizontal axes (False for an unknown name or shape)."""
    if not robot.hands or name not in robot.objects:
        return False
    try:
        half, _ = _extent_of(robot.model, robot.model.body(name).id, name)
    except InvalidGoalError:
        return False
    return 2.0 * float(max(half[0], half[1])) <= ONE_HAND_MAX_WIDTH_M


def check_fetchable(robot: RobotSpec, name: str, grip_force_n: float) -> tuple[int, np.ndarray]:
    """Judge, from the model alone, whether the palms (or, for a small object, one hand) can hold object ``name``
    with ``grip_force_n`` per palm.

    Returns its body id and its half sizes [m] (a cylinder's: radius, radius, half height).

    Raises:
        UnknownNameError: not an object of the scene (the message lists them).
        InvalidGoalError: for the palms: not a box, too narrow or wide for them, or the grip too weak for its
            weight; for one hand: heavier than ``ONE_HAND_MAX_MASS_KG``.
    """
    model = robot.model
    if name not in robot.objects:
        raise UnknownNameError(f"unknown object {name!r}; objects: {', '.join(robot.objects) or 'none'}")
    body = model.body(name).id
    half, is_box = _extent_of(model, body, name)
    mass = float(model.body_mass[body])
    if for_one_hand(robot, name):
        if mass > ONE_HAND_MAX_MASS_KG:
            raise InvalidGoalError(f"object {name!r} ({mass:.2f} kg) is too heavy for one hand's fingers: at most "
                                   f"{ONE_HAND_MAX_MASS_KG:.1f} kg")
        return body, half
    if not is_box:
        raise InvalidGoalError(f"object {name!r} is not a box: both palms squeeze only a box between them")
    width = 2.0 * float(half[1])
    if not MIN_GRIP_WIDTH_M <= width <= MAX_GRIP_WIDTH_M:
        hand = f", one hand at most {ONE_HAND_MAX_WIDTH_M:.2f} m" if robot.hands else " (the robot has no hand to grasp with)"
        raise InvalidGoalError(f"object {name!r} is {width:.3f} m wide across its grip axis (y): the palms "
                               f"hold {MIN_GRIP_WIDTH_M:.2f}-{MAX_GRIP_WIDTH_M:.2f} m{hand}")
    mu = float(max(model.geom_friction[g][0] for g in range(model.ngeom) if int(model.geom_bodyid[g]) == body))
    gravity = float(np.linalg.norm(model.opt.gravity))
    if 2.0 * mu * grip_force_n < GRIP_SAFETY * mass * gravity:
        least = GRIP_SAFETY * mass * gravity / (2.0 * mu)
        raise InvalidGoalError(f"a grip of {grip_force_n:.1f} N per palm is too weak for {name!r} "
                               f"({mass:.2f} kg): at least {least:.1f} N")
    return body, half


def check_place_on_a_table(robot: RobotSpec, x: float, y: float) -> None:
    """Raise :class:`InvalidGoalError` (naming the table tops) unless (x, y) [m, world] is on a table top."""
    if table_under(robot.obstacles, x, y) is None:
        raise InvalidGoalError(f"place ({x:.2f}, {y:.2f}) is not on a table top; table tops: "
                               + (", ".join(_bounds(t) for t in robot.obstacles) or "none"))


def plan_fetch(robot: RobotSpec, data: mujoco.MjData, goal: FetchGoal, grid: OccupancyGrid,
               config: StanceConfig, in_hand: bool = False, hand: HandLayout | None = None) -> FetchPlan:
    """Judge the goal in the current state and plan its stances (``in_hand``: the palms, or the hand, hold the
    object already; only the place is planned, and the plan's pick is the place's stance). With ``hand`` the
    object is taken with that hand (a small object: :func:`for_one_hand`), and the stances stand
    ``hand_side_m`` to the side of the object and of the place, away from the hand; without it, with both palms.

    Raises:
        UnknownNameError: not an object of the scene (the message lists them).
        InvalidGoalError: the object is not a box the palms can hold, does not rest on a table top, no
            stance reaches it, or the place is not on a table top or out of reach (the message says why).
    """
    body, half = check_fetchable(robot, goal.object_name, goal.grip_force_n)
    if (hand is not None) != for_one_hand(robot, goal.object_name):
        width = 2.0 * float(half[1])
        raise InvalidGoalError(f"object {goal.object_name!r} ({width:.3f} m wide across its grip axis (y)) is for "
                               + ("both palms, not one hand" if hand is not None else "one hand, not both palms"))
    # A hand's fingers hold a square object turned by any quarter turn; a cylinder from any side.
    square = hand is not None and abs(float(half[0]) - float(half[1])) < 1e-6
    symmetry = math.pi / 2 if square else math.pi
    side = 0.0 if hand is None else math.copysign(config.hand_side_m, hand.palm_normal_in_tool[1])
    # One hand: the stance turns with the object as far as it turns at all (the wrist turning the rest ran the arm
    # into its limits).
    config = config if hand is None else replace(config, reach_m=config.hand_reach_m, max_grip_turn_rad=0.0,
                                                         max_heading_offset_rad=config.hand_max_heading_offset_rad)
    mass = float(robot.model.body_mass[body])
    tables = robot.obstacles
    position, quat = data.xpos[body], data.xquat[body]
    x, y, z = (float(v) for v in position)
    table = table_under(tables, x, y)
    if not in_hand and (table is None or abs(z - (table.height + float(half[2]))) > REST_TOLERANCE_M
                        or tilt_of(quat) > MAX_REST_TILT_RAD):
        raise InvalidGoalError(f"object {goal.object_name!r} at ({x:.2f}, {y:.2f}, {z:.2f}) does not rest upright on a "
                               f"table top ({', '.join(t.name for t in tables) or 'no tables'})")
    place_table = table_under(tables, goal.place_x, goal.place_y)
    # Both palms only: a one-hand stance stands 10 cm aside already, and moved farther the hand's pose beside the
    # object left the arm's reach (the can near the table's end: 16 mm short).
    feet, legs = (feet_of(robot, config), table_legs(robot)) if hand is None else (None, ())
    place = None if place_table is None else plan_stance(place_table, goal.place_x, goal.place_y, goal.place_yaw,
                                                         config, symmetry, side, feet, legs)
    if place_table is None or place is None or not _fits(place_table, goal.place_x, goal.place_y, place.yaw, half):
        raise InvalidGoalError(f"place ({goal.place_x:.2f}, {goal.place_y:.2f}) does not keep {goal.object_name!r} "
                               "whole on a table top; table tops: " + ", ".join(_bounds(t) for t in tables))
    if in_hand or table is None:
        pick, pick_top_z = place, place_table.height
    else:
        grip_yaw = yaw_of(quat) if hand is None or square else None
        pick = plan_stance(table, x, y, grip_yaw, config, symmetry, side, feet, legs)
        pick_top_z = table.height
    inflated = grid.inflated(NAVIGATION_INFLATION_M)
    for stance, what in ((pick, "the object"), (place, "the place")):
        if not inflated.is_free(stance.approach_x, stance.approach_y):
            raise InvalidGoalError(f"the approach to {what} ({stance.approach_x:.2f}, {stance.approach_y:.2f}) is "
                                   "blocked by an obstacle")
    center = np.array([goal.place_x, goal.place_y, place_table.height + float(half[2])])
    return FetchPlan(body, half, mass, pick, place, center, place_table.height, pick_top_z)


def feet_of(robot: RobotSpec, config: StanceConfig) -> Feet | None:
    """The robot's feet seen from above (None for a robot that does not walk)."""
    biped = robot.biped
    if biped is None:
        return None
    return Feet(biped.half_step_width_m, float(biped.sole_half_size[0]), float(biped.sole_half_size[1]) + config.leg_margin_m)


def table_legs(robot: RobotSpec) -> tuple[KeepOut, ...]:
    """The footprints of the obstacles' geoms besides their main one (a table's legs), from the model."""
    model = robot.model
    discs = []
    for obstacle in robot.obstacles:
        for name in obstacle.geom_names[1:]:
            geom = model.geom(name)
            if int(model.geom_bodyid[geom.id]) != 0:  # only static geoms of the world body have world poses here
                continue
            discs.append(KeepOut(float(geom.pos[0]), float(geom.pos[1]), float(math.hypot(geom.size[0], geom.size[1]))))
    return tuple(discs)


def _bounds(table: Obstacle) -> str:
    (cx, cy), (hx, hy) = table.center_xy, table.half_size_xy
    return f"{table.name} x [{cx - hx:.2f}, {cx + hx:.2f}] y [{cy - hy:.2f}, {cy + hy:.2f}]"


def _fits(table: Obstacle, x: float, y: float, yaw: float, half: np.ndarray) -> bool:
    """Whether a box of half sizes ``half`` centred at (x, y) with ``yaw`` lies within the table's top."""
    relative = yaw - table.yaw
    c, s = abs(math.cos(relative)), abs(math.sin(relative))
    extent_x, extent_y = c * half[0] + s * half[1], s * half[0] + c * half[1]
    dx, dy = x - table.center_xy[0], y - table.center_xy[1]
    local_x = math.cos(table.yaw) * dx + math.sin(table.yaw) * dy
    local_y = -math.sin(table.yaw) * dx + math.cos(table.yaw) * dy
    return abs(local_x) + extent_x <= table.half_size_xy[0] and abs(local_y) + extent_y <= table.half_size_xy[1]


def heading_error(stance: Stance, yaw: float) -> float:
    """Signed difference from the stance heading to ``yaw`` [rad]."""
    return wrap(yaw - stance.yaw)
