"""Plots (matplotlib, Agg) of the quantities a scenario's expectations check."""

from __future__ import annotations

import math
import pathlib
from typing import Any

import numpy as np

from sim_client.scenario import artifacts

_NUMERIC_FEEDBACK = ("distance_walked", "current_speed", "distance_remaining", "position_error", "orientation_error",
                     "percent_complete", "stage_progress")


def _marks(ax: Any, run: Any, start: float) -> None:
    for name, t in run.marks.items():
        if name in ("start", "end"):
            continue
        ax.axvline(t - start, color="0.6", lw=0.8, ls=":")
        ax.text(t - start, ax.get_ylim()[1], name, rotation=90, va="top", ha="right", fontsize=7, color="0.4")


def make_plots(run: Any, folder: pathlib.Path) -> list[pathlib.Path]:
    """Write the plots that fit the run's robot and expectations; returns their paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    start = run.marks.get("start", 0.0)
    kinds = {e.measure.kind for e in run.scenario.expectations if e.measure is not None}
    paths = []
    odom = artifacts.odom_series(run.odom.messages())
    if run.scenario.robot == "g1" and len(odom.t) > 2:
        t = odom.t - start
        fig, axes = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
        # pace = planar displacement over 0.5 s (the pelvis sways sideways within a step)
        half = 0.25
        inside = (odom.t >= odom.t[0] + half) & (odom.t <= odom.t[-1] - half)
        speed_t = t[inside]
        ahead = [np.interp(odom.t[inside] + half, odom.t, odom.values[:, k]) for k in (0, 1)]
        behind = [np.interp(odom.t[inside] - half, odom.t, odom.values[:, k]) for k in (0, 1)]
        speed = np.hypot(ahead[0] - behind[0], ahead[1] - behind[1]) / (2 * half)
        # A reset moves the base farther between two samples than any walk: no pace across it.
        step = np.hypot(np.diff(odom.values[:, 0]), np.diff(odom.values[:, 1]))
        jumps = odom.t[1:][step > 0.25 + 2.0 * np.diff(odom.t)]
        for jump in jumps:
            speed[np.abs(odom.t[inside] - jump) <= half + 1e-9] = np.nan
        axes[0].plot(speed_t, speed, label="measured pace (displacement over 0.5 s)")
        for event in run.param_events:
            if event["name"] == "walking_speed" and event["accepted"]:
                axes[0].axhline(float(event["value"]), color="C1", ls="--", lw=1,
                                label=f"walking_speed {event['value']} (set at {event['t']:.1f} s)")
        axes[0].set_ylabel("speed [m/s]")
        axes[0].legend(fontsize=7, loc="upper left")
        axes[1].plot(t, odom.values[:, 2])
        axes[1].axhline(0.5, color="C3", ls="--", lw=1, label="fallen below")
        axes[1].set_ylabel("base height [m]")
        axes[1].legend(fontsize=7)
        p0 = odom.at(start)
        if p0 is None:  # no /odom sample (len(odom.t) > 2 above, so not reached)
            p0 = odom.values[0]
        travelled = np.hypot(odom.values[:, 0] - p0[0], odom.values[:, 1] - p0[1])
        axes[2].plot(t, travelled, label="planar distance from start")
        axes[2].set_ylabel("distance [m]")
        axes[2].set_xlabel("sim time [s]")
        axes[2].legend(fontsize=7)
        for ax in axes:
            ax.grid(alpha=0.3)
            _marks(ax, run, start)
        fig.suptitle(f"{run.scenario.name}: base")
        fig.tight_layout()
        paths.append(_save(fig, folder / "base.png", plt))
        fig, ax = plt.subplots(figsize=(6, 6))
        ax.plot(odom.values[:, 0], odom.values[:, 1])
        ax.plot(odom.values[0, 0], odom.values[0, 1], "go", label="start")
        ax.plot(odom.values[-1, 0], odom.values[-1, 1], "rs", label="end")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
        ax.set_title(f"{run.scenario.name}: base path (odom)")
        paths.append(_save(fig, folder / "path.png", plt))
    targets = [(e.measure.args["object"], e.measure.args["target"]) for e in run.scenario.expectations
               if e.measure is not None and e.measure.kind == "object_distance"]
    if targets or "object_position" in kinds:
        fig, ax = plt.subplots(figsize=(8, 4))
        for name, target in targets:
            series = artifacts.object_series(run.objects.messages(), name)
            if len(series.t):
                distance = np.linalg.norm(series.values[:, 0:3] - np.array(target), axis=1)
                ax.plot(series.t - start, distance, label=f"{name} to {tuple(round(v, 3) for v in target)}")
        ax.set_yscale("log")
        ax.set_ylabel("distance [m]")
        ax.set_xlabel("sim time [s]")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
        _marks(ax, run, start)
        ax.set_title(f"{run.scenario.name}: objects")
        paths.append(_save(fig, folder / "objects.png", plt))
    for goal_id, handle in run.goals.items():
        history = handle.feedback_history
        if not history:
            continue
        fields = [f for f in _NUMERIC_FEEDBACK if hasattr(history[0].feedback, f)]
        if not fields:
            continue
        fig, axes = plt.subplots(len(fields), 1, figsize=(8, 2.0 * len(fields) + 1), sharex=True, squeeze=False)
        t = np.array([s.sim_time for s in history]) - start
        for ax, name in zip(axes[:, 0], fields, strict=True):
            values = [float(getattr(s.feedback, name)) for s in history]
            ax.plot(t, [v if math.isfinite(v) else np.nan for v in values], ".-", ms=3)
            ax.set_ylabel(name, fontsize=8)
            ax.grid(alpha=0.3)
            _marks(ax, run, start)
        axes[-1, 0].set_xlabel("sim time [s]")
        outcome = handle.outcome()
        fig.suptitle(f"{run.scenario.name}: feedback of {goal_id} ({run.goal_actions[goal_id]}) -> {outcome or 'running'}",
                     fontsize=9)
        fig.tight_layout()
        paths.append(_save(fig, folder / f"feedback_{goal_id}.png", plt))
    return paths


def _save(fig: Any, path: pathlib.Path, plt: Any) -> pathlib.Path:
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
