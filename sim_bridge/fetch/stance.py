"""Where to stand to work at a table: the scene's table tops and a stance facing one of their edges.

A table top is an obstacle of the scene (:class:`~robot_models.spec.Obstacle`): its top is at its
height, over its footprint. A stance faces the edge of the top nearest the point to work at, with the
pelvis ``reach`` behind that point along the edge's inward normal, and its heading the one that
lines the object's grip axis up with the robot's left-right axis. It is refused when the point lies
too deep inside the top (the body would meet the table), or when the grip heading is too far from
facing the edge.
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
        hand_reach_m: ``reach_m`` for a grasp with one hand [m] (the pelvis stands about 5 cm behind the feet, and
            the hand reaches less far forward than the palms on a box's sides).
        hand_side_m: for a grasp with one hand, the stance stands this far to the side of the object, away
            from the hand (the object in front of that hand's shoulder) [m].
    """

    reach_m: float = 0.18
    max_reach_m: float = 0.22
    body_clearance_m: float = 0.04
    approach_back_m: float = 0.35
    approach_edge_m: float = 0.45
    max_heading_offset_rad: float = math.radians(30.0)
    hand_reach_m: float = 0.14
    hand_side_m: float = 0.10


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


def _to_local(table: Obstacle, x: float, y: float) -> tuple[float, float]:
    dx, dy = x - table.center_xy[0], y - table.center_xy[1]
    c, s = math.cos(table.yaw), math.sin(table.yaw)
    return c * dx + s * dy, -s * dx + c * dy


def plan_stance(table: Obstacle, x: float, y: float, grip_yaw: float | None, config: StanceConfig,
                symmetry_rad: float = math.pi) -> Stance:
    """A stance to work at (x, y) on ``table``'s top, holding an object whose grip axis is at ``grip_yaw``.

    Args:
        table: the table the point is on.
        x, y: the point (the object's centre), world frame [m].
        grip_yaw: yaw of the object's x axis [rad]: the robot faces along it (or its opposite), so the
            palms meet the object's +-y faces; None: face the edge squarely.
        config: distances.
        symmetry_rad: the grip is the same turned by this [rad] (a half turn for the palms on a box's sides;
            a quarter turn for fingers on a square object).

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
        if abs(offset) > config.max_heading_offset_rad:
            problems.append(f"the grip needs a heading {math.degrees(offset):.0f} deg off facing the edge "
                            f"(at most {math.degrees(config.max_heading_offset_rad):.0f})")
            continue
        c, s = math.cos(heading), math.sin(heading)
        stance_x, stance_y = x - reach * c, y - reach * s
        back = (depth + config.approach_edge_m) / math.cos(offset)  # approach_edge_m from the edge, turned or not
        return Stance(stance_x, stance_y, wrap(heading), x - back * c, y - back * s, table.name)
    raise InvalidGoalError(f"no stance at {table.name} reaches ({x:.2f}, {y:.2f}): " + "; ".join(problems))


def beside(stance: Stance, left_m: float) -> Stance:
    """``stance`` and its approach point moved ``left_m`` [m] to the robot's left (negative: right)."""
    dx, dy = -math.sin(stance.yaw) * left_m, math.cos(stance.yaw) * left_m
    return replace(stance, x=stance.x + dx, y=stance.y + dy, approach_x=stance.approach_x + dx,
                   approach_y=stance.approach_y + dy)
