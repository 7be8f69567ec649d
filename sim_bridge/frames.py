"""Named frames a goal may be given in: the frames ``/sim`` publishes on /tf, resolved from the sim's state.

/tf here holds ``world``; ``world -> odom`` (identity: odometry is exact in simulation) for a robot
with a floating base; ``odom -> <base body>`` (``world -> <base body>`` for a fixed base); every link
of the robot below its base; and ``world -> <object>`` for the scene's objects. ``map`` is accepted
as another name of ``world`` (there is no localisation drift to correct), as Nav2 users send goals
in it. A pose given in one of these frames is expressed in ``world`` with the frame's pose at the
moment the goal starts (the latest state: the simulation keeps no history to look up a past stamp).
"""

from __future__ import annotations

import mujoco
import numpy as np

from robot_models import RobotSpec
from sim_bridge.errors import InvalidGoalError
from sim_bridge.state import Pose

WORLD_FRAMES = ("world", "map", "odom")  # one frame here; "" means world as well


def frame_names(robot: RobotSpec) -> tuple[str, ...]:
    """Every frame a goal may name for ``robot``: the world's names, the robot's links, the objects."""
    model = robot.model
    base = model.body(robot.base_body).id
    links = [model.body(i).name for i in range(1, model.nbody)
             if int(model.body_rootid[i]) == int(model.body_rootid[base]) and model.body(i).name]
    objects = [name for name in robot.objects if name not in links]
    return (*WORLD_FRAMES, *links, *objects)


def is_world(frame: str) -> bool:
    """Whether ``frame`` names the world frame (``""``, world, map, odom)."""
    return frame == "" or frame in WORLD_FRAMES


def check_frame(frame: str, robot: RobotSpec, what: str = "pose") -> None:
    """Raise :class:`InvalidGoalError` naming the known frames when ``frame`` is not one of them."""
    if is_world(frame):
        return
    known = frame_names(robot)
    if frame not in known:
        shown = frame if len(frame) <= 80 else frame[:77] + "..."
        raise InvalidGoalError(f"unknown {what} frame {shown!r}; known frames (as on /tf): world (or empty), "
                               f"{', '.join(known[1:])}")


def compose(parent: Pose, child: Pose) -> Pose:
    """``child`` given in ``parent``'s frame, expressed in the frame ``parent`` is given in."""
    rotation = np.empty(9)
    mujoco.mju_quat2Mat(rotation, parent.orientation_wxyz)
    orientation = np.empty(4)
    mujoco.mju_mulQuat(orientation, parent.orientation_wxyz, child.orientation_wxyz)
    return Pose(parent.position + rotation.reshape(3, 3) @ child.position, orientation)


def frame_pose(model: mujoco.MjModel, data: mujoco.MjData, frame: str) -> Pose:
    """World pose of a named frame (a world name or a body), from the simulation's current state.

    Raises:
        InvalidGoalError: no such frame.
    """
    if is_world(frame):
        return Pose(np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]))
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, frame)
    if body < 0:
        raise InvalidGoalError(f"unknown frame {frame!r}")
    return Pose(data.xpos[body].copy(), data.xquat[body].copy())


def to_world(model: mujoco.MjModel, data: mujoco.MjData, frame: str, local: Pose) -> Pose:
    """A pose given in ``frame``, expressed in the world frame (the frame's pose now)."""
    if is_world(frame):
        return local
    return compose(frame_pose(model, data, frame), local)
