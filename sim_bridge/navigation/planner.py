"""A* on an occupancy grid (8-connected), then shortcutting by line of sight."""

from __future__ import annotations

import heapq
import itertools
import math

import numpy as np

from sim_bridge.errors import SimError
from sim_bridge.navigation.grid import OccupancyGrid


class NoPathError(SimError):
    """No collision-free path joins start and goal; the message says why."""


def _line_free(grid: OccupancyGrid, a: tuple[int, int], b: tuple[int, int]) -> bool:
    """Whether the segment between two cell centres crosses only free cells (sampled at 1/4 cell)."""
    steps = 4 * max(abs(b[0] - a[0]), abs(b[1] - a[1]), 1)
    for i in range(steps + 1):
        ix = math.floor(a[0] + 0.5 + (b[0] - a[0]) * i / steps)
        iy = math.floor(a[1] + 0.5 + (b[1] - a[1]) * i / steps)
        if grid.occupied[iy, ix]:
            return False
    return True


def plan_path(grid: OccupancyGrid, start_xy: tuple[float, float], goal_xy: tuple[float, float]) -> list[tuple[float, float]]:
    """Shortest 8-connected path from start to goal on free cells, as world waypoints [m].

    The start cell may be occupied (the robot may stand inside the inflation margin); the path
    leaves it by the nearest free cells.

    Raises:
        NoPathError: the goal is outside the grid or occupied, or no path exists.
    """
    start = grid.cell_of(*start_xy)
    goal = grid.cell_of(*goal_xy)
    if not grid.inside(*goal):
        raise NoPathError(f"goal ({goal_xy[0]:.2f}, {goal_xy[1]:.2f}) is outside the mapped area")
    if grid.occupied[goal[1], goal[0]]:
        raise NoPathError(f"goal ({goal_xy[0]:.2f}, {goal_xy[1]:.2f}) is inside an obstacle (or its safety margin)")
    if not grid.inside(*start):
        raise NoPathError(f"start ({start_xy[0]:.2f}, {start_xy[1]:.2f}) is outside the mapped area")
    occupied = grid.occupied
    came_from: dict[tuple[int, int], tuple[int, int]] = {}
    cost = {start: 0.0}
    frontier = [(0.0, start)]
    moves = [(dx, dy, math.hypot(dx, dy)) for dx in (-1, 0, 1) for dy in (-1, 0, 1) if dx or dy]
    while frontier:
        _, cell = heapq.heappop(frontier)
        if cell == goal:
            break
        base = cost[cell]
        for dx, dy, step in moves:
            nxt = (cell[0] + dx, cell[1] + dy)
            if not grid.inside(*nxt):
                continue
            if occupied[nxt[1], nxt[0]] and not occupied[cell[1], cell[0]]:
                continue  # never step from free space back into an obstacle
            new = base + step
            if new < cost.get(nxt, math.inf):
                cost[nxt] = new
                came_from[nxt] = cell
                heapq.heappush(frontier, (new + math.hypot(goal[0] - nxt[0], goal[1] - nxt[1]), nxt))
    if goal not in cost:
        raise NoPathError(f"no collision-free path to ({goal_xy[0]:.2f}, {goal_xy[1]:.2f})")
    cells = [goal]
    while cells[-1] != start:
        cells.append(came_from[cells[-1]])
    cells.reverse()
    # Shortcut: keep only the cells where the straight line would cross an obstacle.
    kept = [cells[0]]
    index = 0
    while index < len(cells) - 1:
        farthest = len(cells) - 1
        while farthest > index + 1 and not _line_free(grid, cells[index], cells[farthest]):
            farthest -= 1
        kept.append(cells[farthest])
        index = farthest
    waypoints = [grid.center_of(*c) for c in kept[1:]]
    waypoints[-1] = (float(goal_xy[0]), float(goal_xy[1]))
    return [(float(start_xy[0]), float(start_xy[1])), *waypoints]


def path_length(path: list[tuple[float, float]]) -> float:
    """Length of a polyline [m]."""
    return float(sum(np.hypot(b[0] - a[0], b[1] - a[1]) for a, b in itertools.pairwise(path)))
