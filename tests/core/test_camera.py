"""Cameras: the G1's head camera on its tilt mount, the Panda's scene camera, intrinsics, exposure.

Rendered for real (EGL, headless): the tilt moves the horizon in the image as the measured tilt says,
the intrinsics put known world points on the pixels where they are drawn, exposure brightens
monotonically and saturates, the scene camera sees the boxes.
"""

from __future__ import annotations

import itertools
import math
import re

import mujoco
import numpy as np
import pytest
from scipy import ndimage

import robot_models
from robot_models import g1 as g1_module, g1_constants as g1_names, panda as panda_module, panda_constants as panda_names
from robot_models.cameras import CameraLayout
from robot_models.spec import example_robot_data_root
from sim_bridge import Simulation
from sim_bridge.camera import CameraRenderer, apply_exposure, exposure_table, intrinsics

WIDTH, HEIGHT = 320, 240
SETTLE_TOLERANCE_RAD = 0.005
SETTLE_DEADLINE_S = 0.5  # of sim time


@pytest.fixture(scope="module")
def g1() -> robot_models.RobotSpec:
    return robot_models.load("g1")


@pytest.fixture(scope="module")
def panda() -> robot_models.RobotSpec:
    return robot_models.load("panda")


def head_camera(robot: robot_models.RobotSpec) -> CameraLayout:
    (camera,) = (c for c in robot.cameras if c.name == g1_names.HEAD_CAMERA)
    return camera


def optical_pose(model: mujoco.MjModel, data: mujoco.MjData, layout: CameraLayout) -> tuple[np.ndarray, np.ndarray]:
    """World position (3,) and rotation (3, 3) (columns: the optical axes) of the camera's optical frame."""
    body = model.body(layout.optical_frame).id
    return data.xpos[body].copy(), data.xmat[body].reshape(3, 3).copy()


def project(points_world: np.ndarray, position: np.ndarray, rotation: np.ndarray, k: tuple[float, ...]) -> np.ndarray:
    """Pixels (n, 2) of world points (n, 3) through the camera matrix K (row-major 3x3)."""
    in_camera = (points_world - position) @ rotation
    uvw = in_camera @ np.array(k).reshape(3, 3).T
    return uvw[:, :2] / uvw[:, 2:]


def floor_mask(image: np.ndarray) -> np.ndarray:
    """Pixels of the grey floor; the sky's blue exceeds its red by >= 0.15 (robot_models.cameras)."""
    return image[..., 2].astype(int) - image[..., 0].astype(int) < 25


def horizon_row(image: np.ndarray) -> int:
    """The first row from the top that is mostly floor."""
    return int(np.argmax(floor_mask(image).mean(axis=1) > 0.5))


def settle_tilt(sim: Simulation, camera: str, target: float) -> float:
    """Step until the measured tilt is within tolerance of ``target``; returns the sim time it took [s]."""
    start = sim.time
    while abs(sim.camera_tilt(camera) - target) > SETTLE_TOLERANCE_RAD:
        assert sim.time - start < SETTLE_DEADLINE_S, (
            f"the tilt mount did not reach {target} rad within {SETTLE_DEADLINE_S} s (at {sim.camera_tilt(camera):.4f})")
        sim.step(1)
    sim.step(round(0.1 / sim.control_timestep))  # let it come to rest
    return sim.time - start


# ----- the models ----------------------------------------------------------------------------------
def test_the_robots_declare_their_cameras(g1, panda):
    assert [c.name for c in g1.cameras] == [g1_names.HEAD_CAMERA]
    assert [c.name for c in panda.cameras] == [panda_names.SCENE_CAMERA]
    assert g1_module.CAMERAS == g1.cameras and panda_module.CAMERAS == panda.cameras, "readable without a model"
    camera = head_camera(g1)
    assert camera.tilt_joint in g1.actuated_joints and g1.joint_groups["head"] == (camera.tilt_joint,)
    low, high = camera.tilt_range_rad
    assert g1.joint_limits[str(camera.tilt_joint)].lower == low and g1.joint_limits[str(camera.tilt_joint)].upper == high
    assert panda.cameras[0].tilt_joint is None
    for robot in (g1, panda):
        assert robot.model.vis.global_.offwidth >= 1280 and robot.model.vis.global_.offheight >= 720


