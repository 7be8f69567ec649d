"""Franka Panda on a table with three graspable boxes, built from example-robot-data's URDF.

Changes against the URDF as shipped:
- both finger joints get their own position servo (the URDF mimic becomes a soft joint equality
  that lets the grasp go asymmetric, so it is removed);
- a ``tcp`` site 0.1034 m along the hand's z axis, gravity compensation on the arm links (as the
  real robot's controller does), arm position servos (kp 4500..2000);
- a table whose top is the plane z = 0 under the arm's base, a floor, a light, three 4 cm boxes;
- contact settings that hold a friction grasp: elliptic cone, impratio 10, condim 4 and a stiff
  ``solref`` on finger pads and boxes;
- a ``home`` keyframe with the fingers open and the boxes on the table;
- a fixed scene camera in front of the table looking at the boxes, and what a camera needs to see
  (:func:`robot_models.cameras.prepare_scene_for_cameras`: sky, floor texture, a directional light,
  a 1280 x 720 offscreen buffer).
"""

from __future__ import annotations

import mujoco
import numpy as np

import robot_models.panda_constants as names
from robot_models.cameras import add_optical_camera, prepare_scene_for_cameras
from robot_models.panda_layout import CAMERAS, SENSORS
from robot_models.physics import set_physics_options
from robot_models.sensors import add_sensors
from robot_models.spec import (
    ArmScene,
    GraspLimits,
    RobotSpec,
    UnknownSceneError,
    add_position_actuator,
    compile_copy,
    joint_limits_of,
    read_urdf,
)

PHYSICS_TIMESTEP_S = 0.002
IMPRATIO = 10.0  # frictional / normal contact impedance: a friction grasp that holds
CONTROL_DECIMATION = 2  # 250 Hz control
ARM_KP = (4500.0, 4500.0, 3500.0, 3500.0, 2000.0, 2000.0, 2000.0)
ARM_DAMPRATIO = 1.0
FINGER_KP = 1000.0
FINGER_KV = 50.0
FINGER_FORCE_LIMIT_N = 70.0
GRASP = GraspLimits(max_force_n=FINGER_FORCE_LIMIT_N, default_force_n=20.0)
CONTACT_SOLREF = [0.004, 1.0]
GRASP_FRICTION = [1.0, 0.02, 0.001]


def _looking_at(position: tuple[float, float, float], target: tuple[float, float, float]) -> tuple[float, float, float, float]:
    """Orientation (w, x, y, z) of an optical frame at ``position`` whose z axis points at ``target``
    and whose x axis (image right) is level."""
    forward = np.subtract(target, position)
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.column_stack([right, down, forward]).ravel())
    w, x, y, z = (float(v) for v in quat)
    return w, x, y, z


