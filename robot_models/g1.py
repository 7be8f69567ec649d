"""Unitree G1 (29 DoF) with Dex3-1 hands on a floor, built from example-robot-data's URDF.

Changes against the URDF as shipped:
- the floating base block (commented out in the URDF) is restored, so the pelvis has a free joint;
- the mesh collision geoms and the four 5 mm foot spheres are replaced by one box sole per foot
  (0.20 x 0.07 m, like the real sole); visual meshes are kept for rendering, without contacts;
- a body shell of capsules and spheres (pelvis, torso, head, limbs, hands) that touches only the
  floor and obstacles, so a fallen robot lies on the floor;
- the hands' contact geoms for grasping (a palm box and capsules on the finger links, condim 4, friction 1,
  a stiff ``solref``) and position servos on their 14 joints, whose torque is the URDF's effort limit at
  most, so a closing hand squeezes with a bounded force (see :func:`_add_hands`);
- a floor, a light, sole/hand/IMU sites, an IMU and wrist force/torque sensors (:mod:`robot_models.sensors`),
  joint armature and damping, position servos with gains
  that hold a stand (hip/knee 500, hip yaw 350, ankle 300, kd = 0.03 kp; waist and arms 150/3);
- a head camera on a tilt mount where the real G1's D435 sits (see :func:`_add_head_camera`), and what
  a camera needs to see (:func:`robot_models.cameras.prepare_scene_for_cameras`: sky, floor texture,
  a directional light, a 1280 x 720 offscreen buffer);
- physics: 2 ms step, implicitfast, elliptic friction cone with impratio 10;
- a ``stand`` keyframe in a slight crouch with both soles flat on the floor and both hands open.
"""

from __future__ import annotations

import mujoco
import numpy as np

import robot_models.g1_constants as names
import robot_models.g1_tables as tables
from robot_models.cameras import OPTICAL_IN_BODY_QUAT, CameraLayout, add_optical_camera, prepare_scene_for_cameras
from robot_models.g1_gait import BIPED, WALKING
from robot_models.g1_grasp import HANDS
from robot_models.g1_layout import CAMERAS, SENSORS
from robot_models.g1_palms import PALM_SITES
from robot_models.physics import set_physics_options
from robot_models.sensors import add_sensors
from robot_models.spec import (
    ArmScene,
    Obstacle,
    RobotSpec,
    UnknownSceneError,
    add_position_actuator,
    compile_copy,
    joint_limits_of,
    read_urdf,
)

PHYSICS_TIMESTEP_S = 0.002
IMPRATIO = 10.0  # frictional / normal contact impedance: soles that stick
CONTROL_DECIMATION = 2  # 250 Hz control

# Standing crouch [rad]: hip pitch, knee, ankle pitch per leg.
STAND_HIP_PITCH = -0.3
STAND_KNEE = 0.6
STAND_ANKLE_PITCH = -0.3
STAND_ARM_POSE = {"shoulder_roll": 0.25, "elbow": 0.9}

LEG_GAINS = {"hip_pitch": 500.0, "hip_roll": 500.0, "hip_yaw": 350.0, "knee": 500.0, "ankle_pitch": 300.0, "ankle_roll": 300.0}
UPPER_BODY_KP = 150.0
UPPER_BODY_KV = 3.0
KD_OVER_KP = 0.03

# The head camera's tilt mount: a small servo (a 50 g camera balanced on its axis, a geared motor's
# reflected inertia, critically damped, 2 N m at most).
HEAD_CAMERA_MASS_KG = 0.05
HEAD_CAMERA_TILT_KP = 10.0  # [N m/rad]
HEAD_CAMERA_TILT_KV = 0.4  # [N m s/rad]
HEAD_CAMERA_TILT_FORCE_LIMIT = 2.0  # [N m]
HEAD_CAMERA_TILT_ARMATURE = 0.005  # [kg m^2]
HEAD_CAMERA_TILT_DAMPING = 0.05  # [N m s/rad]

# The hands' servos: light fingers (a few tens of grams per link) behind small geared motors. With
# the armature, a finger settles in about 0.1 s, critically damped; kp 2 N m/rad saturates at the
# URDF's effort limit (1.4 N m, the thumb's swing 2.45 N m) 0.7 rad short of a target, so a hand
# closed on an object squeezes it with that torque at most (about 15-20 N at a fingertip).
HAND_KP = 2.0  # [N m/rad]
HAND_KV = 0.08  # [N m s/rad]
HAND_ARMATURE = 0.001  # [kg m^2]
HAND_DAMPING = 0.02  # [N m s/rad]
HAND_CONTACT_SOLREF = [0.004, 1.0]  # stiff (2 physics steps), as the Panda's finger pads: light links sink otherwise
HAND_FRICTION = [1.0, 0.02, 0.001]