def test_the_tilt_mount_collides_with_nothing_and_weighs_what_the_urdf_says(g1):
    model = g1.model
    mount = model.body(g1_names.HEAD_CAMERA_LINK).id
    subtree = [b for b in range(model.nbody) if b == mount or model.body_parentid[b] == mount]
    geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] in subtree]
    assert geoms and all(model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0 for g in geoms)
    assert 0.0 < model.body_mass[mount] <= 0.1
    # The mount's mass is taken out of the head link: the robot weighs what the URDF's links weigh.
    urdf = (example_robot_data_root() / g1_names.URDF_RELATIVE_PATH).read_text()
    urdf_mass = sum(float(m) for m in re.findall(r'<mass value="([^"]+)"', urdf))
    assert model.body_subtreemass[model.body(g1.base_body).id] == pytest.approx(urdf_mass, abs=1e-9)


@pytest.mark.parametrize("robot_name", ["g1", "panda"])
def test_the_optical_frame_has_ros_optical_axes(robot_name, g1, panda):
    robot = {"g1": g1, "panda": panda}[robot_name]
    model = robot.model
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    for layout in robot.cameras:
        _, optical = optical_pose(model, data, layout)
        mj_camera = data.cam(layout.mj_camera).xmat.reshape(3, 3)
        # MuJoCo's camera looks along its -z with +y up: optical z = -z_cam, y = -y_cam, x = x_cam.
        np.testing.assert_allclose(optical, mj_camera @ np.diag([1.0, -1.0, -1.0]), atol=1e-12)
        np.testing.assert_allclose(data.body(layout.optical_frame).xpos, data.cam(layout.mj_camera).xpos, atol=1e-12)
        assert abs(optical[2, 0]) < 1e-9, "the image's x axis is level"
    if robot_name == "g1":
        _, optical = optical_pose(model, data, head_camera(robot))
        assert optical[:, 2] @ [1.0, 0.0, 0.0] > math.cos(0.02), "at tilt 0 the standing G1 looks straight ahead"
        assert data.body(head_camera(robot).optical_frame).xpos[2] > 1.1, "from head height"


# ----- tilt --------------------------------------------------------------------------------------
def test_tilting_down_raises_the_horizon_by_what_the_measured_tilt_says(g1):
    sim = Simulation(g1)
    camera = head_camera(g1)
    sim.step(round(0.2 / sim.control_timestep))
    with CameraRenderer(sim.model, camera, WIDTH, HEIGHT) as renderer:
        level = renderer.render(sim.data)
        _, level_axes = optical_pose(sim.model, sim.data, camera)
        sim.set_camera_tilt(camera.name, 0.2)
        took = settle_tilt(sim, camera.name, 0.2)
        tilted = renderer.render(sim.data)
        _, tilted_axes = optical_pose(sim.model, sim.data, camera)
        fy = renderer.intrinsics.fy
    assert sim.camera_tilt(camera.name) == pytest.approx(0.2, abs=SETTLE_TOLERANCE_RAD)
    assert took < 0.3, f"the servo settles within 0.3 s (took {took:.3f} s)"
    assert floor_mask(tilted).mean() > floor_mask(level).mean() + 0.2, "more floor in view"
    # The horizon (far floor) lies ~level: it is drawn fy tan(pitch) above the centre of a camera pitched down.
    pitch = [math.asin(-axes[2, 2]) for axes in (level_axes, tilted_axes)]
    assert pitch[1] - pitch[0] == pytest.approx(0.2, abs=0.01)
    predicted_shift = fy * (math.tan(pitch[1]) - math.tan(pitch[0]))
    shift = horizon_row(level) - horizon_row(tilted)
    assert shift == pytest.approx(predicted_shift, abs=3.0), f"horizon rose {shift} px, expected {predicted_shift:.1f}"


def test_the_tilt_survives_a_reset(g1):
    sim = Simulation(g1)
    camera = head_camera(g1).name
    sim.set_camera_tilt(camera, 0.3)
    settle_tilt(sim, camera, 0.3)
    sim.reset()
    assert sim.camera_tilt(camera) == pytest.approx(0.3, abs=1e-12), "a reset puts the mount at the commanded tilt"
    key = sim.model.key(g1.default_keyframe)
    others = np.ones(sim.model.nq, dtype=bool)
    others[sim.model.joint(head_camera(g1).tilt_joint).qposadr[0]] = False
    np.testing.assert_array_equal(sim.data.qpos[others], key.qpos[others])
    sim.step(round(0.5 / sim.control_timestep))
    assert sim.camera_tilt(camera) == pytest.approx(0.3, abs=SETTLE_TOLERANCE_RAD), "and holds it"


