"""Per-robot arm facts: which arms have grippers and what each arm must not collide with.

Every name comes from the robot's constants module; robots without an entry get arms without
grippers and no collision avoidance obstacles.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from robot_models import RobotSpec, g1_constants, panda_constants


@dataclass(frozen=True)
class ArmSceneConfig:
    """Arm facts of one robot scene.

    Attributes:
        grippers: arm name -> finger joint names (each actuated by a position servo).
        gripper_open_width: widest gripper opening [m] (sum of both finger travels).
        obstacle_geoms: geoms the arm links must keep away from.
        obstacle_bodies: bodies whose geoms the arm links must keep away from.
        collision_from_joint: index in the arm's joint list of the first joint whose body
            subtree is checked against the obstacles (links near the shoulder are skipped).
        make_visuals_collide: the obstacle and arm geoms are visual-only in the physics model;
            enable them in the IK model so mink's collision limit uses them.
        objects_table_top_z: height of the surface objects rest on [m] (None when no table).
        object_half_size: half edge of the graspable boxes [m].
        table_xy_bounds: (x_min, x_max, y_min, y_max) of the table top [m] (None when no table).
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


def scene_config(robot: RobotSpec) -> ArmSceneConfig:
    """The arm facts of a robot scene, by registry name."""
    if robot.name == panda_constants.ROBOT_NAME:
        return ArmSceneConfig(
            grippers={"arm": panda_constants.FINGER_JOINTS},
            gripper_open_width=2.0 * panda_constants.FINGER_OPEN,
            obstacle_geoms=(panda_constants.TABLE_GEOM,),
            collision_from_joint=3,
            objects_table_top_z=panda_constants.TABLE_TOP_Z,
            object_half_size=panda_constants.BOX_HALF_SIZE,
            table_xy_bounds=(
                panda_constants.TABLE_CENTER[0] - panda_constants.TABLE_HALF_SIZE[0],
                panda_constants.TABLE_CENTER[0] + panda_constants.TABLE_HALF_SIZE[0],
                panda_constants.TABLE_CENTER[1] - panda_constants.TABLE_HALF_SIZE[1],
                panda_constants.TABLE_CENTER[1] + panda_constants.TABLE_HALF_SIZE[1],
            ),
        )
    if robot.name == g1_constants.ROBOT_NAME:
        leg_and_waist = g1_constants.LEFT_LEG_JOINTS + g1_constants.RIGHT_LEG_JOINTS + g1_constants.WAIST_JOINTS
        bodies = (g1_constants.ROOT_BODY, g1_constants.TORSO_BODY) + tuple(
            robot.model.body(robot.model.jnt_bodyid[robot.model.joint(j).id]).name for j in leg_and_waist
        )
        return ArmSceneConfig(obstacle_bodies=bodies, collision_from_joint=3, make_visuals_collide=True)
    return ArmSceneConfig()
