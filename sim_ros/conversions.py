"""Conversions between the core's typed values and ROS messages (no logic beyond that; stamps: :mod:`sim_ros.stamps`)."""

from __future__ import annotations

import math

import numpy as np
from geometry_msgs.msg import Pose as PoseMsg
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg

from sim_bridge.navigation import OccupancyGrid
from sim_bridge.state import Pose


def set_pose(msg: PoseMsg, position: np.ndarray, quat_wxyz: np.ndarray) -> None:
    p = position.tolist()
    q = quat_wxyz.tolist()
    msg.position.x, msg.position.y, msg.position.z = p[0], p[1], p[2]
    msg.orientation.w, msg.orientation.x, msg.orientation.y, msg.orientation.z = q[0], q[1], q[2], q[3]


def pose_from_msg(msg: PoseMsg) -> Pose:
    """Core pose from a ROS pose. The quaternion is returned as given (not normalised)."""
    o = msg.orientation
    return Pose(
        np.array([msg.position.x, msg.position.y, msg.position.z]),
        np.array([o.w, o.x, o.y, o.z]),
    )



def yaw_of(quat_wxyz: np.ndarray) -> float:
    """Heading [rad] of a quaternion (rotation about world z)."""
    w, x, y, z = (float(v) for v in quat_wxyz)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def occupancy_grid_msg(grid: OccupancyGrid, frame_id: str = "world") -> OccupancyGridMsg:
    """nav_msgs/OccupancyGrid (100 = occupied, 0 = free) of a core grid."""
    msg = OccupancyGridMsg()
    msg.header.frame_id = frame_id
    msg.info.resolution = float(grid.resolution)
    msg.info.width, msg.info.height = grid.width, grid.height
    msg.info.origin.position.x, msg.info.origin.position.y = float(grid.origin_xy[0]), float(grid.origin_xy[1])
    msg.info.origin.orientation.w = 1.0
    msg.data = (grid.occupied.astype(np.int8) * 100).ravel().tolist()
    return msg