def build_spec() -> mujoco.MjSpec:
    """The Panda scene as an editable spec (not compiled)."""
    urdf = read_urdf(names.URDF_RELATIVE_PATH, keep_visuals=False)
    # Keep the fixed links (panda_link0, panda_hand) as bodies so their names exist in the model.
    urdf = urdf.replace("</robot>", '<mujoco><compiler fusestatic="false"/></mujoco></robot>')
    spec = mujoco.MjSpec.from_string(urdf)
    spec.modelname = names.ROBOT_NAME
    set_physics_options(spec, timestep_s=PHYSICS_TIMESTEP_S, impratio=IMPRATIO)

    for equality in list(spec.equalities):
        spec.delete(equality)
    for body in spec.bodies:
        if body.name.startswith("panda_link") or body.name == names.HAND_BODY:
            body.gravcomp = 1.0
    for body_name in (names.LEFT_FINGER_BODY, names.RIGHT_FINGER_BODY):
        for geom in spec.body(body_name).geoms:
            geom.condim = 4
            geom.solref = CONTACT_SOLREF
            geom.friction = GRASP_FRICTION
            geom.rgba = [0.25, 0.25, 0.25, 1.0]
    for geom in spec.geoms:
        if geom.rgba[0] == 0.5 and geom.rgba[1] == 0.5 and geom.rgba[2] == 0.5:
            geom.rgba = [0.92, 0.92, 0.92, 1.0]
    spec.body(names.HAND_BODY).add_site(name=names.TCP_SITE, pos=list(names.TCP_IN_HAND), size=[0.005] * 3)
    add_sensors(spec, SENSORS)

    world = spec.worldbody
    floor_material = prepare_scene_for_cameras(spec)
    world.add_geom(name=names.FLOOR_GEOM, type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05],
                   pos=[0, 0, -2 * names.TABLE_HALF_SIZE[2]], material=floor_material)
    table = world.add_body(name=names.TABLE_BODY, pos=list(names.TABLE_CENTER))
    table.add_geom(name=names.TABLE_GEOM, type=mujoco.mjtGeom.mjGEOM_BOX, size=list(names.TABLE_HALF_SIZE),
                   rgba=[0.55, 0.4, 0.25, 1.0], friction=GRASP_FRICTION)
    world.add_light(pos=[0.5, 0, 2.5], dir=[0, 0, -1], diffuse=[0.8, 0.8, 0.8])
    world.add_camera(name="track", pos=[1.6, -1.0, 0.9], xyaxes=[0.53, 0.85, 0, -0.35, 0.22, 0.91])
    (scene_camera,) = CAMERAS
    add_optical_camera(world, scene_camera, pos=names.SCENE_CAMERA_POSITION,
                       quat=_looking_at(names.SCENE_CAMERA_POSITION, names.SCENE_CAMERA_TARGET))
    for box_name, position, color in zip(names.BOX_NAMES, names.BOX_HOME_POSITIONS, names.BOX_COLORS, strict=True):
        box = world.add_body(name=box_name, pos=list(position))
        box.add_freejoint(name=box_name)
        half = names.BOX_HALF_SIZE
        box.add_geom(name=box_name, type=mujoco.mjtGeom.mjGEOM_BOX, size=[half, half, half], mass=names.BOX_MASS,
                     condim=4, solref=CONTACT_SOLREF, friction=GRASP_FRICTION, rgba=list(color))

    arm_joints = {joint.name: joint for joint in spec.joints}
    for joint_name in names.ARM_JOINTS + names.FINGER_JOINTS:
        # Finger armature 0.02 removes grip-width chatter while squeezing a box.
        arm_joints[joint_name].armature = 0.1 if joint_name in names.ARM_JOINTS else 0.02
        arm_joints[joint_name].damping = [1.0 if joint_name in names.ARM_JOINTS else 0.0, 0.0, 0.0]
    for joint_name, kp in zip(names.ARM_JOINTS, ARM_KP, strict=True):
        actuator = spec.add_actuator(name=joint_name, target=joint_name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        actuator.set_to_position(kp=kp, dampratio=ARM_DAMPRATIO)
        actuator.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
    for joint_name in names.FINGER_JOINTS:
        add_position_actuator(spec, joint_name, kp=FINGER_KP, kv=FINGER_KV, force_limit=FINGER_FORCE_LIMIT_N)
    return spec


def _home_qpos(model: mujoco.MjModel) -> np.ndarray:
    qpos = model.qpos0.copy()
    for joint_name, value in zip(names.ARM_JOINTS, names.HOME_ARM_QPOS, strict=True):
        qpos[model.joint(joint_name).qposadr[0]] = value
    for joint_name in names.FINGER_JOINTS:
        qpos[model.joint(joint_name).qposadr[0]] = names.FINGER_OPEN
    for box_name, position in zip(names.BOX_NAMES, names.BOX_HOME_POSITIONS, strict=True):
        adr = int(model.joint(box_name).qposadr[0])
        qpos[adr : adr + 7] = [*position, 1.0, 0.0, 0.0, 0.0]
    return qpos


def _arm_scene() -> ArmScene:
    """One gripper (two finger servos) on the arm; the arm keeps away from the table top, boxes rest on it."""
    return ArmScene(
        grippers={"arm": names.FINGER_JOINTS},
        gripper_open_width=2.0 * names.FINGER_OPEN,
        obstacle_geoms=(names.TABLE_GEOM,),
        collision_from_joint=3,
        objects_table_top_z=names.TABLE_TOP_Z,
        object_half_size=names.BOX_HALF_SIZE,
        table_xy_bounds=(
            names.TABLE_CENTER[0] - names.TABLE_HALF_SIZE[0],
            names.TABLE_CENTER[0] + names.TABLE_HALF_SIZE[0],
            names.TABLE_CENTER[1] - names.TABLE_HALF_SIZE[1],
            names.TABLE_CENTER[1] + names.TABLE_HALF_SIZE[1],
        ),
    )


def load(scene: str = names.DEFAULT_SCENE, visuals: bool = True) -> RobotSpec:
    """Build and compile the Panda scene (one scene: ``"table"``).

    Args:
        scene: ``"table"``.
        visuals: keep the visual-only geoms (``RobotSpec.visuals``); the Panda's model has none.

    Raises:
        UnknownSceneError: another scene name.
    """
    if scene not in names.SCENES:
        raise UnknownSceneError(f"unknown scene {scene!r} for {names.ROBOT_NAME}; scenes: {', '.join(names.SCENES)}")
    spec = build_spec()
    model = compile_copy(spec, visuals=False)  # kinematics for the keyframe; the spec itself is never compiled
    qpos = _home_qpos(model)
    ctrl = [qpos[model.joint(j).qposadr[0]] for j in names.ALL_JOINTS]
    spec.add_key(name=names.HOME_KEYFRAME, qpos=qpos.tolist(), ctrl=ctrl)
    model = compile_copy(spec, visuals)
    return RobotSpec(
        name=names.ROBOT_NAME,
        mjspec=spec,
        model=model,
        joint_groups={"arm": names.ARM_JOINTS, "gripper": names.FINGER_JOINTS},
        actuated_joints=names.ALL_JOINTS,
        end_effector_sites={"arm": names.TCP_SITE},
        default_end_effector="arm",
        feet_sites=(),
        base_body=names.ROOT_BODY,
        floating_base=False,
        keyframes=(names.HOME_KEYFRAME,),
        default_keyframe=names.HOME_KEYFRAME,
        joint_limits=joint_limits_of(model, names.ALL_JOINTS),
        control_decimation=CONTROL_DECIMATION,
        objects=names.BOX_NAMES,
        scene=scene,
        arm_scene=_arm_scene(),
        grasp=GRASP,
        sensors=SENSORS,
        cameras=CAMERAS,
        visuals=visuals,
    )