def _gain_for(joint: str) -> tuple[float, float]:
    for key, kp in LEG_GAINS.items():
        if f"_{key}_joint" in joint:
            return kp, KD_OVER_KP * kp
    return UPPER_BODY_KP, UPPER_BODY_KV


def _restore_floating_base(urdf: str) -> str:
    opening = '<!-- <link name="world"></link>'
    if opening not in urdf:
        raise ValueError("G1 URDF layout changed: the commented floating-base block was not found")
    urdf = urdf.replace(opening, '<link name="world"></link>', 1)
    return urdf.replace("</joint> -->", "</joint>", 1)


def _add_obstacles(spec: mujoco.MjSpec) -> tuple[Obstacle, ...]:
    obstacles = []
    for name, x, y, hx, hy, height in names.COURSE_OBSTACLES:
        spec.worldbody.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX, size=[hx, hy, height / 2],
                                pos=[x, y, height / 2], rgba=[0.8, 0.55, 0.2, 1.0], contype=1,
                                conaffinity=1 | names.SHELL_CONTYPE)
        obstacles.append(Obstacle(name=name, center_xy=(x, y), half_size_xy=(hx, hy), height=height))
    return tuple(obstacles)


def _add_body_shell(spec: mujoco.MjSpec) -> None:
    """Massless primitive geoms that collide with the floor and obstacles only (see ``BODY_SHELL``)."""
    for name, body, shape, radius, start, end in names.BODY_SHELL:
        geom = spec.body(body).add_geom(
            name=name, contype=names.SHELL_CONTYPE, conaffinity=0, condim=3, friction=[0.8, 0.02, 0.001],
            group=3, mass=0.0, rgba=[0.5, 0.5, 0.5, 0.3],
        )
        if shape == "capsule":
            if end is None:
                raise ValueError(f"body shell geom {name!r}: a capsule needs an end point")
            geom.type = mujoco.mjtGeom.mjGEOM_CAPSULE
            geom.fromto = [*start, *end]
            geom.size = [radius, 0.0, 0.0]
        else:
            geom.type = mujoco.mjtGeom.mjGEOM_SPHERE
            geom.pos = list(start)
            geom.size = [radius, 0.0, 0.0]


def _add_hands(spec: mujoco.MjSpec) -> None:
    """The hands' contact geoms (``HAND_PADS``) and the servos of their joints (after the body's actuators).

    The geoms are massless (the links' inertials come from the URDF); the servos' force limit is each
    joint's effort limit from the URDF, which MuJoCo also imported as the joint's actuator force range.
    """
    for name, body, shape, size, start, end in names.HAND_PADS:
        geom = spec.body(body).add_geom(
            name=name, contype=names.HAND_CONTYPE, conaffinity=1, condim=4, friction=HAND_FRICTION,
            solref=HAND_CONTACT_SOLREF, group=3, mass=0.0, rgba=[0.3, 0.3, 0.3, 0.5], size=list(size),
        )
        if shape == "capsule":
            if end is None:
                raise ValueError(f"hand geom {name!r}: a capsule needs an end point")
            geom.type = mujoco.mjtGeom.mjGEOM_CAPSULE
            geom.fromto = [*start, *end]
        else:
            geom.type = mujoco.mjtGeom.mjGEOM_BOX
            geom.pos = list(start)
    for joint_name in names.HAND_JOINTS:
        joint = spec.joint(joint_name)
        joint.armature = HAND_ARMATURE
        joint.damping = [HAND_DAMPING, 0.0, 0.0]
        add_position_actuator(spec, joint_name, kp=HAND_KP, kv=HAND_KV, force_limit=float(joint.actfrcrange[1]))


