"""Plots (matplotlib, no pyplot state) of a run: where the base went, how fast, and what the expectations check.

- ``path.png`` (walking robots): the scene's obstacles (footprint and the margin navigation keeps
  clear), the path NavigateToPose plans from the start, the goals and, on top, the path walked;
- ``speed.png``: commanded vs measured forward speed and turn rate, the goals' feedback, each goal's
  start and end marked;
- ``base.png``: base height (fall line) and distance from the start;
- ``objects.png``, ``feedback_<goal>.png``: the objects' distances to their targets, every goal's feedback.
"""

from __future__ import annotations

import math
import pathlib
from collections.abc import Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from robot_models import Obstacle, RobotSpec
from sim_client.scenario.model.series import Series, object_series, odom_series, stamp_s
from sim_client.scenario.outputs import goalview
from sim_client.scenario.outputs.goalview import GoalView

_NUMERIC_FEEDBACK = ("distance_walked", "current_speed", "distance_remaining", "position_error", "orientation_error",
                     "percent_complete", "stage_progress")
OBSTACLE_RGB = (0.8, 0.55, 0.2)  # as the scene draws them
PLANNED_RGB = (0.10, 0.65, 0.90)
GOAL_COLOURS = ("tab:green", "tab:purple", "tab:cyan", "tab:pink")  # by goal number, as the video's markers
PACE_WINDOW_S = 0.5  # the pelvis sways sideways within a step: pace = planar displacement over this window


def _goal_colour(goal: GoalView) -> str:
    return GOAL_COLOURS[(goal.number - 1) % len(GOAL_COLOURS)]


# ----- marks on time axes ---------------------------------------------------------------------
def mark_goals(ax: Axes, goals: Sequence[GoalView], start: float, label: bool = True) -> None:
    """Each goal's start (solid line) and end (dashed, green when it succeeded, red otherwise), its span shaded.

    With ``label``, the lines are named above the axes: ``nav sent`` and ``nav SUCCEEDED``.
    """
    above = ax.get_xaxis_transform()  # x in data, y in axes fraction
    for goal in goals:
        colour = _goal_colour(goal)
        sent = goal.sent - start
        ax.axvline(sent, color=colour, lw=1.2)
        if label:
            ax.text(sent, 1.01, f"{goal.goal_id} sent", transform=above, va="bottom", ha="left", fontsize=7,
                    color=colour, clip_on=False)
        if goal.done is not None:
            done = goal.done - start
            ended = "tab:green" if goal.succeeded else "tab:red"
            ax.axvline(done, color=ended, lw=1.2, ls="--")
            ax.axvspan(sent, done, color=colour, alpha=0.06, lw=0)
            if label:
                ax.text(done, 1.01, f"{goal.goal_id} {goal.status or 'ended'}", transform=above, va="bottom",
                        ha="right", fontsize=7, color=ended, clip_on=False)


def mark_end(ax: Axes, at: float, label: bool = True) -> None:
    """The end of the run (the last step done) at ``at`` on the time axis; later samples are the wind-down."""
    ax.axvline(at, color="0.3", lw=1.0, ls=":")
    if label:
        ax.text(at, 1.01, "end of run", transform=ax.get_xaxis_transform(), va="bottom", ha="center", fontsize=7,
                color="0.3", clip_on=False)


def _step_marks(ax: Axes, marks: dict[str, float], start: float) -> None:
    """The scenario's own marks (steps with ``mark:``), dotted; goal marks are drawn by :func:`mark_goals`."""
    for name, t in marks.items():
        if name in ("start", "end") or name.endswith((".sent", ".done")):
            continue
        ax.axvline(t - start, color="0.6", lw=0.8, ls=":")
        ax.text(t - start, ax.get_ylim()[1], name, rotation=90, va="top", ha="right", fontsize=7, color="0.4")


