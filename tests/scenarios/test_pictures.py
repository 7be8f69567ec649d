"""Pictures a person reads at a glance: the video's floor grid, obstacles, goal marker and overlay; the plots' obstacles,
planned path and goal marks. Rendered headless (MUJOCO_GL=egl or osmesa) from a G1 course scene."""

from __future__ import annotations

import io
import json
import pathlib
import textwrap

import mujoco
import numpy as np
import pytest

import robot_models
from sim_client.scenario.model import schema
from sim_client.scenario.model.series import Series
from sim_client.scenario.outputs import goalview, overlay, plots, render
from sim_client.scenario.outputs.goalview import GoalView
from sim_client.scenario.running.options import RunOptions
from sim_client.scenario.running.runner import run

SIZE = (480, 360)


@pytest.fixture(scope="module")
def course() -> robot_models.RobotSpec:
    return robot_models.load("g1", "course")


def walking_odom() -> Series:
    """The base walking from the origin towards the wall's left end (x, y, z, yaw, qw, qx, qy, qz)."""
    t = np.linspace(0.0, 4.0, 41)
    x, y = 0.25 * t, 0.3 * t
    yaw = np.full_like(t, np.arctan2(0.3, 0.25))
    rows = np.column_stack([x, y, np.full_like(t, 0.76), yaw, np.cos(yaw / 2), 0 * t, 0 * t, np.sin(yaw / 2)])
    return Series(t, rows)


def navigate_goal(done: float | None = 9.0, status: str = "SUCCEEDED") -> GoalView:
    return GoalView("nav", "navigate", 1, 0.0, done, status if done is not None else "", "SUCCESS" if done else "",
                    (3.0, 0.0, 0.0), 0.0, ((0.1, "4.2 m left"), (3.0, "2.9 m left")))


class NavigationDefaults:
    """A run as the pictures read the navigation node's parameters: the /locomotion node's defaults."""

    def parameter(self, node: str, name: str) -> float:
        assert node == goalview.NAVIGATION_NODE
        return {"robot_radius": 0.30, "obstacle_detection_threshold": 0.15}[name]


def recorded(course: robot_models.RobotSpec, goal: GoalView) -> render.RecordedRun:
    odom = walking_odom()
    planned = goalview.planned_paths(course, [goal], odom, goalview.navigation_inflation(course, NavigationDefaults()))
    return render.RecordedRun("course_walk", "g1", "course", 0.0, 4.0, odom, ([], Series(np.zeros(0), np.zeros((0, 0)))),
                              {}, (goal,), planned)


