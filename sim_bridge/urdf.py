"""The robot as simulated, written as URDF: what ``/robot_description`` carries for RViz and Foxglove.

One link per body of the robot's tree (the base and every body below it: each has a /tf frame, see
``nodes/sim/tf.py``), one joint per child body: revolute or continuous for a hinge, prismatic for a
slide, fixed for a body without a joint. Joint origins are the bodies' poses in their parents as
compiled (fixed links the build fused away are gone, added ones such as the head camera's mount are
there), axes and limits as simulated. The free objects and the scene's static parts are not the
robot's and are left out.

Visuals are the geoms a viewer shows (groups 0 to 2: meshes, sole boxes, finger pads, the camera
housing; not the invisible body shell). A mesh is named by its file (``file://`` + absolute path,
resolvable on this machine) in the file's own frame: MuJoCo moves a mesh's vertices to its centre of
mass and principal axes (``mesh_pos``, ``mesh_quat``) and the geom's pose the other way, so the
visual origin undoes that move. Capsules, which URDF lacks, are drawn as cylinders of the same length
between the cap centres.

URDF limits have a velocity the simulation does not model: written as 0 ("not given").
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import mujoco
import numpy as np

from robot_models import RobotSpec

VISIBLE_GROUPS = (0, 1, 2)  # geom groups a viewer shows by default (MuJoCo's viewer does too)


def _rpy(quat_wxyz: np.ndarray) -> tuple[float, float, float]:
    """Roll, pitch, yaw [rad] (URDF's fixed-axis x-y-z) of a unit quaternion (w, x, y, z)."""
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, np.asarray(quat_wxyz, dtype=float))
    r = mat.reshape(3, 3)
    pitch = math.asin(max(-1.0, min(1.0, -r[2, 0])))
    if abs(r[2, 0]) < 1.0 - 1e-9:
        roll = math.atan2(r[2, 1], r[2, 2])
        yaw = math.atan2(r[1, 0], r[0, 0])
    else:  # gimbal lock: yaw carries the whole turn about z
        roll = 0.0
        yaw = math.atan2(-r[0, 1], r[1, 1])
    return roll, pitch, yaw


def _origin(parent: ET.Element, pos: np.ndarray, quat_wxyz: np.ndarray) -> None:
    roll, pitch, yaw = _rpy(quat_wxyz)
    ET.SubElement(parent, "origin", xyz=" ".join(f"{v:.9g}" for v in pos),
                  rpy=f"{roll:.9g} {pitch:.9g} {yaw:.9g}")


def robot_bodies(model: mujoco.MjModel, robot: RobotSpec) -> list[int]:
    """Ids of the robot's bodies: its base and every body below it, free objects excluded, in model order."""
    base = model.body(robot.base_body).id
    objects = {model.body(name).id for name in robot.objects}
    inside = {base}
    for body in range(base + 1, model.nbody):  # a parent always comes before its children
        if int(model.body_parentid[body]) in inside and body not in objects:
            inside.add(body)
    return sorted(inside)


def _visual(link: ET.Element, model: mujoco.MjModel, spec: mujoco.MjSpec, geom: int) -> None:
    kind = int(model.geom_type[geom])
    pos = np.array(model.geom_pos[geom], dtype=float)
    quat = np.array(model.geom_quat[geom], dtype=float)
    size = model.geom_size[geom]
    shape: dict[str, str]
    if kind == mujoco.mjtGeom.mjGEOM_MESH:
        mesh_id = int(model.geom_dataid[geom])
        mesh = spec.mesh(model.mesh(mesh_id).name)
        if mesh is None or not mesh.file:
            return
        # vertices as compiled = R(mesh_quat)^T (file vertices - mesh_pos): undo it in the origin
        mesh_rot = np.zeros(9)
        mujoco.mju_quat2Mat(mesh_rot, model.mesh_quat[mesh_id])
        geom_rot = np.zeros(9)
        mujoco.mju_quat2Mat(geom_rot, quat)
        rot = geom_rot.reshape(3, 3) @ mesh_rot.reshape(3, 3).T
        pos = pos - rot @ np.asarray(model.mesh_pos[mesh_id], dtype=float)
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, rot.ravel())
        path = mesh.file if mesh.file.startswith("/") else f"{spec.meshdir.rstrip('/')}/{mesh.file}"
        shape = {"tag": "mesh", "filename": f"file://{path}", "scale": " ".join(f"{v:.9g}" for v in mesh.scale)}
    elif kind == mujoco.mjtGeom.mjGEOM_BOX:
        shape = {"tag": "box", "size": " ".join(f"{2 * v:.9g}" for v in size)}
    elif kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        shape = {"tag": "sphere", "radius": f"{size[0]:.9g}"}
    elif kind in (mujoco.mjtGeom.mjGEOM_CYLINDER, mujoco.mjtGeom.mjGEOM_CAPSULE):
        shape = {"tag": "cylinder", "radius": f"{size[0]:.9g}", "length": f"{2 * size[1]:.9g}"}
    else:
        return
    visual = ET.SubElement(link, "visual", name=model.geom(geom).name or f"geom_{geom}")
    _origin(visual, pos, quat)
    tag = shape.pop("tag")
    ET.SubElement(ET.SubElement(visual, "geometry"), tag, attrib=shape)
    material = ET.SubElement(visual, "material", name=f"rgba_{geom}")
    ET.SubElement(material, "color", rgba=" ".join(f"{v:.4g}" for v in model.geom_rgba[geom]))


