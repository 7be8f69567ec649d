"""The meshes a video draws: far fewer triangles, the same shapes in the same places (to within a few mm)."""

from __future__ import annotations

import pathlib

import mujoco
import numpy as np

import robot_models
from sim_client.scenario.outputs.light_meshes import RENDER_MESH_CELL_M, cluster, lighten_meshes, read_binary_stl
from sim_client.scenario.outputs.render import render_spec


def _sphere(subdivisions: int) -> np.ndarray:
    """A unit icosphere's triangles (m, 3, 3), outward winding."""
    t = (1.0 + 5 ** 0.5) / 2.0
    points = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
              (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6),
             (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
             (8, 6, 7), (9, 8, 1)]
    triangles = np.array([[points[i] for i in face] for face in faces], dtype=float)
    for _ in range(subdivisions):
        a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
        ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
        triangles = np.concatenate([np.stack(t, axis=1) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
    return triangles / np.linalg.norm(triangles, axis=2, keepdims=True)


def _write_stl(path: pathlib.Path, triangles: np.ndarray) -> None:
    record = np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attribute", "<u2")])
    records = np.zeros(len(triangles), dtype=record)
    records["corners"] = triangles
    path.write_bytes(b"\0" * 80 + len(triangles).to_bytes(4, "little") + records.tobytes())


def test_a_binary_stl_reads_back_and_an_ascii_one_is_left_alone(tmp_path):
    sphere = _sphere(2)
    _write_stl(tmp_path / "sphere.stl", sphere)
    assert np.allclose(read_binary_stl(tmp_path / "sphere.stl"), sphere, atol=1e-6)
    (tmp_path / "ascii.stl").write_text("solid x\nendsolid x\n")
    assert read_binary_stl(tmp_path / "ascii.stl") is None


def test_clustering_keeps_the_shape_within_a_cell_and_drops_what_collapsed():
    sphere = _sphere(5) * 0.05  # 20k triangles on a 5 cm sphere
    vertices, faces = cluster(sphere, 0.005)
    assert len(faces) < len(sphere) / 5  # 3k of 20k
    radii = np.linalg.norm(vertices, axis=1)
    assert np.all(np.abs(radii - 0.05) < 0.005), (radii.min(), radii.max())
    assert np.all((faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2]))
    assert len({tuple(sorted(face)) for face in faces.tolist()}) == len(faces)
    corners = vertices[faces]  # winding kept: normals point outwards
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    assert np.mean(np.einsum("ij,ij->i", normals, corners.mean(axis=1)) > 0) > 0.99


def _mesh_boxes(model: mujoco.MjModel) -> dict[str, np.ndarray]:
    """Every mesh geom's world bounding box (min and max corner) at the default keyframe."""
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    boxes = {}
    for geom in range(model.ngeom):
        mesh = int(model.geom_dataid[geom])
        if model.geom_type[geom] != mujoco.mjtGeom.mjGEOM_MESH or mesh < 0:
            continue
        start, count = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
        world = model.mesh_vert[start:start + count] @ data.geom_xmat[geom].reshape(3, 3).T + data.geom_xpos[geom]
        boxes[f"{geom}:{model.geom(geom).name}"] = np.stack([world.min(axis=0), world.max(axis=0)])
    return boxes


def test_the_g1_in_a_video_has_a_sixth_of_its_triangles_and_every_part_where_it_was():
    robot = robot_models.load(robot_models.G1, "tables")
    full_meshes = {mesh.name: mesh.file for mesh in robot.mjspec.meshes}
    assert all(full_meshes.values())
    light = render_spec(robot)  # simplified by render_spec itself
    assert all(not mesh.file for mesh in light.meshes if full_meshes[mesh.name].lower().endswith(".stl"))
    full_model = robot_models.load(robot_models.G1, "tables").model
    light_model = light.compile()
    assert light_model.nmeshface < full_model.nmeshface / 4, (light_model.nmeshface, full_model.nmeshface)
    assert (light_model.nbody, light_model.nq) == (full_model.nbody, full_model.nq)
    before, after = _mesh_boxes(full_model), _mesh_boxes(light_model)
    assert before.keys() == after.keys() and len(before) >= 40
    off = {name: float(np.abs(after[name] - before[name]).max()) for name in before}
    assert max(off.values()) < 2 * RENDER_MESH_CELL_M, sorted(off.items(), key=lambda item: -item[1])[:3]
    assert lighten_meshes(light) == (0, 0)  # already simplified: nothing left to do