# ----- path -----------------------------------------------------------------------------------
def draw_obstacles(ax: Axes, obstacles: Sequence[Obstacle], clearance_m: float = 0.0) -> None:
    """Obstacle footprints (patches with ``gid`` = the obstacle's name) and, dashed, the margin navigation keeps clear."""
    from matplotlib.patches import FancyBboxPatch, Rectangle
    from matplotlib.transforms import Affine2D

    for i, obstacle in enumerate(obstacles):
        (x, y), (hx, hy) = obstacle.center_xy, obstacle.half_size_xy
        ax.add_patch(Rectangle((x - hx, y - hy), 2 * hx, 2 * hy, angle=math.degrees(obstacle.yaw), rotation_point="center",
                               facecolor=OBSTACLE_RGB, edgecolor="0.25", lw=0.8, zorder=2, gid=obstacle.name,
                               label="obstacle" if i == 0 else None))
        ax.text(x, y, obstacle.name.removeprefix("obstacle_"), ha="center", va="center", fontsize=6, zorder=3,
                rotation=90 if hy > hx else 0)
        if clearance_m > 0:
            rotate = Affine2D().rotate_around(x, y, obstacle.yaw) + ax.transData
            ax.add_patch(FancyBboxPatch((x - hx, y - hy), 2 * hx, 2 * hy, boxstyle=f"round,pad={clearance_m}", fill=False,
                                        ls="--", lw=0.8, edgecolor=OBSTACLE_RGB, transform=rotate, zorder=2,
                                        gid=f"{obstacle.name}_clearance",
                                        label=f"kept clear by navigation ({clearance_m:.2f} m)" if i == 0 else None))


def path_figure(title: str, odom: Series, obstacles: Sequence[Obstacle] = (), goals: Sequence[GoalView] = (),
                planned: dict[str, list[tuple[float, float]]] | None = None, clearance_m: float = 0.0) -> Figure:
    """Top view: obstacles, planned paths (dashed), goals (stars, with their heading) and the walked path (odom) on top.

    Args:
        odom: base pose (``series.odom_series``) over the run.
        planned: goal id -> planned path, world frame [m].
        clearance_m: the margin navigation keeps around obstacles [m] (0: not drawn).
    """
    fig = Figure(figsize=(7, 6))
    ax = fig.subplots()
    draw_obstacles(ax, obstacles, clearance_m)
    for i, (goal_id, path) in enumerate((planned or {}).items()):
        xy = np.array(path)
        ax.plot(xy[:, 0], xy[:, 1], "--", marker=".", ms=5, color=PLANNED_RGB, lw=1.5, zorder=3,
                label="planned (from start)" if i == 0 else None, gid=f"planned_{goal_id}")
    if len(odom.t):
        ax.plot(odom.values[:, 0], odom.values[:, 1], color="tab:blue", lw=2.0, zorder=4, label="walked (odom)")
        ax.plot(odom.values[0, 0], odom.values[0, 1], "o", color="tab:green", ms=8, zorder=5, label="start")
        ax.plot(odom.values[-1, 0], odom.values[-1, 1], "s", color="tab:red", ms=7, zorder=5, label="end")
    for goal in goals:
        if goal.target is None or goal.action not in ("walk", "navigate"):
            continue
        x, y, _ = goal.target
        ax.plot(x, y, "*", color=_goal_colour(goal), ms=16, mec="0.2", zorder=6,
                label=f"goal {goal.goal_id} ({goal.server}): {goal.status or 'running'}")
        if goal.target_yaw is not None:
            ax.annotate("", (x + 0.35 * math.cos(goal.target_yaw), y + 0.35 * math.sin(goal.target_yaw)), (x, y),
                        arrowprops={"arrowstyle": "->", "color": _goal_colour(goal), "lw": 1.5}, zorder=6)
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.margins(0.08)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    ax.set_title(f"{title}: base path", fontsize=10)
    fig.tight_layout()
    return fig


# ----- speed ----------------------------------------------------------------------------------
def measured_pace(odom: Series) -> tuple[np.ndarray, np.ndarray]:
    """Planar displacement over ``PACE_WINDOW_S`` [m/s] at times [s]; none across a reset (the base jumps)."""
    half = PACE_WINDOW_S / 2
    if len(odom.t) < 3:
        return np.zeros(0), np.zeros(0)
    inside = (odom.t >= odom.t[0] + half) & (odom.t <= odom.t[-1] - half)
    times = odom.t[inside]
    ahead = [np.interp(times + half, odom.t, odom.values[:, k]) for k in (0, 1)]
    behind = [np.interp(times - half, odom.t, odom.values[:, k]) for k in (0, 1)]
    pace = np.hypot(ahead[0] - behind[0], ahead[1] - behind[1]) / (2 * half)
    step = np.hypot(np.diff(odom.values[:, 0]), np.diff(odom.values[:, 1]))
    for jump in odom.t[1:][step > 0.25 + 2.0 * np.diff(odom.t)]:
        pace[np.abs(times - jump) <= half + 1e-9] = np.nan
    return times, pace


def locomotion_series(messages: Sequence[Any]) -> Series:
    """``sim_interfaces/LocomotionState`` as columns: commanded vx [m/s], wz [rad/s], measured vx, wz."""
    rows = [(stamp_s(m.header.stamp), m.command.linear.x, m.command.angular.z, m.measured.linear.x,
             m.measured.angular.z) for m in messages]
    if not rows:
        return Series(np.zeros(0), np.zeros((0, 4)))
    array = np.array(sorted(rows, key=lambda r: r[0]), dtype=float)
    return Series(array[:, 0], array[:, 1:])