def _remove_point_mass(body: mujoco.MjsBody, mass: float, position: np.ndarray, inertia: np.ndarray) -> None:
    """Take a rigid part (``mass`` [kg], centre of mass ``position`` and inertia (3, 3) about it, in the
    body's frame) out of a body's explicit inertial, so that body + part weigh and turn as the body did."""
    full = np.asarray(body.fullinertia, dtype=float)
    if not body.explicitinertial or np.isnan(full[0]) or np.any(np.asarray(body.iquat) != [1.0, 0.0, 0.0, 0.0]):
        raise ValueError(f"body {body.name!r}: expected an explicit full inertia in the body's axes")
    inertia_body = np.array([[full[0], full[3], full[4]], [full[3], full[1], full[5]], [full[4], full[5], full[2]]])
    com = np.asarray(body.ipos, dtype=float)
    rest_mass = float(body.mass) - mass
    rest_com = (float(body.mass) * com - mass * position) / rest_mass

    def shift(d: np.ndarray) -> np.ndarray:  # parallel-axis term of a unit mass at offset d
        return np.dot(d, d) * np.eye(3) - np.outer(d, d)

    rest = inertia_body - inertia - mass * shift(position - com) - rest_mass * shift(rest_com - com)
    if np.any(np.linalg.eigvalsh(rest) <= 0.0):
        raise ValueError(f"body {body.name!r} is too light to carry {mass} kg out of it")
    body.mass = rest_mass
    body.ipos = rest_com.tolist()
    body.fullinertia = [rest[0, 0], rest[1, 1], rest[2, 2], rest[0, 1], rest[0, 2], rest[1, 2]]


def _add_head_camera(spec: mujoco.MjSpec, layout: CameraLayout) -> None:
    """The head camera on its tilt mount, a child of the torso (the G1 has no neck).

    The mount's pivot is the URDF's ``d435_link`` origin (the real camera's place behind the head's
    front cover); at tilt 0 its axes are the torso's (x forward, y left, z up), and the hinge turns it
    about y (+ = looking down) within the layout's range, held by a position servo. Its 50 g sit on the
    hinge axis and are taken out of the URDF's head link (whose mass holds the real camera already), so
    the robot's mass, centre of mass and inertia at tilt 0 are those of the URDF. Its housing is visual
    only (it collides with nothing). The optical frame is a child body at the lens.
    """
    if layout.tilt_joint is None:
        raise ValueError(f"camera {layout.name!r}: the G1's head camera needs a tilt joint")
    pivot = np.asarray(spec.body(names.D435_BODY).pos, dtype=float)
    mount = spec.body(names.TORSO_BODY).add_body(name=names.HEAD_CAMERA_LINK, pos=pivot.tolist())
    half = np.asarray(names.HEAD_CAMERA_HOUSING_HALF_SIZE)
    inertia = HEAD_CAMERA_MASS_KG / 3.0 * np.array([half[1] ** 2 + half[2] ** 2, half[0] ** 2 + half[2] ** 2,
                                                    half[0] ** 2 + half[1] ** 2])  # a solid box
    mount.explicitinertial = True
    mount.mass = HEAD_CAMERA_MASS_KG
    mount.ipos = [0.0, 0.0, 0.0]
    mount.inertia = inertia.tolist()
    low, high = layout.tilt_range_rad
    mount.add_joint(
        name=layout.tilt_joint, type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0.0, 1.0, 0.0],
        limited=mujoco.mjtLimited.mjLIMITED_TRUE, range=[low, high],
        actfrclimited=mujoco.mjtLimited.mjLIMITED_TRUE,
        actfrcrange=[-HEAD_CAMERA_TILT_FORCE_LIMIT, HEAD_CAMERA_TILT_FORCE_LIMIT],
        armature=HEAD_CAMERA_TILT_ARMATURE, damping=[HEAD_CAMERA_TILT_DAMPING, 0.0, 0.0],
    )
    mount.add_geom(name=names.HEAD_CAMERA_GEOM, type=mujoco.mjtGeom.mjGEOM_BOX, size=half.tolist(), contype=0,
                   conaffinity=0, group=1, mass=0.0, rgba=[0.12, 0.12, 0.12, 1.0])
    add_optical_camera(mount, layout, pos=names.HEAD_CAMERA_LENS_IN_MOUNT, quat=OPTICAL_IN_BODY_QUAT)
    head = spec.body(names.HEAD_LINK_BODY)
    _remove_point_mass(head, HEAD_CAMERA_MASS_KG, pivot - np.asarray(head.pos, dtype=float), np.diag(inertia))


