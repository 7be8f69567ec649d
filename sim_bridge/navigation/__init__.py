"""Navigation for a walking robot: occupancy grid of static obstacles, A* planning, path following."""

from sim_bridge.navigation.follower import FollowerCommand, PathFollower
from sim_bridge.navigation.grid import OccupancyGrid, grid_from_obstacles
from sim_bridge.navigation.planner import NoPathError, plan_path

__all__ = ["FollowerCommand", "NoPathError", "OccupancyGrid", "PathFollower", "grid_from_obstacles", "plan_path"]
