"""Which actions each server executable serves, and their types: names only, no model and no physics.

The servers use these tables; ``bringup`` reads them to watch the servers' goals without importing a
server (a server's module brings the robot model, mink and the skills with it).
"""

from __future__ import annotations

from typing import Any, Final

from sim_interfaces.action import MoveArm, NavigateToPose, PickPlace, ResetPose, Walk

ARM_ACTIONS: Final = {"move_arm": "move_arm", "pick_place": "pick_place"}  # skill -> the action that serves it
LOCOMOTION_ACTIONS: Final = {"walk": "walk", "navigate_to_pose": "navigate_to_pose"}  # skill -> the action that serves it
ACTION_TYPES: Final[dict[str, Any]] = {
    "walk": Walk, "navigate_to_pose": NavigateToPose, "reset_pose": ResetPose, "move_arm": MoveArm, "pick_place": PickPlace,
}  # skill -> its generated action type
SERVED_BY: Final = {"arm_server": ARM_ACTIONS, "locomotion_server": LOCOMOTION_ACTIONS}  # executable -> its actions