def build_spec() -> mujoco.MjSpec:
    """The G1 scene as an editable spec (not compiled)."""
    spec = mujoco.MjSpec.from_string(_restore_floating_base(read_urdf(names.URDF_RELATIVE_PATH, keep_visuals=True)))
    spec.modelname = names.ROBOT_NAME
    set_physics_options(spec, timestep_s=PHYSICS_TIMESTEP_S, impratio=IMPRATIO)

    # Replace collision geoms (group 0) with box soles; visuals (group 1) never collide.
    for geom in list(spec.geoms):
        if geom.contype != 0 or geom.conaffinity != 0:
            spec.delete(geom)
        else:
            geom.group = 1
    for foot_body, geom_name, site_name in (
        (names.LEFT_FOOT_BODY, names.LEFT_SOLE_GEOM, names.LEFT_SOLE_SITE),
        (names.RIGHT_FOOT_BODY, names.RIGHT_SOLE_GEOM, names.RIGHT_SOLE_SITE),
    ):
        body = spec.body(foot_body)
        body.add_geom(
            name=geom_name,
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=list(names.SOLE_HALF_SIZE),
            pos=list(names.SOLE_CENTER_IN_FOOT),
            friction=[1.0, 0.02, 0.001],
            condim=3,
            contype=1,
            conaffinity=1,
            group=0,
            rgba=[0.15, 0.15, 0.15, 1.0],
            mass=0.0,
        )
        body.add_site(name=site_name, pos=list(names.SOLE_SITE_IN_FOOT), size=[0.01, 0.01, 0.01])
    spec.body(names.LEFT_HAND_BODY).add_site(name=names.LEFT_HAND_SITE, pos=list(names.HAND_SITE_IN_WRIST), size=[0.01] * 3)
    spec.body(names.RIGHT_HAND_BODY).add_site(name=names.RIGHT_HAND_SITE, pos=list(names.HAND_SITE_IN_WRIST), size=[0.01] * 3)
    spec.body(names.ROOT_BODY).add_site(name=names.IMU_SITE, pos=list(names.IMU_SITE_IN_PELVIS), size=[0.01] * 3)

    _add_body_shell(spec)
    add_sensors(spec, SENSORS)

    world = spec.worldbody
    floor_material = prepare_scene_for_cameras(spec)
    world.add_geom(
        name=names.FLOOR_GEOM, type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05], material=floor_material,
        friction=[1.0, 0.02, 0.001], contype=1, conaffinity=1 | names.SHELL_CONTYPE,
    )
    world.add_light(pos=[0, 0, 4], dir=[0, 0, -1], diffuse=[0.8, 0.8, 0.8])
    world.add_camera(name="track", pos=[2.2, -2.2, 1.4], xyaxes=[0.707, 0.707, 0, -0.25, 0.25, 0.93],
                     mode=mujoco.mjtCamLight.mjCAMLIGHT_TRACKCOM)

    for joint in spec.joints:
        if joint.type == mujoco.mjtJoint.mjJNT_HINGE:
            joint.armature = 0.01
            joint.damping = [0.5, 0.0, 0.0]
    for joint in names.BODY_JOINTS:
        kp, kv = _gain_for(joint)
        add_position_actuator(spec, joint, kp=kp, kv=kv, force_limit=None)
    _add_hands(spec)
    (head_camera,) = CAMERAS
    _add_head_camera(spec, head_camera)  # after the loops above: the mount has armature, damping and gains of its own
    add_position_actuator(spec, names.HEAD_CAMERA_TILT_JOINT, kp=HEAD_CAMERA_TILT_KP, kv=HEAD_CAMERA_TILT_KV,
                          force_limit=HEAD_CAMERA_TILT_FORCE_LIMIT)
    return spec


def _stand_qpos(model: mujoco.MjModel) -> np.ndarray:
    """Crouched stance with both sole sites on the floor, pelvis above the soles' midpoint."""
    data = mujoco.MjData(model)
    qpos = model.qpos0.copy()
    base = model.joint(model.body(names.ROOT_BODY).jntadr[0])
    adr = int(base.qposadr[0])
    qpos[adr : adr + 7] = [0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0]
    for side in ("left", "right"):
        qpos[model.joint(f"{side}_hip_pitch_joint").qposadr[0]] = STAND_HIP_PITCH
        qpos[model.joint(f"{side}_knee_joint").qposadr[0]] = STAND_KNEE
        qpos[model.joint(f"{side}_ankle_pitch_joint").qposadr[0]] = STAND_ANKLE_PITCH
        sign = 1.0 if side == "left" else -1.0
        qpos[model.joint(f"{side}_shoulder_roll_joint").qposadr[0]] = sign * STAND_ARM_POSE["shoulder_roll"]
        qpos[model.joint(f"{side}_elbow_joint").qposadr[0]] = STAND_ARM_POSE["elbow"]
    for joint, angle in names.HAND_OPEN_POSE.items():
        qpos[model.joint(joint).qposadr[0]] = angle
    for camera in CAMERAS:
        if camera.tilt_joint is not None:
            qpos[model.joint(camera.tilt_joint).qposadr[0]] = camera.default_tilt_rad
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    sole_z = min(data.site(names.LEFT_SOLE_SITE).xpos[2], data.site(names.RIGHT_SOLE_SITE).xpos[2])
    qpos[adr + 2] -= sole_z
    return qpos


