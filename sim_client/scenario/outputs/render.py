"""A run's video, re-rendered from its recorded state so that a person reads it at a glance.

The physics model is never touched: a render-only copy of the robot's scene (its ``MjSpec``) gets a
checkered floor (1 m squares with lines), a sky, even light, a marker at each goal's target and the
planned path on the floor (geoms that collide with nothing), and is posed frame by frame from the
recorded ``/odom``, ``/joint_states`` and ``/objects``. A camera fitted to the robot's path, the
obstacles and the goals keeps them all in view; an overlay says the sim time and what each goal is
doing (:mod:`sim_client.scenario.outputs.overlay`).
"""

from __future__ import annotations

import itertools
import math
import os
import pathlib
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

import robot_models
from robot_models import RobotSpec
from sim_client.scenario.model.series import Series, joint_series, object_series, odom_series
from sim_client.scenario.outputs import goalview, overlay
from sim_client.scenario.outputs.framing import View, box_corners, fit_view
from sim_client.scenario.outputs.goalview import GoalView
from sim_client.scenario.outputs.light_meshes import lighten_meshes

FLOOR_SQUARE_M = 1.0  # side of one floor square [m]
FLOOR_HALF_M = 50.0  # half side of the floor as drawn [m]
GOAL_RGB = ((0.15, 0.75, 0.25), (0.60, 0.35, 0.85), (0.10, 0.70, 0.85), (0.90, 0.40, 0.70))  # by goal number
PLANNED_RGBA = (0.10, 0.75, 0.95, 0.85)
TRACK_ABOVE_M = 10.0  # a run whose course spans more than this [m] is followed by the camera instead of framed
HOLD_END_S = 1.5  # the last frame is held this long [s of video]
# Multisampling of the offscreen buffer (MuJoCo's default is 4). On a CPU renderer (EGL on llvmpipe) 4 samples
# doubled a 640x480 G1 frame (215 against 108 ms); the edges are a little harder without.
VIDEO_MSAA_SAMPLES = 0
MAX_VIDEO_S = 30.0  # a longer run plays faster, to last this long [s of video]: frames cost ~0.1 s each on a CPU


@dataclass(frozen=True)
class RecordedRun:
    """What a video shows of a run: the scene, the recorded state and the goals.

    Attributes:
        name: the scenario's name (first words of the overlay).
        robot: robot name in :mod:`robot_models`.
        scene: the robot's scene (``course``...).
        start: sim time of the video's first frame [s].
        end: sim time of its last frame [s].
        odom: base pose (``series.odom_series``).
        joints: joint names and positions (``series.joint_series``).
        objects: object name -> pose series (``series.object_series``).
        goals: the run's goals (``goalview.goal_views``).
        planned: goal id -> the path NavigateToPose planned from the start, world frame [m].
    """

    name: str
    robot: str
    scene: str
    start: float
    end: float
    odom: Series
    joints: tuple[list[str], Series]
    objects: dict[str, Series]
    goals: tuple[GoalView, ...] = ()
    planned: dict[str, list[tuple[float, float]]] = field(default_factory=dict)


def load_robot(robot: str, scene: str) -> RobotSpec:
    return robot_models.load(robot, scene)


def recorded_run(run: Any, robot: RobotSpec | None = None) -> RecordedRun:
    """The recorded state of a ``ScenarioRun`` (after its end), for :func:`render_video`."""
    scenario = run.scenario
    robot = robot or load_robot(scenario.robot, scenario.scene)
    odom = odom_series(run.odom.messages())
    names = run.objects.latest.names if run.objects.latest else []
    goals = goalview.goal_views(run, odom)
    return RecordedRun(scenario.name, scenario.robot, scenario.scene, run.marks.get("start", 0.0), run.marks.get("end", 0.0),
                       odom, joint_series(run.joints.messages()),
                       {name: object_series(run.objects.messages(), name) for name in names}, goals,
                       goalview.planned_paths(robot, goals, odom, goalview.navigation_inflation(robot, run)))