def test_an_out_of_range_tilt_or_an_unknown_camera_is_refused_with_what_is_allowed(g1, panda):
    sim = Simulation(g1)
    camera = head_camera(g1)
    low, high = camera.tilt_range_rad
    for bad in (high + 0.1, low - 0.1, math.nan):
        with pytest.raises(ValueError, match=re.escape(f"[{low:g}, {high:g}] rad")):
            sim.set_camera_tilt(camera.name, bad)
    sim.step(10)
    assert sim.camera_tilt(camera.name) == pytest.approx(camera.default_tilt_rad, abs=1e-3), "nothing changed"
    with pytest.raises(ValueError, match="cameras of g1 with a tilt mount: head_camera"):
        sim.set_camera_tilt("tail_camera", 0.1)
    with pytest.raises(ValueError, match="is fixed"):
        Simulation(panda).set_camera_tilt(panda_names.SCENE_CAMERA, 0.1)


# ----- intrinsics --------------------------------------------------------------------------------
def test_intrinsics_follow_the_vertical_field_of_view_with_square_pixels(g1):
    camera = head_camera(g1)
    k = intrinsics(camera, 640, 480)
    assert k.fy == pytest.approx(240.0 / math.tan(math.radians(camera.fovy_deg) / 2.0))
    assert k.fx == k.fy and (k.cx, k.cy) == (319.5, 239.5)
    assert k.k() == (k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0)
    assert k.p() == (k.fx, 0.0, k.cx, 0.0, 0.0, k.fy, k.cy, 0.0, 0.0, 0.0, 1.0, 0.0)


MARKER_OFFSETS = ((0.0, 0.0), (-0.7, -0.5), (0.65, -0.45), (-0.6, 0.5), (0.75, 0.55), (0.1, 0.3))  # of the half width, height


@pytest.mark.parametrize(("robot_name", "width", "height", "depth"),
                         [("g1", 640, 480, 2.0), ("g1", 1280, 720, 2.0), ("panda", 320, 240, 0.8)])