def _arm_scene(model: mujoco.MjModel) -> ArmScene:
    """The G1's hands are not the arm skills' grippers (yet); its arms must keep away from the pelvis, torso, legs
    and waist."""
    leg_and_waist = names.LEFT_LEG_JOINTS + names.RIGHT_LEG_JOINTS + names.WAIST_JOINTS
    bodies = (names.ROOT_BODY, names.TORSO_BODY, *(model.body(model.jnt_bodyid[model.joint(j).id]).name for j in leg_and_waist))
    # The G1's meshes are visual-only in the physics model (the soles, the shell and the hands' pads collide).
    return ArmScene(obstacle_bodies=bodies, collision_from_joint=3, make_visuals_collide=True)


def load(scene: str = names.DEFAULT_SCENE, visuals: bool = True) -> RobotSpec:
    """Build and compile the G1 scene.

    Args:
        scene: ``"open"`` (empty floor), ``"course"`` (static obstacles to walk around) or ``"tables"``
            (two tables, objects on the first: :mod:`robot_models.g1_tables`).
        visuals: keep the visual meshes (``RobotSpec.visuals``); without them the model is ~0.1 MB, not ~85 MB.

    Raises:
        UnknownSceneError: another scene name.
    """
    if scene not in names.SCENES:
        raise UnknownSceneError(f"unknown scene {scene!r} for {names.ROBOT_NAME}; scenes: {', '.join(names.SCENES)}")
    spec = build_spec()
    obstacles = _add_obstacles(spec) if scene == "course" else ()
    objects: tuple[str, ...] = ()
    if scene == names.TABLES_SCENE:
        obstacles, objects = tables.add_tables_and_objects(spec)
    model = compile_copy(spec, visuals=False)  # kinematics for the keyframe; the spec itself is never compiled
    qpos = _stand_qpos(model)
    ctrl = np.array([qpos[model.joint(j).qposadr[0]] for j in names.ALL_JOINTS])
    spec.add_key(name=names.STAND_KEYFRAME, qpos=qpos.tolist(), ctrl=ctrl.tolist())
    model = compile_copy(spec, visuals)
    return RobotSpec(
        name=names.ROBOT_NAME,
        mjspec=spec,
        model=model,
        joint_groups={
            "left_leg": names.LEFT_LEG_JOINTS,
            "right_leg": names.RIGHT_LEG_JOINTS,
            "waist": names.WAIST_JOINTS,
            "left_arm": names.LEFT_ARM_JOINTS,
            "right_arm": names.RIGHT_ARM_JOINTS,
            "left_hand": names.LEFT_HAND_JOINTS,
            "right_hand": names.RIGHT_HAND_JOINTS,
            "head": names.HEAD_JOINTS,
        },
        actuated_joints=names.ALL_JOINTS,
        end_effector_sites={"left_arm": names.LEFT_HAND_SITE, "right_arm": names.RIGHT_HAND_SITE},
        default_end_effector="right_arm",
        feet_sites=names.FEET_SITES,
        base_body=names.ROOT_BODY,
        floating_base=True,
        keyframes=(names.STAND_KEYFRAME,),
        default_keyframe=names.STAND_KEYFRAME,
        joint_limits=joint_limits_of(model, names.ALL_JOINTS),
        control_decimation=CONTROL_DECIMATION,
        scene=scene,
        objects=objects,
        obstacles=obstacles,
        arm_scene=_arm_scene(model),
        walking=WALKING,
        biped=BIPED,
        sensors=SENSORS,
        cameras=CAMERAS,
        palms=dict(PALM_SITES) if scene == names.TABLES_SCENE else {},  # the pads the tables scene adds
        palm_hand_pose=dict(names.HAND_PALM_POSE) if scene == names.TABLES_SCENE else {},
        hands=dict(HANDS) if scene == names.TABLES_SCENE else {},  # small objects for one hand are in that scene
        visuals=visuals,
    )