# ----- the render-only scene ------------------------------------------------------------------
def render_spec(robot: RobotSpec, goals: Sequence[GoalView] = (),
                planned: dict[str, list[tuple[float, float]]] | None = None) -> Any:
    """A copy of the robot's spec dressed for pictures; the robot's own spec is not changed.

    The robot's meshes are simplified to what a video shows (:mod:`~sim_client.scenario.outputs.light_meshes`).
    Floor planes get a checker of ``FLOOR_SQUARE_M`` squares with lines, the lights become even
    directional light, a gradient sky is added, and every goal target and planned path gets
    geoms with ``contype = conaffinity = 0``.
    """
    import mujoco

    spec = robot.mjspec.copy()
    spec.compiler.discardvisual = False  # keep the markers (geoms that collide with nothing) in the compiled model
    lighten_meshes(spec)  # the G1: 76k triangles instead of 461k, drawn in half the time on a CPU renderer
    spec.add_texture(name="render_floor", type=mujoco.mjtTexture.mjTEXTURE_2D, builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
                     width=512, height=512, rgb1=[0.40, 0.44, 0.50], rgb2=[0.30, 0.33, 0.38],
                     mark=mujoco.mjtMark.mjMARK_EDGE, markrgb=[0.85, 0.87, 0.90])
    floor = spec.add_material(name="render_floor", texuniform=True, texrepeat=[0.5 / FLOOR_SQUARE_M] * 2, reflectance=0.0)
    floor.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "render_floor"
    spec.add_texture(name="render_sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX, builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
                     width=256, height=1536, rgb1=[0.62, 0.72, 0.84], rgb2=[0.95, 0.96, 0.98])
    for geom in spec.worldbody.geoms:
        if geom.type == mujoco.mjtGeom.mjGEOM_PLANE:
            geom.material = "render_floor"
            geom.rgba = [1.0, 1.0, 1.0, 1.0]
            if geom.size[0] <= 0.0:  # an infinite plane is drawn as large as the model's extent: a small scene's is small
                geom.size = [FLOOR_HALF_M, FLOOR_HALF_M, geom.size[2]]
    for light in spec.lights:
        light.type = mujoco.mjtLightType.mjLIGHT_DIRECTIONAL
        light.dir = [0.3, 0.4, -1.0]
        light.castshadow = False
    spec.visual.headlight.ambient = [0.35, 0.35, 0.35]
    spec.visual.headlight.diffuse = [0.45, 0.45, 0.45]
    spec.visual.headlight.specular = [0.1, 0.1, 0.1]
    for goal in goals:
        if goal.target is not None:
            _add_goal_marker(spec, robot, goal, goal.target)
    for goal_id, path in (planned or {}).items():
        _add_path(spec, f"render_planned_{goal_id}", path)
    return spec


def _geom(spec: Any, name: str, kind: str, size: Sequence[float], pos: Sequence[float], rgba: Sequence[float],
          yaw: float = 0.0) -> None:
    import mujoco

    geom_type = {"box": mujoco.mjtGeom.mjGEOM_BOX, "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
                 "sphere": mujoco.mjtGeom.mjGEOM_SPHERE}[kind]
    spec.worldbody.add_geom(name=name, type=geom_type, size=list(size), pos=list(pos), rgba=list(rgba), contype=0,
                            conaffinity=0, group=0, quat=[math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])


def _add_goal_marker(spec: Any, robot: RobotSpec, goal: GoalView, target: tuple[float, float, float]) -> None:
    """A disc, a pole with a ball and (with a heading) an arrow on the floor; a plate on the table; a ball in the air."""
    rgb = GOAL_RGB[(goal.number - 1) % len(GOAL_RGB)]
    x, y, z = target
    name = f"render_goal_{goal.number}"
    if goal.action in ("walk", "navigate"):
        _geom(spec, f"{name}_disc", "cylinder", [0.30, 0.004], [x, y, 0.004], [*rgb, 0.55])
        _geom(spec, f"{name}_pole", "cylinder", [0.012, 0.5], [x, y, 0.5], [*rgb, 0.9])
        _geom(spec, f"{name}_ball", "sphere", [0.06], [x, y, 1.0], [*rgb, 0.9])
        if goal.target_yaw is not None:
            yaw = goal.target_yaw
            _geom(spec, f"{name}_heading", "box", [0.2, 0.03, 0.006], [x + 0.2 * math.cos(yaw), y + 0.2 * math.sin(yaw), 0.01],
                  [*rgb, 0.95], yaw)
    elif goal.action == "pick_place":
        carried = spec.body(goal.carried) if goal.carried else None
        if carried is not None and len(carried.geoms):  # the plate in the colour of what goes on it
            red, green, blue = (float(v) for v in carried.geoms[0].rgba[:3])
            rgb = (red, green, blue)
        x, y, z = goalview.on_table(robot, target)
        half = max(robot.arm_scene.object_half_size, 0.01) * 1.6
        _geom(spec, f"{name}_plate", "box", [half, half, 0.0015], [x, y, z + 0.0015], [*rgb, 0.6])
        _geom(spec, f"{name}_pole", "cylinder", [0.003, 0.1], [x, y, z + 0.1], [*rgb, 0.9])
        _geom(spec, f"{name}_ball", "sphere", [0.012], [x, y, z + 0.2], [*rgb, 0.9])
    else:
        _geom(spec, f"{name}_ball", "sphere", [0.025], [x, y, z], [*rgb, 0.5])