def _joint(robot_xml: ET.Element, model: mujoco.MjModel, body: int) -> None:
    parent = model.body(int(model.body_parentid[body])).name
    child = model.body(body).name
    count = int(model.body_jntnum[body])
    if count > 1:
        raise ValueError(f"body {child!r} has {count} joints; URDF has one joint per link")
    if count == 0:
        joint = ET.SubElement(robot_xml, "joint", name=f"{parent}_to_{child}", type="fixed")
    else:
        jid = int(model.body_jntadr[body])
        kind = int(model.jnt_type[jid])
        if kind == mujoco.mjtJoint.mjJNT_HINGE:
            urdf_type = "revolute" if model.jnt_limited[jid] else "continuous"
        elif kind == mujoco.mjtJoint.mjJNT_SLIDE:
            urdf_type = "prismatic"
        else:
            raise ValueError(f"joint {model.joint(jid).name!r} of body {child!r}: only hinge and slide joints go to URDF")
        if np.any(np.abs(model.jnt_pos[jid]) > 1e-9):
            raise ValueError(f"joint {model.joint(jid).name!r} is not at its body's origin; URDF puts it there")
        joint = ET.SubElement(robot_xml, "joint", name=model.joint(jid).name, type=urdf_type)
    ET.SubElement(joint, "parent", link=parent)
    ET.SubElement(joint, "child", link=child)
    _origin(joint, np.asarray(model.body_pos[body], dtype=float), np.asarray(model.body_quat[body], dtype=float))
    if count:
        jid = int(model.body_jntadr[body])
        ET.SubElement(joint, "axis", xyz=" ".join(f"{v:.9g}" for v in model.jnt_axis[jid]))
        if model.jnt_limited[jid]:
            low, high = (float(v) for v in model.jnt_range[jid])
            effort = float(np.max(np.abs(model.jnt_actfrcrange[jid]))) if model.jnt_actfrclimited[jid] else 0.0
            ET.SubElement(joint, "limit", lower=f"{low:.9g}", upper=f"{high:.9g}", effort=f"{effort:.9g}", velocity="0")


def robot_urdf(model: mujoco.MjModel, robot: RobotSpec) -> str:
    """The URDF of ``robot`` as compiled in ``model`` (its RobotSpec's ``mjspec`` names the mesh files)."""
    root = ET.Element("robot", name=robot.name)
    for body in robot_bodies(model, robot):
        link = ET.SubElement(root, "link", name=model.body(body).name)
        inertial = ET.SubElement(link, "inertial")
        _origin(inertial, np.asarray(model.body_ipos[body], dtype=float), np.asarray(model.body_iquat[body], dtype=float))
        ET.SubElement(inertial, "mass", value=f"{float(model.body_mass[body]):.9g}")
        ixx, iyy, izz = (float(v) for v in model.body_inertia[body])
        ET.SubElement(inertial, "inertia", ixx=f"{ixx:.9g}", ixy="0", ixz="0", iyy=f"{iyy:.9g}", iyz="0", izz=f"{izz:.9g}")
        for geom in range(int(model.body_geomadr[body]), int(model.body_geomadr[body] + model.body_geomnum[body])):
            if int(model.geom_group[geom]) in VISIBLE_GROUPS:
                _visual(link, model, robot.mjspec, geom)
        if body != model.body(robot.base_body).id:
            _joint(root, model, body)
    ET.indent(root)
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
