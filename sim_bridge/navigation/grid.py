"""A 2-D occupancy grid in the world frame, built from a scene's static obstacles."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robot_models import Obstacle

DEFAULT_RESOLUTION_M = 0.05
DEFAULT_BOUNDS_M = (-4.0, 8.0, -6.0, 6.0)  # x_min, x_max, y_min, y_max of the mapped area


@dataclass(frozen=True)
class OccupancyGrid:
    """Cells of ``resolution`` metres; ``occupied[iy, ix]`` (row = y, as in nav_msgs/OccupancyGrid).

    Attributes:
        origin_xy: world position of the corner of cell (0, 0) [m].
        resolution: cell size [m].
        occupied: boolean array, shape (height, width).
    """

    origin_xy: tuple[float, float]
    resolution: float
    occupied: np.ndarray

    @property
    def width(self) -> int:
        return int(self.occupied.shape[1])

    @property
    def height(self) -> int:
        return int(self.occupied.shape[0])

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        """(ix, iy) of the cell holding world point (x, y) [m]; may be outside the grid."""
        return (math.floor((x - self.origin_xy[0]) / self.resolution),
                math.floor((y - self.origin_xy[1]) / self.resolution))

    def center_of(self, ix: int, iy: int) -> tuple[float, float]:
        return (self.origin_xy[0] + (ix + 0.5) * self.resolution, self.origin_xy[1] + (iy + 0.5) * self.resolution)

    def occupied_centers(self) -> tuple[tuple[float, float], ...]:
        """World centres [m] of the occupied cells, row by row."""
        rows, columns = np.nonzero(self.occupied)
        return tuple(self.center_of(int(ix), int(iy)) for iy, ix in zip(rows.tolist(), columns.tolist(), strict=True))

    def inside(self, ix: int, iy: int) -> bool:
        return 0 <= ix < self.width and 0 <= iy < self.height

    def is_free(self, x: float, y: float) -> bool:
        """Whether world point (x, y) is inside the grid and not occupied."""
        ix, iy = self.cell_of(x, y)
        return self.inside(ix, iy) and not bool(self.occupied[iy, ix])

    def inflated(self, radius_m: float) -> OccupancyGrid:
        """A grid whose occupied cells grow by ``radius_m`` (disc), for a robot of that radius."""
        cells = math.ceil(radius_m / self.resolution)
        if cells <= 0:
            return self
        grown = self.occupied.copy()
        offsets = [(dx, dy) for dx in range(-cells, cells + 1) for dy in range(-cells, cells + 1)
                   if dx * dx + dy * dy <= cells * cells]
        ys, xs = np.nonzero(self.occupied)
        for dx, dy in offsets:
            yy, xx = ys + dy, xs + dx
            keep = (yy >= 0) & (yy < self.height) & (xx >= 0) & (xx < self.width)
            grown[yy[keep], xx[keep]] = True
        return OccupancyGrid(self.origin_xy, self.resolution, grown)


def grid_from_obstacles(obstacles: tuple[Obstacle, ...], resolution: float = DEFAULT_RESOLUTION_M,
                        bounds: tuple[float, float, float, float] = DEFAULT_BOUNDS_M) -> OccupancyGrid:
    """Rasterise box footprints (cells whose centre lies inside a footprint are occupied)."""
    x_min, x_max, y_min, y_max = bounds
    width = round((x_max - x_min) / resolution)
    height = round((y_max - y_min) / resolution)
    xs = x_min + (np.arange(width) + 0.5) * resolution
    ys = y_min + (np.arange(height) + 0.5) * resolution
    gx, gy = np.meshgrid(xs, ys)
    occupied = np.zeros((height, width), dtype=bool)
    for obstacle in obstacles:
        c, s = math.cos(obstacle.yaw), math.sin(obstacle.yaw)
        dx, dy = gx - obstacle.center_xy[0], gy - obstacle.center_xy[1]
        local_x, local_y = c * dx + s * dy, -s * dx + c * dy
        occupied |= (np.abs(local_x) <= obstacle.half_size_xy[0]) & (np.abs(local_y) <= obstacle.half_size_xy[1])
    return OccupancyGrid((x_min, y_min), resolution, occupied)