def speed_figure(title: str, start: float, odom: Series, locomotion: Series, goals: Sequence[GoalView] = (),
                 feedback: dict[str, list[tuple[float, Any]]] | None = None,
                 param_events: Sequence[dict[str, Any]] = (), end: float | None = None) -> Figure:
    """Forward speed and turn rate, commanded vs measured, and the goals' feedback, each goal's start and end marked.

    Args:
        start: sim time the time axis counts from [s].
        locomotion: ``locomotion_series`` of /sim/locomotion_state (may be empty).
        feedback: goal id -> (sim time [s], feedback message) per message.
        param_events: the run's ``set_param`` steps (``walking_speed`` is drawn).
        end: sim time the run ended [s], marked when given (goals still running then are canceled after it).
    """
    fig = Figure(figsize=(8, 7.5))
    axes = fig.subplots(3, 1, sharex=True)
    speed_ax, feedback_ax, turn_ax = axes
    if len(locomotion.t):
        t = locomotion.t - start
        speed_ax.step(t, locomotion.values[:, 0], where="post", color="tab:orange", lw=1.5, label="commanded (gait, clamped)")
        speed_ax.plot(t, locomotion.values[:, 2], color="tab:blue", lw=0.6, alpha=0.45, label="measured (base velocity)")
        turn_ax.step(t, locomotion.values[:, 1], where="post", color="tab:orange", lw=1.5, label="commanded")
        turn_ax.plot(t, locomotion.values[:, 3], color="tab:blue", lw=0.8, alpha=0.7, label="measured")
    times, pace = measured_pace(odom)
    if len(times):
        speed_ax.plot(times - start, pace, color="tab:blue", lw=1.8,
                      label=f"measured pace (displacement over {PACE_WINDOW_S:g} s)")
    for event in param_events:
        if event["name"] == "walking_speed" and event["accepted"]:
            speed_ax.axhline(float(event["value"]), color="0.4", ls=":", lw=1,
                             label=f"walking_speed {event['value']} (set at {event['t']:.1f} s)")
    for goal_id, samples in (feedback or {}).items():
        if not samples:
            continue
        t = np.array([when for when, _ in samples]) - start
        first = samples[0][1]
        if hasattr(first, "current_speed"):
            speed_ax.plot(t, [float(f.current_speed) for _, f in samples], "o", ms=3, color="tab:green",
                          label=f"{goal_id} feedback current_speed")
        for name in ("distance_remaining", "distance_walked"):
            if hasattr(first, name):
                values = [float(getattr(f, name)) for _, f in samples]
                feedback_ax.plot(t, [v if math.isfinite(v) else np.nan for v in values], ".-", ms=3,
                                 label=f"{goal_id} {name}")
    speed_ax.set_ylabel("forward speed [m/s]")
    feedback_ax.set_ylabel("feedback [m]")
    turn_ax.set_ylabel("turn rate [rad/s]")
    turn_ax.set_xlabel("sim time [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
        mark_goals(ax, goals, start, label=ax is speed_ax)
        if end is not None and not any(g.done is not None and abs(g.done - end) < 0.5 for g in goals):
            mark_end(ax, end - start, label=ax is speed_ax)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7, loc="upper right")
    fig.suptitle(f"{title}: speed, commanded vs measured", fontsize=10)
    fig.tight_layout()
    return fig


# ----- all plots of a run -----------------------------------------------------------------------
def make_plots(run: Any, folder: pathlib.Path, robot: RobotSpec | None = None) -> list[pathlib.Path]:
    """Write the plots that fit the run's robot and expectations; returns their paths.

    Args:
        run: a ``ScenarioRun`` after its end (read, not changed).
        robot: the run's robot in its scene, when already loaded.
    """
    import robot_models

    scenario = run.scenario
    name = scenario.name
    start = run.marks.get("start", 0.0)
    kinds = {e.measure.kind for e in scenario.expectations if e.measure is not None}
    paths = []
    odom = odom_series(run.odom.messages())
    goals = goalview.goal_views(run, odom)
    robot = robot or robot_models.load(scenario.robot, scenario.scene)
    if robot.floating_base and len(odom.t) > 2:
        paths.append(_base_plot(name, start, odom, run, goals, folder))
        clearance = goalview.navigation_inflation(robot, run)
        planned = goalview.planned_paths(robot, goals, odom, clearance)
        paths.append(_save(path_figure(name, odom, robot.obstacles, goals, planned, clearance), folder / "path.png"))
        recorder = getattr(run, "locomotion", None)  # /sim/locomotion_state, recorded when plots were asked for
        locomotion = locomotion_series(recorder.messages() if recorder is not None else [])
        feedback = {g: [(s.sim_time, s.feedback) for s in h.feedback_history] for g, h in run.goals.items()}
        paths.append(_save(speed_figure(name, start, odom, locomotion, goals, feedback, run.param_events,
                                        run.marks.get("end")), folder / "speed.png"))
    targets = [(e.measure.args["object"], e.measure.args["target"]) for e in scenario.expectations
               if e.measure is not None and e.measure.kind == "object_distance"]
    if targets or "object_position" in kinds:
        paths.append(_objects_plot(name, start, run, goals, targets, folder))
    for goal in goals:
        path = _feedback_plot(name, start, run, goal, folder)
        if path is not None:
            paths.append(path)
    return paths


