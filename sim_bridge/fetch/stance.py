"""Where to stand to work at a table: the scene's table tops and a stance facing one of their edges.

A table top is an obstacle of the scene (:class:`~robot_models.spec.Obstacle`): its top is at its
height, over its footprint. A stance faces the edge of the top nearest the point to work at, with the
pelvis ``reach`` behind that point along the edge's inward normal, and its heading the one that
lines the object's grip axis up with the robot's left-right axis, turned at most
``max_heading_offset_rad`` from facing the edge: a grip needing more, by at most ``max_grip_turn_rad``, gets
the most and the hands turn the rest. It is refused when the point lies too deep inside the top (the body
would meet the table), or when the grip heading is farther still from facing the edge.

Where the feet would stand against a table's leg (an object near the end of a table, the robot turned
toward that end), the stance moves sideways, along the robot's left-right axis and away from the nearest
leg, in steps, until both soles and the line between them keep clear of every leg; the arms then reach
to that side. No clear stance
within ``max_side_shift_m``: refused.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

from robot_models.spec import Obstacle
from sim_bridge.errors import InvalidGoalError


def wrap(angle: float) -> float:
    """``angle`` [rad] wrapped into [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


@dataclass(frozen=True)
class StanceConfig:
    """How a stance is placed.

    Attributes:
        reach_m: horizontal distance from the stance point (the midpoint between the feet) to the
            object's centre along the heading [m]. Holding the arms forward, the pelvis stands a few
            centimetres behind the feet's midpoint.
        max_reach_m: the farthest reach, for an object deeper inside the table than ``reach_m`` allows
            (the feet then stand ``body_clearance_m`` from the edge) [m].
        body_clearance_m: least distance from the feet's midpoint to the table edge [m].
        approach_back_m: the robot steps back this far from a stance when it leaves it [m].
        approach_edge_m: the approach point, where navigation ends, is this far from the table's edge
            [m]; it must be outside the navigation map's inflated obstacles.
        max_heading_offset_rad: largest angle between the stance heading and the edge's inward normal.
        max_grip_turn_rad: a grip needing a heading farther off than ``max_heading_offset_rad`` by at most this
            gets a stance turned ``max_heading_offset_rad``; the hands turn the rest (the palms take the box's yaw).
        hand_reach_m: ``reach_m`` for a grasp with one hand [m] (the pelvis stands about 5 cm behind the feet, and
            the hand reaches less far forward than the palms on a box's sides).
        hand_max_heading_offset_rad: ``max_heading_offset_rad`` for a grasp with one hand.
        hand_side_m: for a grasp with one hand, the stance stands this far to the side of the object, away
            from the hand (the object in front of that hand's shoulder) [m].
        max_side_shift_m: farthest a stance moves sideways to keep the feet clear of a table's legs [m].
        side_shift_step_m: the sideways steps tried up to that [m].
        leg_margin_m: the robot's shins and thighs reach this far beyond its soles' sides [m].
    """


    reach_m: float = 0.18
    max_reach_m: float = 0.22
    body_clearance_m: float = 0.04
    approach_back_m: float = 0.35
    approach_edge_m: float = 0.45
    max_heading_offset_rad: float = math.radians(30.0)
    max_grip_turn_rad: float = math.radians(15.0)
    hand_reach_m: float = 0.14
    hand_max_heading_offset_rad: float = math.radians(45.0)
    hand_side_m: float = 0.10
    max_side_shift_m: float = 0.06
    side_shift_step_m: float = 0.02
    leg_margin_m: float = 0.005


@dataclass(frozen=True)
class Feet:
    """Where a standing robot's legs are, seen from above, for keeping them clear of a table's legs.

    Attributes:
        half_spacing_m: from the stance point (midpoint between the feet) to each sole's centre, sideways [m].
        half_length_m: half the sole's length, along the heading [m].
        radius_m: the legs' half width above the sole centre line: the sole's half width plus the margin the
            shins and thighs need [m].
    """

    half_spacing_m: float
    half_length_m: float
    radius_m: float


@dataclass(frozen=True)
class KeepOut:
    """A disc of the floor the feet keep out of (a table leg's footprint), world frame [m]."""

    x: float
    y: float
    radius: float


@dataclass(frozen=True)
class Stance:
    """A pose to stand in, and the approach point behind it (world frame).

    Attributes:
        x, y: the midpoint between the feet [m].
        yaw: heading [rad].
        approach_x, approach_y: the point ``approach_edge_m`` from the edge, where navigation ends [m].
        table: the table's name.
    """

    x: float
    y: float
    yaw: float
    approach_x: float
    approach_y: float
    table: str


def table_under(tables: Sequence[Obstacle], x: float, y: float, margin: float = 0.0) -> Obstacle | None:
    """The table whose top holds (x, y) with ``margin`` [m] to spare on every side, or None."""
    for table in tables:
        local_x, local_y = _to_local(table, x, y)
        if (abs(local_x) <= table.half_size_xy[0] - margin) and (abs(local_y) <= table.half_size_xy[1] - margin):
            return table
    return None


def edge_clearance(table: Obstacle, x: float, y: float) -> float:
    """Distance [m] from (x, y) to ``table``'s top seen from above: positive outside it, negative inside."""
    local_x, local_y = _to_local(table, x, y)
    out_x = abs(local_x) - table.half_size_xy[0]
    out_y = abs(local_y) - table.half_size_xy[1]
    if out_x <= 0.0 and out_y <= 0.0:
        return max(out_x, out_y)
    return math.hypot(max(out_x, 0.0), max(out_y, 0.0))


def _to_local(table: Obstacle, x: float, y: float) -> tuple[float, float]:
    dx, dy = x - table.center_xy[0], y - table.center_xy[1]
    c, s = math.cos(table.yaw), math.sin(table.yaw)
    return c * dx + s * dy, -s * dx + c * dy


def plan_stance(table: Obstacle, x: float, y: float, grip_yaw: float | None, config: StanceConfig,
                symmetry_rad: float = math.pi, side_m: float = 0.0, feet: Feet | None = None,
                keep_out: Sequence[KeepOut] = ()) -> Stance:
    """A stance to work at (x, y) on ``table``'s top, holding an object whose grip axis is at ``grip_yaw``.

    Args:
        table: the table the point is on.
        x, y: the point (the object's centre), world frame [m].
        grip_yaw: yaw of the object's x axis [rad]: the robot faces along it (or its opposite), so the
            palms meet the object's +-y faces; None: face the edge squarely.
        config: distances.
        symmetry_rad: the grip is the same turned by this [rad] (a half turn for the palms on a box's sides;
            a quarter turn for fingers on a square object).
        side_m: the stance stands this far to the robot's left of the object [m] (negative: right).
        feet: the robot's feet, kept clear of ``keep_out`` (None: not checked).
        keep_out: discs of the floor the feet keep clear of (the table legs).

    The approach point of a stance moved sideways is moved back along the heading to stay ``approach_edge_m``
    from the edge.

    Raises:
        InvalidGoalError: no edge of the table lets the robot reach the point (the message says why).
    """
    local_x, local_y = _to_local(table, x, y)
    hx, hy = table.half_size_xy
    # Inward normals (world yaw) and depths of the point from each edge.
    edges = [
        (hx - local_x, table.yaw + math.pi),  # the +x edge: stand beyond it, face -x
        (hx + local_x, table.yaw),
        (hy - local_y, table.yaw - math.pi / 2),
        (hy + local_y, table.yaw + math.pi / 2),
    ]
    problems = []
    for depth, normal in sorted(edges):
        most = config.max_reach_m - config.body_clearance_m
        reach = max(config.reach_m, depth + config.body_clearance_m)
        if depth > most:
            problems.append(f"{depth:.2f} m inside the edge facing yaw {math.degrees(wrap(normal + math.pi)):.0f} deg "
                            f"(at most {most:.2f} m is reachable)")
            continue
        heading = normal if grip_yaw is None else grip_yaw + symmetry_rad * round(wrap(normal - grip_yaw) / symmetry_rad)
        offset = wrap(heading - normal)
        if abs(offset) > config.max_heading_offset_rad + config.max_grip_turn_rad:
            most_rad = config.max_heading_offset_rad + config.max_grip_turn_rad
            problems.append(f"the grip needs a heading {math.degrees(offset):.0f} deg off facing the edge "
                            f"(at most {math.degrees(most_rad):.0f})")
            continue
        if abs(offset) > config.max_heading_offset_rad:  # the stance turns its most, the hands the rest
            offset = math.copysign(config.max_heading_offset_rad, offset)
            heading = normal + offset
        c, s = math.cos(heading), math.sin(heading)
        stance_x, stance_y = x - reach * c, y - reach * s
        back = (depth + config.approach_edge_m) / math.cos(offset)  # approach_edge_m from the edge, turned or not
        facing = Stance(stance_x, stance_y, wrap(heading), x - back * c, y - back * s, table.name)
        moved = _clear_of_legs(facing, side_m, config, feet, keep_out)
        # A sideways move of a turned stance brings its approach point nearer the edge (or farther): back along the
        # heading until it is approach_edge_m out again.
        inward_x, inward_y = math.cos(normal), math.sin(normal)
        nearer = (moved.approach_x - facing.approach_x) * inward_x + (moved.approach_y - facing.approach_y) * inward_y
        extra = nearer / math.cos(offset)
        return replace(moved, approach_x=moved.approach_x - extra * c, approach_y=moved.approach_y - extra * s)
    raise InvalidGoalError(f"no stance at {table.name} reaches ({x:.2f}, {y:.2f}): " + "; ".join(problems))


def _clear_of_legs(stance: Stance, side_m: float, config: StanceConfig, feet: Feet | None,
                   keep_out: Sequence[KeepOut]) -> Stance:
    """``stance`` moved ``side_m`` to the left, or, where the legs would stand against a table leg, moved farther
    sideways, away from the nearest table leg, in steps until they are clear or ``max_side_shift_m`` is reached."""
    first = beside(stance, side_m)
    if feet is None or not keep_out or legs_clear(first, feet, keep_out):
        return first
    left_x, left_y = -math.sin(first.yaw), math.cos(first.yaw)
    nearest = min(keep_out, key=lambda disc: math.hypot(disc.x - first.x, disc.y - first.y))
    away = -1.0 if (nearest.x - first.x) * left_x + (nearest.y - first.y) * left_y > 0.0 else 1.0
    steps = round(config.max_side_shift_m / config.side_shift_step_m)
    moved = first
    for k in range(1, steps + 1):
        moved = beside(stance, side_m + away * k * config.side_shift_step_m)
        if legs_clear(moved, feet, keep_out):
            return moved
    return moved


def legs_clear(stance: Stance, feet: Feet, keep_out: Sequence[KeepOut]) -> bool:
    """Whether each sole's centre line (heel to toe) and the line between the soles, widened by
    ``feet.radius_m``, miss every disc."""
    c, s = math.cos(stance.yaw), math.sin(stance.yaw)
    left = (stance.x - s * feet.half_spacing_m, stance.y + c * feet.half_spacing_m)
    right = (stance.x + s * feet.half_spacing_m, stance.y - c * feet.half_spacing_m)
    toe_x, toe_y = c * feet.half_length_m, s * feet.half_length_m
    segments = [((x - toe_x, y - toe_y), (x + toe_x, y + toe_y)) for x, y in (left, right)] + [(left, right)]
    return all(_distance_to_segment((disc.x, disc.y), *segment) >= disc.radius + feet.radius_m
               for disc in keep_out for segment in segments)


def _distance_to_segment(point: tuple[float, float], start: tuple[float, float], end: tuple[float, float]) -> float:
    """Distance [m] from ``point`` to the segment from ``start`` to ``end`` (2-D)."""
    dx, dy = end[0] - start[0], end[1] - start[1]
    length2 = dx * dx + dy * dy
    t = 0.0 if length2 == 0.0 else max(0.0, min(1.0, ((point[0] - start[0]) * dx + (point[1] - start[1]) * dy) / length2))
    return math.hypot(point[0] - start[0] - t * dx, point[1] - start[1] - t * dy)


def beside(stance: Stance, left_m: float) -> Stance:
    """``stance`` and its approach point moved ``left_m`` [m] to the robot's left (negative: right)."""
    dx, dy = -math.sin(stance.yaw) * left_m, math.cos(stance.yaw) * left_m
    return replace(stance, x=stance.x + dx, y=stance.y + dy, approach_x=stance.approach_x + dx,
                   approach_y=stance.approach_y + dy)
