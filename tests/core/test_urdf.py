"""The robot as simulated, written as URDF (/robot_description): parsed back, it is the same robot."""

from __future__ import annotations

import pathlib
import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pytest

import robot_models
from sim_bridge.urdf import robot_bodies, robot_urdf


@pytest.fixture(scope="module", params=robot_models.ROBOT_NAMES)
def robot(request):
    return robot_models.load(request.param)


def test_every_link_is_a_body_of_the_robot_and_every_actuated_joint_is_named(robot):
    model = robot.model
    tree = ET.fromstring(robot_urdf(model, robot))
    links = {link.get("name") for link in tree.iter("link")}
    assert links == {model.body(b).name for b in robot_bodies(model, robot)}
    assert not links & set(robot.objects), "the free objects are not the robot's"
    joints = {joint.get("name") for joint in tree.iter("joint") if joint.get("type") != "fixed"}
    assert set(robot.actuated_joints) <= joints, set(robot.actuated_joints) - joints
    children = [joint.find("child").get("link") for joint in tree.iter("joint")]
    assert len(children) == len(set(children)) == len(links) - 1, "a tree: one parent per link but the root"


def test_every_mesh_it_names_exists(robot):
    tree = ET.fromstring(robot_urdf(robot.model, robot))
    files = [mesh.get("filename") for mesh in tree.iter("mesh")]
    assert files, "the robot is drawn with its meshes"
    for uri in files:
        assert uri.startswith("file:///") and pathlib.Path(uri.removeprefix("file://")).is_file(), uri


def test_parsed_back_by_mujoco_the_links_and_meshes_are_where_the_simulation_has_them(robot):
    """MuJoCo compiles the URDF; at the keyframe's joint angles every link and every mesh sits where it does in the
    simulation (meshes compared by their compiled poses: both sides move a mesh to its centre of mass alike)."""
    model = robot.model
    text = robot_urdf(model, robot).replace("file://", "")
    text = text.replace("</robot>", '<mujoco><compiler fusestatic="false" discardvisual="false"/></mujoco></robot>')
    back = mujoco.MjSpec.from_string(text).compile()
    data, data_back = mujoco.MjData(model), mujoco.MjData(back)
    mujoco.mj_resetDataKeyframe(model, data, model.key(robot.default_keyframe).id)
    mujoco.mj_kinematics(model, data)
    base = model.body(robot.base_body).id
    for j in range(back.njnt):
        name = back.joint(j).name
        data_back.qpos[back.jnt_qposadr[j]] = data.qpos[model.jnt_qposadr[model.joint(name).id]]
    mujoco.mj_kinematics(back, data_back)

    def in_base(d: mujoco.MjData, m: mujoco.MjModel, body: int, root: int) -> tuple[np.ndarray, np.ndarray]:
        rot = d.xmat[root].reshape(3, 3)
        return rot.T @ (d.xpos[body] - d.xpos[root]), rot.T @ d.xmat[body].reshape(3, 3)

    root_back = back.body(robot.base_body).id
    for body in robot_bodies(model, robot):
        name = model.body(body).name
        pos, rot = in_base(data, model, body, base)
        pos_back, rot_back = in_base(data_back, back, back.body(name).id, root_back)
        np.testing.assert_allclose(pos_back, pos, atol=1e-6, err_msg=name)
        np.testing.assert_allclose(rot_back, rot, atol=1e-6, err_msg=name)
    for geom in range(model.ngeom):
        if model.geom_type[geom] != mujoco.mjtGeom.mjGEOM_MESH or model.geom_group[geom] > 2:
            continue
        if int(model.geom_bodyid[geom]) not in robot_bodies(model, robot):
            continue
        mesh = model.mesh(int(model.geom_dataid[geom])).name
        matches = [g for g in range(back.ngeom) if back.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH
                   and back.body(int(back.geom_bodyid[g])).name == model.body(int(model.geom_bodyid[geom])).name
                   and np.allclose(back.geom_size[g], model.geom_size[geom])]
        assert matches, f"mesh {mesh} of {model.body(int(model.geom_bodyid[geom])).name}"
        rot = data.xmat[base].reshape(3, 3)
        expected = rot.T @ (data.geom_xpos[geom] - data.xpos[base])
        rot_back = data_back.xmat[root_back].reshape(3, 3)
        found = [rot_back.T @ (data_back.geom_xpos[g] - data_back.xpos[root_back]) for g in matches]
        assert min(np.linalg.norm(f - expected) for f in found) < 1e-5, f"mesh {mesh} placed as simulated"