def test_intrinsics_put_world_points_where_they_are_drawn(robot_name, width, height, depth, g1, panda):
    """Small red spheres at known world points are drawn where K and the optical frame's pose project them."""
    robot = {"g1": g1, "panda": panda}[robot_name]
    layout = robot.cameras[0]
    model, data = robot.model, mujoco.MjData(robot.model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    position, rotation = optical_pose(model, data, layout)
    half_height = math.tan(math.radians(layout.fovy_deg) / 2.0)  # of the view at unit depth
    half_width = half_height * width / height
    points = np.array([position + rotation @ (depth * np.array([x * half_width, y * half_height, 1.0]))
                       for x, y in MARKER_OFFSETS])
    radius = 4.0 * depth * 2.0 * half_height / height  # about 4 px
    spec = robot.mjspec.copy()
    spec.compiler.discardvisual = False  # keep the markers, which collide with nothing
    spec.add_material(name="marker", emission=1.0, specular=0.0, rgba=[1.0, 0.0, 0.0, 1.0])
    for i, point in enumerate(points):
        spec.worldbody.add_geom(name=f"marker_{i}", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[radius, 0, 0],
                                pos=point.tolist(), material="marker", contype=0, conaffinity=0)
    marked = spec.compile()
    marked_data = mujoco.MjData(marked)
    marked_data.qpos[:] = data.qpos
    with CameraRenderer(marked, layout, width, height) as renderer:
        image = renderer.render(marked_data)
        k = renderer.intrinsics
    expected = project(points, position, rotation, k.k())
    red = (image[..., 0] > 150) & (image[..., 1] < 90) & (image[..., 2] < 90)
    labels, count = ndimage.label(red)
    assert count >= len(points), f"{count} markers seen of {len(points)}"
    weights = image[..., 0].astype(float) * red
    centroids = np.array(ndimage.center_of_mass(weights, labels, range(1, count + 1)))[:, ::-1]  # (u, v)
    for point, pixel in zip(points, expected, strict=True):
        assert 0 <= pixel[0] < width and 0 <= pixel[1] < height, f"marker {point} projects outside the image"
        error = np.linalg.norm(centroids - pixel, axis=1).min()
        assert error < 0.5, f"marker projected at {pixel.round(2)} is drawn {error:.2f} px away"


# ----- rendering ---------------------------------------------------------------------------------
def test_render_returns_rgb_and_leaves_the_simulation_untouched(g1):
    sim = Simulation(g1)
    sim.step(25)
    before = {name: getattr(sim.data, name).copy() for name in ("qpos", "qvel", "qacc", "ctrl", "xpos", "act")}
    time = sim.time
    with CameraRenderer(sim.model, head_camera(g1), WIDTH, HEIGHT) as renderer:
        image = renderer.render(sim.data)
        with pytest.raises(ValueError, match="positive"):
            renderer.render(sim.data, exposure_gain=0.0)
    assert image.shape == (HEIGHT, WIDTH, 3) and image.dtype == np.uint8 and image.flags.c_contiguous
    assert sim.time == time
    for name, value in before.items():
        np.testing.assert_array_equal(getattr(sim.data, name), value, err_msg=name)
    with pytest.raises(RuntimeError, match="closed"):
        renderer.render(sim.data)
    with pytest.raises(ValueError, match="offscreen buffer"):
        CameraRenderer(sim.model, head_camera(g1), 1920, 1080)


def test_the_scene_camera_sees_the_boxes(panda):
    model = panda.model
    layout = panda.cameras[0]
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    position, rotation = optical_pose(model, data, layout)
    with CameraRenderer(model, layout, 640, 480) as renderer:
        with_boxes = renderer.render(data).astype(int)
        centres = project(np.array([data.body(name).xpos for name in panda_names.BOX_NAMES]), position, rotation,
                          renderer.intrinsics.k())
        away = data.qpos.copy()
        for name in panda_names.BOX_NAMES:
            away[model.joint(name).qposadr[0] + 2] = -5.0  # under the floor
        data.qpos[:] = away
        without_boxes = renderer.render(data).astype(int)
    for name, colour, (u, v) in zip(panda_names.BOX_NAMES, panda_names.BOX_COLORS, centres, strict=True):
        assert 0 <= u < 640 and 0 <= v < 480, f"{name} is in view"
        pixel, background = with_boxes[round(v), round(u)], without_boxes[round(v), round(u)]
        assert np.abs(pixel - background).sum() > 60, f"{name}: {pixel} against the table's {background}"
        strongest = int(np.argmax(colour[:3]))
        assert int(np.argmax(pixel)) == strongest, f"{name} looks {pixel}, its colour is {colour}"


# ----- exposure ----------------------------------------------------------------------------------
def test_exposure_brightens_monotonically_and_saturates(g1):
    sim = Simulation(g1)
    with CameraRenderer(sim.model, head_camera(g1), WIDTH, HEIGHT) as renderer:
        image = renderer.render(sim.data)
        np.testing.assert_array_equal(renderer.render(sim.data, exposure_gain=2.0), apply_exposure(image, 2.0))
    assert apply_exposure(image, 1.0) is image, "gain 1 is the image as rendered"
    gains = (0.25, 0.5, 1.0, 1.5, 2.0, 4.0, 8.0, 100.0)
    means = [float(apply_exposure(image, gain).mean()) for gain in gains]
    assert all(a < b for a, b in itertools.pairwise(means)), f"mean intensity by gain: {means}"
    assert 20.0 < means[gains.index(1.0)] < 200.0, "the rendered image is neither dark nor washed out"
    saturated = apply_exposure(image, 100.0)
    assert np.mean(saturated == 255) > 0.95 and means[-1] > 250.0, "a long exposure saturates at white"


def test_exposure_is_the_gamma_curve_of_a_light_gain():
    table = exposure_table(2.0)
    assert table[0] == 0 and table[255] == 255
    assert np.all(np.diff(table.astype(int)) >= 0)
    assert table[128] == round(255 * min(1.0, 2.0 * (128 / 255) ** 2.2) ** (1 / 2.2))
    np.testing.assert_array_equal(exposure_table(1.0), np.arange(256))
    assert not table.flags.writeable
    for bad in (0.0, -1.0, math.inf, math.nan):
        with pytest.raises(ValueError, match="positive finite"):
            apply_exposure(np.zeros((2, 2, 3), np.uint8), bad)
    with pytest.raises(ValueError, match="uint8"):
        apply_exposure(np.zeros((2, 2, 3), np.float32), 2.0)