def _base_plot(name: str, start: float, odom: Series, run: Any, goals: Sequence[GoalView], folder: pathlib.Path) -> pathlib.Path:
    fig = Figure(figsize=(8, 6))
    height_ax, distance_ax = fig.subplots(2, 1, sharex=True)
    t = odom.t - start
    height_ax.plot(t, odom.values[:, 2])
    height_ax.axhline(0.5, color="C3", ls="--", lw=1, label="fallen below")
    height_ax.set_ylabel("base height [m]")
    p0 = odom.at(start)
    if p0 is None:
        p0 = odom.values[0]
    distance_ax.plot(t, np.hypot(odom.values[:, 0] - p0[0], odom.values[:, 1] - p0[1]), label="planar distance from start")
    distance_ax.set_ylabel("distance [m]")
    distance_ax.set_xlabel("sim time [s]")
    for ax in (height_ax, distance_ax):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
        mark_goals(ax, goals, start, label=ax is height_ax)
        _step_marks(ax, run.marks, start)
    fig.suptitle(f"{name}: base", fontsize=10)
    fig.tight_layout()
    return _save(fig, folder / "base.png")


def _objects_plot(name: str, start: float, run: Any, goals: Sequence[GoalView], targets: list[tuple[str, Any]],
                  folder: pathlib.Path) -> pathlib.Path:
    fig = Figure(figsize=(8, 4))
    ax = fig.subplots()
    for object_name, target in targets:
        series = object_series(run.objects.messages(), object_name)
        if len(series.t):
            distance = np.linalg.norm(series.values[:, 0:3] - np.array(target), axis=1)
            ax.plot(series.t - start, distance, label=f"{object_name} to {tuple(round(v, 3) for v in target)}")
    ax.set_yscale("log")
    ax.set_ylabel("distance [m]")
    ax.set_xlabel("sim time [s]")
    ax.grid(alpha=0.3, which="both")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7)
    mark_goals(ax, goals, start)
    _step_marks(ax, run.marks, start)
    ax.set_title(f"{name}: objects", fontsize=10)
    fig.tight_layout()
    return _save(fig, folder / "objects.png")


def _feedback_plot(name: str, start: float, run: Any, goal: GoalView, folder: pathlib.Path) -> pathlib.Path | None:
    history = run.goals[goal.goal_id].feedback_history
    if not history:
        return None
    fields = [f for f in _NUMERIC_FEEDBACK if hasattr(history[0].feedback, f)]
    if not fields:
        return None
    fig = Figure(figsize=(8, 2.0 * len(fields) + 1))
    axes = fig.subplots(len(fields), 1, sharex=True, squeeze=False)
    t = np.array([s.sim_time for s in history]) - start
    for ax, field_name in zip(axes[:, 0], fields, strict=True):
        values = [float(getattr(s.feedback, field_name)) for s in history]
        ax.plot(t, [v if math.isfinite(v) else np.nan for v in values], ".-", ms=3)
        ax.set_ylabel(field_name, fontsize=8)
        ax.grid(alpha=0.3)
        mark_goals(ax, [goal], start, label=ax is axes[0, 0])
        _step_marks(ax, run.marks, start)
    axes[-1, 0].set_xlabel("sim time [s]")
    fig.suptitle(f"{name}: feedback of {goal.label()} -> {goal.state_at(math.inf)}", fontsize=9)
    fig.tight_layout()
    return _save(fig, folder / f"feedback_{goal.goal_id}.png")


def _save(fig: Figure, path: pathlib.Path) -> pathlib.Path:
    fig.savefig(path, dpi=90)
    return path
