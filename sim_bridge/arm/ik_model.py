"""The private model the arms' IK runs on: colliding meshes, the other DoFs unlimited, each arm's collision pairs."""

from __future__ import annotations

import copy

import mujoco
import numpy as np

from robot_models import ArmScene, RobotSpec
from robot_models.model_cache import compile_cached
from sim_bridge.arm.description import ArmInfo
from sim_bridge.errors import SimError


def _subtree_bodies(model: mujoco.MjModel, root: int) -> list[int]:
    bodies = [root]
    for body in range(root + 1, model.nbody):
        parent = int(model.body_parentid[body])
        if parent in bodies:
            bodies.append(body)
    return bodies


def _arm_and_obstacle_geoms(model: mujoco.MjModel, scene: ArmScene, info: ArmInfo) -> tuple[list[int], list[int]]:
    """The arm link geoms checked for collisions (from ``scene.collision_from_joint`` on) and the obstacle geoms."""
    obstacle_geoms = [model.geom(name).id for name in scene.obstacle_geoms]
    for body_name in scene.obstacle_bodies:
        body_id = model.body(body_name).id
        obstacle_geoms += [g for g in range(model.ngeom) if model.geom_bodyid[g] == body_id]
    first = info.joints[min(scene.collision_from_joint, len(info.joints) - 1)]
    bodies = set(_subtree_bodies(model, int(model.jnt_bodyid[model.joint(first).id])))
    arm_geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] in bodies]
    return arm_geoms, obstacle_geoms


def build_collision_model(robot: RobotSpec, scene: ArmScene, infos: dict[str, ArmInfo]) -> mujoco.MjModel:
    """The robot's model, recompiled with the arm and obstacle geoms colliding if they are visual-only.

    Compiling them as colliding geoms (rather than flipping ``geom_contype`` in a compiled model)
    gives their meshes the convex hulls MuJoCo's distance queries walk: without one, every query
    visits all of a mesh's vertices.

    Raises:
        SimError: the robot was loaded without the visual meshes its IK needs, or the recompiled model
            does not have the layout of the robot's model.
    """
    model = robot.model
    if not scene.make_visuals_collide:
        return model
    if not robot.visuals:
        raise SimError(f"robot {robot.name!r} was loaded without its visual meshes, which its arms' IK keeps away "
                       "from: load it with visuals")
    colliding = set()
    for info in infos.values():
        arm_geoms, obstacle_geoms = _arm_and_obstacle_geoms(model, scene, info)
        colliding.update(arm_geoms + obstacle_geoms)
    spec = robot.mjspec.copy()
    for geom_id, geom in enumerate(spec.geoms):
        if geom_id in colliding:
            geom.contype, geom.conaffinity = 1, 1
    compiled = compile_cached(spec)  # ~0.8 s for the G1's meshes, ~0.1 s once kept on disk
    same_layout = (
        (compiled.nq, compiled.nv, compiled.ngeom, compiled.nbody) == (model.nq, model.nv, model.ngeom, model.nbody)
        and np.array_equal(compiled.geom_bodyid, model.geom_bodyid) and np.array_equal(compiled.jnt_qposadr, model.jnt_qposadr)
    )
    if not same_layout:
        raise SimError(f"the collision model of {robot.name!r} does not have the layout of its model")
    return compiled


def build_ik_model(
    base: mujoco.MjModel, scene: ArmScene, infos: dict[str, ArmInfo],
) -> tuple[mujoco.MjModel, dict[str, list[tuple[list[int], list[int]]]]]:
    """A private copy of the model for the arms' IK, and each arm's collision pairs.

    Only the arms' joints keep their position limits in the copy: every other DoF is frozen by an
    equality constraint in each arm's problem, and a frozen DoF measured a hair outside its range
    would make mink's ConfigurationLimit contradict the freezing constraint. One copy serves every
    arm (the G1's IK model is ~60 MB): an arm's solve bounds only its own joints (the other arm is
    frozen there, and the arm-only QP of :class:`~sim_bridge.arm.ik_problem.IKProblem` eliminates
    the frozen DoFs), so the other arm's limits never enter it.

    Args:
        base: the robot's model, with the arm and obstacle geoms colliding (see :func:`build_collision_model`).
        scene: the robot's arm facts.
        infos: the arms, by name.

    Returns:
        The IK model, and per arm its mink collision pairs (arm link geoms, obstacle geoms).
    """
    model = copy.deepcopy(base)
    arm_joint_ids = {model.joint(j).id for info in infos.values() for j in info.joints}
    for joint_id in range(model.njnt):
        if joint_id not in arm_joint_ids:
            model.jnt_limited[joint_id] = 0
    pairs = {}
    for arm, info in infos.items():
        arm_geoms, obstacle_geoms = _arm_and_obstacle_geoms(model, scene, info)
        pairs[arm] = [(arm_geoms, obstacle_geoms)] if arm_geoms and obstacle_geoms else []
    return model, pairs