def _add_path(spec: Any, name: str, path: Sequence[tuple[float, float]]) -> None:
    for i, (a, b) in enumerate(itertools.pairwise(path)):
        length = math.dist(a, b)
        if length < 1e-3:
            continue
        yaw = math.atan2(b[1] - a[1], b[0] - a[0])
        _geom(spec, f"{name}_{i}", "box", [length / 2, 0.02, 0.002], [(a[0] + b[0]) / 2, (a[1] + b[1]) / 2, 0.004],
              PLANNED_RGBA, yaw)


class VideoRenderer:
    """Renders frames of a recorded run in its render-only scene, with the overlay; use it in a ``with``.

    Args:
        recorded: the run.
        size: (width, height) [px].
        shadows: draw shadows (slower on a CPU renderer).
        robot: the robot's spec, when already loaded.
    """

    def __init__(self, recorded: RecordedRun, size: tuple[int, int] = (640, 480), shadows: bool = False,
                 robot: RobotSpec | None = None) -> None:
        import mujoco

        self._mujoco = mujoco
        self.recorded = recorded
        self.robot = robot or load_robot(recorded.robot, recorded.scene)
        spec = render_spec(self.robot, recorded.goals, recorded.planned)
        width, height = size
        spec.visual.global_.offwidth = max(spec.visual.global_.offwidth, width)
        spec.visual.global_.offheight = max(spec.visual.global_.offheight, height)
        spec.visual.quality.offsamples = VIDEO_MSAA_SAMPLES
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        self._keyframe_qpos = self.data.qpos.copy()
        if self.robot.default_keyframe:
            mujoco.mj_resetDataKeyframe(self.model, self.data, self.model.key(self.robot.default_keyframe).id)
            self._keyframe_qpos = self.data.qpos.copy()
        model = self.model
        names, _ = recorded.joints
        self._joint_adr = [(i, int(model.joint(n).qposadr[0])) for i, n in enumerate(names) if _has_joint(model, n)]
        self._base_adr = -1
        if self.robot.floating_base:
            body = model.body(self.robot.base_body).id
            self._base_adr = int(model.jnt_qposadr[int(model.body_jntadr[body])])
        self._object_adr = {name: int(model.jnt_qposadr[int(model.body_jntadr[model.body(name).id])])
                            for name in recorded.objects if _has_body(model, name)}
        self._shadows = shadows
        self._painter = overlay.TextPainter(max(11, round(height / 34)))
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        self.view = self._choose_view(width / height)
        self._track = self._course_span() > TRACK_ABOVE_M
        self._renderer = mujoco.Renderer(model, height=height, width=width)  # last: nothing after it can fail

    def __enter__(self) -> VideoRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._renderer.close()

    # ----- posing and framing ---------------------------------------------------------------
    def pose(self, t: float) -> None:
        """Set the scene to the recorded state at sim time ``t`` [s]."""
        data, recorded = self.data, self.recorded
        data.qpos[:] = self._keyframe_qpos
        row = recorded.joints[1].at(t)
        if row is not None:
            for i, adr in self._joint_adr:
                data.qpos[adr] = row[i]
        if self._base_adr >= 0:
            pose = recorded.odom.at(t)
            if pose is not None:
                data.qpos[self._base_adr:self._base_adr + 3] = pose[0:3]
                data.qpos[self._base_adr + 3:self._base_adr + 7] = pose[4:8]
        for name, adr in self._object_adr.items():
            pose = recorded.objects[name].at(t)
            if pose is not None:
                data.qpos[adr:adr + 7] = pose[0:7]
        self._mujoco.mj_forward(self.model, data)

    def _base_xy(self) -> np.ndarray:
        if self._base_adr >= 0:
            return np.array(self.data.qpos[self._base_adr:self._base_adr + 2])
        return np.array(self.data.xpos[self.model.body(self.robot.base_body).id][:2])

    def _course(self) -> np.ndarray:
        """Base positions (n, 2) [m] over the video (at least the one at the start)."""
        odom = self.recorded.odom.window(self.recorded.start, self.recorded.end)
        if len(odom.t) and self._base_adr >= 0:
            return np.array(odom.values[:: max(1, len(odom.t) // 200), 0:2])
        self.pose(self.recorded.start)
        return self._base_xy()[None, :]

    def _course_span(self) -> float:
        course = self._course()
        targets = [g.target[:2] for g in self.recorded.goals if g.target is not None]
        points = np.vstack([course, *(np.array([t]) for t in targets)])
        return float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))

    def _points_to_frame(self) -> np.ndarray:
        """Points (n, 3) [m] the picture must hold: the robot along its course, obstacles, objects, goals, planned paths."""
        self.pose(self.recorded.start)
        body_xyz = np.array(self.data.xpos[1:])
        base = np.append(self._base_xy(), 0.0)
        relative = body_xyz - base
        reach = float(np.max(np.linalg.norm(relative[:, :2], axis=1))) + 0.1
        top = float(np.max(body_xyz[:, 2])) + 0.1
        points: list[list[float]] = []
        if self._base_adr >= 0:
            for x, y in self._course():
                points += box_corners((x, y), (reach, reach), 0.0, top)
        else:
            points += [list(p) for p in body_xyz]
        for obstacle in self.robot.obstacles:
            points += box_corners(obstacle.center_xy, obstacle.half_size_xy, 0.0, obstacle.height, obstacle.yaw)
        for series in self.recorded.objects.values():
            if len(series.values):
                points += [list(series.values[0, 0:3]), list(series.values[-1, 0:3])]
        for goal in self.recorded.goals:
            if goal.target is not None:
                x, y, z = goal.target
                points += [[x, y, z], [x, y, z + (1.0 if goal.action in ("walk", "navigate") else 0.2)]]
        for path in self.recorded.planned.values():
            points += [[x, y, 0.0] for x, y in path]
        return np.array(points, dtype=float)

    def _azimuth(self) -> float:
        """Look across the course from the side it bends to (so the robot stays in front of what it avoids)."""
        self.pose(self.recorded.start)
        start = self._base_xy()
        course = self._course()
        ends = [np.array(g.target[:2]) for g in self.recorded.goals if g.target is not None and g.action in ("walk", "navigate")]
        end = ends[-1] if ends else course[-1]
        travel = end - start
        if self._base_adr < 0 or float(np.linalg.norm(travel)) < 0.5:
            pose = self.recorded.odom.at(self.recorded.start)
            yaw = float(pose[3]) if pose is not None and self._base_adr >= 0 else 0.0
            return math.degrees(yaw) + 145.0  # from the robot's front right
        heading = math.atan2(travel[1], travel[0])
        unit = travel / np.linalg.norm(travel)
        bends = np.vstack([course, *(np.array(p) for p in self.recorded.planned.values())]) - start
        side = float(np.mean(unit[0] * bends[:, 1] - unit[1] * bends[:, 0]))
        return math.degrees(heading) + (-60.0 if side > 0.05 else 60.0)

    def _choose_view(self, aspect: float) -> View:
        return fit_view(self._points_to_frame(), float(self.model.vis.global_.fovy), aspect, self._azimuth())

    def view_at(self, t: float) -> View:
        """The camera at sim time ``t`` [s]: the fitted view; on a long course, following the base
        (smoothed over 2 s) from the fitted view's direction, 7 m away."""
        if not self._track:
            return self.view
        odom = self.recorded.odom.window(t - 1.0, t + 1.0)
        x, y = (odom.values[:, 0:2].mean(axis=0) if len(odom.t) else self._base_xy())
        return View((float(x), float(y), 0.6), 7.0, self.view.azimuth, self.view.elevation)

    # ----- frames ---------------------------------------------------------------------------
    def frame(self, t: float, with_overlay: bool = True) -> np.ndarray:
        """The picture at sim time ``t`` [s]: RGB, uint8, (height, width, 3)."""
        mujoco = self._mujoco
        view = self.view_at(t)
        self.pose(t)
        camera = self._camera
        camera.lookat[:] = view.lookat
        camera.distance, camera.azimuth, camera.elevation = view.distance, view.azimuth, view.elevation
        self._renderer.update_scene(self.data, camera=camera)
        if not self._shadows:
            self._renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0
            self._renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = 0
        picture = np.array(self._renderer.render())
        if with_overlay:
            recorded = self.recorded
            self._painter.draw(picture, overlay.overlay_lines(recorded.name, t, recorded.start, recorded.goals))
            note = [overlay.Line(f"floor squares {FLOOR_SQUARE_M:g} m", overlay.GREY)]
            if recorded.planned:
                note.append(overlay.Line("cyan line: planned path", overlay.GREY))
            self._painter.draw(picture, note, corner="bottom-right")
        return picture


def playback_speed(sim_s: float) -> float:
    """Sim seconds per video second for a run of ``sim_s`` [s]: real time, or faster to last ``MAX_VIDEO_S``."""
    return max(1.0, sim_s / MAX_VIDEO_S)


def render_video(recorded: RecordedRun, path: pathlib.Path, fps: int = 20, size: tuple[int, int] = (640, 480),
                 speed: float | None = None, shadows: bool = False, robot: RobotSpec | None = None,
                 workers: int | None = None) -> int:
    """Render the run from ``recorded.start`` to ``recorded.end`` into an MP4; returns the number of frames.

    Headless rendering may run on the CPU, where shadows and reflections cost most of a frame: they are
    off by default. The frames are rendered by ``workers`` processes at once (default: ``VIDEO_WORKERS``), each a
    stretch of the video encoded on its own; the stretches are joined without re-encoding.

    Args:
        fps: frames per video second.
        speed: sim seconds per video second (None: :func:`playback_speed`); a sped-up video says so in its title.
        workers: processes rendering at once (1: this one alone).
    """
    if speed is None:
        speed = playback_speed(recorded.end - recorded.start)
    if speed != 1.0:
        recorded = replace(recorded, name=f"{recorded.name} ({speed:.1f}x)")
    frames = max(1, int((recorded.end - recorded.start) / speed * fps))
    # ... and the last frame at the end exactly (how the goals ended)
    times = [t for t in (recorded.start + k * speed / fps for k in range(frames)) if t < recorded.end - 1e-6] + [recorded.end]
    hold = round(HOLD_END_S * fps)  # the end, still, long enough to read how it went
    workers = VIDEO_WORKERS if workers is None else max(1, workers)
    if workers == 1 or len(times) < workers * MIN_FRAMES_PER_WORKER:
        return render_frames(recorded, path, times, hold, fps, size, shadows, robot)
    # This process starts on its stretch at once, the others after their start-up: it takes that many frames more.
    share = (len(times) + (workers - 1) * STARTUP_FRAMES) / workers
    bounds = [0, *(min(len(times), round(share + (i - 1) * (share - STARTUP_FRAMES))) for i in range(1, workers)), len(times)]
    stretches = [times[a:b] for a, b in itertools.pairwise(bounds)]
    parts = [path.with_name(f".{path.stem}.part{i}{path.suffix}") for i in range(workers)]
    from sim_client.scenario.outputs.video_stretches import RenderProcess, join

    others = []
    try:
        for i in range(1, workers):
            args = (recorded, parts[i], stretches[i], hold if i == workers - 1 else 0, fps, size, shadows)
            others.append(RenderProcess(render_frames, args, path.with_name(f".{path.stem}.part{i}.job")))
        count = render_frames(recorded, parts[0], stretches[0], 0, fps, size, shadows, robot)
        count += sum(other.result() for other in others)
        join(parts, path)
    finally:
        for other in others:
            other.close()
        for part in parts:
            part.unlink(missing_ok=True)
    return count


VIDEO_WORKERS = min(2, os.cpu_count() or 1)  # processes rendering a video's frames at once (the CPU renders them)
MIN_FRAMES_PER_WORKER = 60  # a shorter stretch is not worth a process of its own
STARTUP_FRAMES = 50  # frames rendered in the time a rendering process takes to start (~1 s: imports, the scene)


def render_frames(recorded: RecordedRun, path: pathlib.Path, times: Sequence[float], hold: int, fps: int,
                  size: tuple[int, int], shadows: bool = False, robot: RobotSpec | None = None) -> int:
    """Render the frames at sim ``times`` [s] into the MP4 ``path``, the last one held ``hold`` more frames; returns
    the number of frames written."""
    import imageio_ffmpeg

    width, height = size
    writer = imageio_ffmpeg.write_frames(str(path), (width, height), fps=fps, codec="libx264", pix_fmt_out="yuv420p",
                                         macro_block_size=16, output_params=["-preset", "veryfast", "-crf", "26"])
    writer.send(None)
    count = 0
    try:
        with VideoRenderer(recorded, size, shadows, robot) as renderer:
            for t in times:
                picture = np.ascontiguousarray(renderer.frame(t))
                writer.send(picture)
                count += 1
            for _ in range(hold):
                writer.send(picture)
                count += 1
    finally:
        writer.close()
    return count


def _has_joint(model: Any, name: str) -> bool:
    try:
        model.joint(name)
    except KeyError:
        return False
    return True


def _has_body(model: Any, name: str) -> bool:
    try:
        model.body(name)
    except KeyError:
        return False
    return True