def edge_fraction(picture: np.ndarray) -> float:
    """Share of pixels in the lower third where the brightness jumps (grid lines, checker edges)."""
    grey = picture[2 * picture.shape[0] // 3:].astype(float).mean(axis=2)
    jumps = np.maximum(np.abs(np.diff(grey, axis=0))[:, :-1], np.abs(np.diff(grey, axis=1))[:-1, :])
    return float(np.mean(jumps > 6.0))


def obstacle_pixels(picture: np.ndarray) -> int:
    """Pixels of the course's orange obstacles (rgba 0.8, 0.55, 0.2, lit)."""
    r, g, b = (picture[..., k].astype(int) for k in range(3))
    return int(np.sum((r > 140) & (g > 70) & (g < 0.85 * r) & (b < 0.5 * r)))


def test_a_frame_shows_the_floor_grid_the_obstacles_the_goal_and_the_overlay(course):
    goal = navigate_goal()
    with render.VideoRenderer(recorded(course, goal), SIZE, robot=course) as renderer:
        picture = renderer.frame(2.0)
        bare = renderer.frame(2.0, with_overlay=False)
        # The same view of the physics model with its textures off (a flat floor: the model's own floor has a
        # checker for the robot's cameras) fails the floor check.
        camera = mujoco.MjvCamera()
        camera.lookat[:], camera.distance = renderer.view.lookat, renderer.view.distance
        camera.azimuth, camera.elevation = renderer.view.azimuth, renderer.view.elevation
        with mujoco.Renderer(course.model, height=SIZE[1], width=SIZE[0]) as plain:
            data = mujoco.MjData(course.model)
            data.qpos[:] = renderer.data.qpos  # the render-only copy adds no joints: the same pose
            mujoco.mj_forward(course.model, data)
            untextured = mujoco.MjvOption()
            untextured.flags[mujoco.mjtVisFlag.mjVIS_TEXTURE] = False
            plain.update_scene(data, camera=camera, scene_option=untextured)
            flat = plain.render()
    assert picture.shape == (SIZE[1], SIZE[0], 3)
    assert edge_fraction(bare) > 0.04, f"the floor looks uniform: {edge_fraction(bare):.4f}"
    assert edge_fraction(flat) < 0.04, f"the check does not tell a flat floor: {edge_fraction(flat):.4f}"
    assert obstacle_pixels(bare) > 2000, "the obstacles are not in view"
    r, g, b = (bare[..., k].astype(int) for k in range(3))
    assert np.sum((g > 150) & (r < 0.6 * g) & (b < 0.6 * g)) > 100, "the green goal marker is not in view"
    band = (slice(0, 30), slice(0, SIZE[0] // 2))
    assert np.abs(picture[band].astype(int) - bare[band].astype(int)).mean() > 20, "no overlay text at the top left"
    assert np.array_equal(picture[SIZE[1] // 2], bare[SIZE[1] // 2]), "the overlay covers the middle of the picture"


def test_a_long_course_is_followed_and_a_short_one_framed_once(course):
    t = np.linspace(0.0, 40.0, 401)
    straight = Series(t, np.column_stack([0.3 * t, 0 * t, 0.76 + 0 * t, 0 * t, 1 + 0 * t, 0 * t, 0 * t, 0 * t]))
    walk = GoalView("walk", "walk", 1, 0.0, 40.0, "SUCCEEDED", "SUCCESS", (12.0, 0.0, 0.0), 0.0, ())
    empty = ([], Series(np.zeros(0), np.zeros((0, 0))))
    long_run = render.RecordedRun("walk_12m", "g1", "course", 0.0, 40.0, straight, empty, {}, (walk,))
    with render.VideoRenderer(long_run, (160, 120), robot=course) as renderer:
        assert renderer.view_at(20.0).lookat[0] == pytest.approx(6.0, abs=0.1)
        assert renderer.view_at(20.0).azimuth == renderer.view_at(0.0).azimuth
    with render.VideoRenderer(recorded(course, navigate_goal()), (160, 120), robot=course) as renderer:
        assert renderer.view_at(0.0) == renderer.view_at(4.0) == renderer.view


def test_a_long_run_plays_faster_to_last_at_most_the_longest_video_and_says_how_fast(tmp_path, course):
    assert render.playback_speed(12.0) == 1.0
    assert render.playback_speed(3 * render.MAX_VIDEO_S) == pytest.approx(3.0)
    long_run = render.RecordedRun("long", "g1", "course", 0.0, 3 * render.MAX_VIDEO_S, walking_odom(),
                                  ([], Series(np.zeros(0), np.zeros((0, 0)))), {})
    shown = []
    original = overlay.overlay_lines
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(overlay, "overlay_lines", lambda title, *rest: shown.append(title) or original(title, *rest))
        frames = render.render_video(long_run, tmp_path / "long.mp4", fps=1, size=(64, 48), robot=course)
    held = round(render.HOLD_END_S * 1)
    assert frames == round(render.MAX_VIDEO_S) + 1 + held  # one per video second, the end itself, then held
    assert set(shown) == {"long (3.0x)"}


def test_the_overlay_says_the_time_and_each_goals_state():
    goal = navigate_goal(done=9.0)
    assert [line.text for line in overlay.overlay_lines("run", 0.0, 0.0, [])] == ["run   t =   0.00 s"]
    running = overlay.overlay_lines("run", 3.2, 0.0, [goal])
    assert running[0].text == "run   t =   3.20 s"
    assert running[1].text == "navigate_to_pose #1 (nav): running, 2.9 m left" and running[1].colour == overlay.RUNNING
    ended = overlay.overlay_lines("run", 9.5, 0.0, [goal])
    assert ended[1].text == "navigate_to_pose #1 (nav): SUCCEEDED" and ended[1].colour == overlay.SUCCEEDED
    failed = GoalView("w", "walk", 2, 1.0, 2.0, "ABORTED", "FELL", None, None, ())
    assert overlay.overlay_lines("run", 30.0, 0.0, [goal, failed])[1].text == "walk #2 (w): ABORTED (FELL)"


def test_the_path_plot_draws_the_obstacles_and_the_planned_path_under_the_walked_path(course):
    goal = navigate_goal()
    odom = walking_odom()
    clearance = goalview.navigation_inflation(course, NavigationDefaults())
    assert clearance == pytest.approx(0.45)
    planned = goalview.planned_paths(course, [goal], odom, clearance)
    assert planned["nav"][0] == (0.0, 0.0) and planned["nav"][-1] == (3.0, 0.0) and len(planned["nav"]) > 2
    fig = plots.path_figure("course_walk", odom, course.obstacles, [goal], planned, clearance)
    ax = fig.axes[0]
    gids = {patch.get_gid() for patch in ax.patches}
    assert {o.name for o in course.obstacles} <= gids
    assert {f"{o.name}_clearance" for o in course.obstacles} <= gids
    lines = {line.get_label(): line for line in ax.lines}
    assert lines["planned (from start)"].get_zorder() < lines["walked (odom)"].get_zorder()
    assert any(label.startswith("goal nav (navigate_to_pose)") for label in lines)


def test_the_speed_plot_shows_commanded_and_measured_speed_and_marks_each_goal():
    t = np.linspace(0.0, 10.0, 101)
    locomotion = Series(t, np.column_stack([np.where(t < 9.0, 0.3, 0.0), 0 * t, 0.28 + 0 * t, 0 * t]))
    odom = walking_odom()
    fig = plots.speed_figure("course_walk", 0.0, odom, locomotion, [navigate_goal(done=9.0)])
    speed_ax = fig.axes[0]
    labels = [line.get_label() for line in speed_ax.lines]
    assert "commanded (gait, clamped)" in labels and "measured (base velocity)" in labels
    texts = [text.get_text() for text in speed_ax.texts]
    assert "nav sent" in texts and "nav SUCCEEDED" in texts
    assert [line.get_xdata()[0] for line in speed_ax.lines if line.get_linestyle() == "--"] == [9.0]


SHORT_COURSE = """\
name: pictures_course
robot: g1
scene: course
steps:
  - send_goal: {id: nav, action: navigate, goal: {x: 3.0, y: 0.0}, wait: false}
  - wait: {duration: 1.5}
expect:
  - name: never fell
    measure: base_height_min
    gte: 0.5
"""


@pytest.mark.slow
def test_a_course_run_writes_the_video_and_the_plots(tmp_path):
    path = tmp_path / "pictures_course.yaml"
    path.write_text(textwrap.dedent(SHORT_COURSE))
    result = run(schema.load(path), RunOptions(out=tmp_path, quiet=True, video=True, plots=True), stream=io.StringIO())
    report = json.loads((result.folder / "report.json").read_text())
    assert "artifact_errors" not in report, report["artifact_errors"]
    written = report["artifacts"]
    assert pathlib.Path(written["video"]).stat().st_size > 20_000
    assert {pathlib.Path(p).name for p in written["plots"]} >= {"path.png", "speed.png", "base.png"}


def test_a_video_rendered_by_two_processes_has_the_frames_of_one_rendered_by_one(tmp_path, course):
    """The stretches rendered at once (render.VIDEO_WORKERS) are joined into one video of the same frames."""
    import imageio_ffmpeg

    recorded = render.RecordedRun("split", "g1", "course", 0.0, 8.0, walking_odom(),
                                  ([], Series(np.zeros(0), np.zeros((0, 0)))), {}, (navigate_goal(done=6.0),))
    size = (192, 144)  # multiples of 16: the encoder's macro blocks
    videos = {}
    for workers in (1, 2):
        path = tmp_path / f"by_{workers}.mp4"
        count = render.render_video(recorded, path, fps=20, size=size, robot=course, workers=workers)
        assert count == 8 * 20 + 1 + round(render.HOLD_END_S * 20)  # 20 per second, the end, then held
        reader = imageio_ffmpeg.read_frames(str(path))
        meta = next(reader)
        assert tuple(meta["size"]) == size
        videos[workers] = np.stack([np.frombuffer(frame, np.uint8).reshape(size[1], size[0], 3) for frame in reader])
    assert len(videos[2]) == len(videos[1])
    # Each stretch is encoded on its own: the pictures agree up to the encoder's rounding, frame by frame.
    difference = np.abs(videos[2].astype(int) - videos[1].astype(int)).mean(axis=(1, 2, 3))
    assert difference.max() < 4.0, difference.max()
    assert not list(tmp_path.glob(".by_2.part*")), "the stretches are removed once joined"
