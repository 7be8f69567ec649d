"""What the pictures of a run say about its goals: where each one leads, when it ran, how it went.

A :class:`GoalView` is read once from the run (the goal messages sent, their feedback and outcome,
the run's marks) and then drawn by the video (a marker at the target, a line of overlay text) and
the plots (the target, the goal's start and end). Targets are world positions; a goal given in a
frame the pictures cannot resolve without /tf (e.g. ``panda_link0``) has no target.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from robot_models import RobotSpec
from sim_client.scenario.model.series import Series, yaw_of

# Frames whose coordinates are world coordinates in this simulator (/odom starts at the world origin).
WORLD_FRAMES = ("", "world", "odom", "map")
# The action server each scenario action names (its ROS name, as a ROS user knows it).
SERVER_NAMES = {"walk": "walk", "navigate": "navigate_to_pose", "move_arm": "move_arm", "pick_place": "pick_place"}
# The node that serves navigate_to_pose; its planner inflates the scene's obstacles by two of its parameters.
NAVIGATION_NODE = "locomotion"


@dataclass(frozen=True)
class GoalView:
    """One goal of a run, as the pictures show it.

    Attributes:
        goal_id: the scenario's id of the goal (``"nav"``).
        action: the scenario's action name (``"navigate"``).
        number: 1 for the first goal of the run, 2 for the next...
        sent: sim time the goal was sent [s].
        done: sim time the runner saw it end [s]; None when it did not end before the run's end.
        status: ``SUCCEEDED``, ``ABORTED``, ``CANCELED``, ``REJECTED``, or ``""`` (still running).
        error_name: the result's error code name (``"SUCCESS"``, ``"FELL"``...), ``""`` when none.
        target: where the goal leads, world frame [m] (x, y, z); None when unknown.
        target_yaw: heading to reach at the target [rad]; None when the goal has none.
        progress: (sim time [s], short text such as ``"1.8 m left"``), one per feedback message, in time order.
        carried: the object a PickPlace goal moves (``"box_0"``), ``""`` for other goals.
    """

    goal_id: str
    action: str
    number: int
    sent: float
    done: float | None
    status: str
    error_name: str
    target: tuple[float, float, float] | None
    target_yaw: float | None
    progress: tuple[tuple[float, str], ...]
    carried: str = ""

    @property
    def server(self) -> str:
        """The action's ROS name (``navigate_to_pose``)."""
        return SERVER_NAMES.get(self.action, self.action)

    @property
    def succeeded(self) -> bool:
        return self.status == "SUCCEEDED"

    def ended_by(self, t: float) -> bool:
        """Whether the goal had ended at sim time ``t`` [s]."""
        return self.done is not None and t >= self.done - 1e-9

    def progress_at(self, t: float) -> str:
        """The progress text of the last feedback at or before ``t`` [s] (``""`` before the first)."""
        text = ""
        for when, what in self.progress:
            if when > t + 1e-9:
                break
            text = what
        return text

    def state_at(self, t: float) -> str:
        """``"running, 1.8 m left"`` while it runs, then ``"SUCCEEDED"`` or ``"ABORTED (FELL)"``."""
        if self.ended_by(t) and self.status:
            if self.status == "SUCCEEDED" or not self.error_name or self.error_name == self.status:
                return self.status
            return f"{self.status} ({self.error_name})"
        progress = self.progress_at(t)
        return f"running, {progress}" if progress else "running"

    def label(self) -> str:
        """``navigate_to_pose #1 (nav)``."""
        return f"{self.server} #{self.number} ({self.goal_id})"


def goal_views(run: Any, odom: Series) -> tuple[GoalView, ...]:
    """The goals of a scenario run (a ``ScenarioRun``: ``goals``, ``goal_actions``, ``marks``), in the order sent.

    Args:
        run: the run; read, not changed.
        odom: the base's recorded pose (``series.odom_series``), to place a Walk goal's target.
    """
    views = []
    sent_order = sorted(run.goals, key=lambda goal_id: run.marks.get(f"{goal_id}.sent", 0.0))
    for number, goal_id in enumerate(sent_order, start=1):
        handle = run.goals[goal_id]
        action = run.goal_actions[goal_id]
        sent = float(run.marks.get(f"{goal_id}.sent", handle.sent_at))
        done = run.marks.get(f"{goal_id}.done")
        outcome = handle.outcome()
        target, yaw = goal_target(action, handle.goal, odom.at(sent))
        progress = tuple((sample.sim_time, progress_text(action, handle.goal, sample.feedback))
                         for sample in handle.feedback_history)
        views.append(GoalView(goal_id, action, number, sent, None if done is None else float(done),
                              outcome.status if outcome is not None else "",
                              (outcome.error_name or "") if outcome is not None else "", target, yaw, progress,
                              str(getattr(handle.goal, "object_id", "")) if action == "pick_place" else ""))
    return tuple(views)


def goal_target(action: str, goal: Any, base_at_sent: Any) -> tuple[tuple[float, float, float] | None, float | None]:
    """Where a goal message leads, world frame [m], and the heading to reach there [rad].

    Args:
        action: the scenario's action name.
        goal: the goal message sent.
        base_at_sent: the ``odom_series`` row (x, y, z, yaw, ...) when the goal was sent, or None.
    """
    if action == "walk" and base_at_sent is not None:
        x, y, yaw = float(base_at_sent[0]), float(base_at_sent[1]), float(base_at_sent[3])
        distance = float(goal.distance)
        return (x + distance * math.cos(yaw), y + distance * math.sin(yaw), 0.0), yaw
    pose = {"navigate": "pose", "move_arm": "target", "pick_place": "place_pose"}.get(action)
    if pose is None:
        return None, None
    stamped = getattr(goal, pose)
    if stamped.header.frame_id not in WORLD_FRAMES:
        return None, None
    p = stamped.pose.position
    if action == "navigate":
        return (float(p.x), float(p.y), 0.0), yaw_of(stamped.pose.orientation)
    return (float(p.x), float(p.y), float(p.z)), None


def progress_text(action: str, goal: Any, feedback: Any) -> str:
    """A few words on how far a goal has come, from one feedback message."""
    if action == "walk":
        left = max(0.0, abs(float(goal.distance)) - math.copysign(1.0, goal.distance) * float(feedback.distance_walked))
        return f"{left:.1f} m left, {float(feedback.current_speed):.2f} m/s"
    if action == "navigate":
        return f"{float(feedback.distance_remaining):.1f} m left"
    if action == "move_arm":
        return f"{100.0 * float(feedback.position_error):.1f} cm to go"
    if action == "pick_place":
        return f"{feedback.stage_name.lower()}, {float(feedback.percent_complete):.0f}%"
    return ""


def on_table(robot: RobotSpec, target: tuple[float, float, float]) -> tuple[float, float, float]:
    """A place target as PickPlace reads it: z at or below the table top means on the table."""
    top = robot.arm_scene.objects_table_top_z
    if top is None or target[2] > top + robot.arm_scene.object_half_size:
        return target
    return target[0], target[1], top


def navigation_inflation(robot: RobotSpec, run: Any) -> float:
    """How far NavigateToPose keeps the base's centre from obstacles [m]: ``robot_radius + obstacle_detection_threshold``.

    As the run's navigation node holds them at its end (its defaults, with the run's ``set_param`` steps
    on top), read through ``run.parameter(node, name)``. 0 for a robot that does not walk; a value the
    node does not answer counts 0.
    """
    if robot.walking is None:
        return 0.0
    values = [run.parameter(NAVIGATION_NODE, name) for name in ("robot_radius", "obstacle_detection_threshold")]
    return sum(float(value) for value in values if isinstance(value, int | float) and not isinstance(value, bool))


def planned_path(robot: RobotSpec, view: GoalView, base_at_sent: Any, inflation_m: float) -> list[tuple[float, float]] | None:
    """The path NavigateToPose plans for a goal from where the base stood when it was sent, world frame [m].

    The same planner as the server's (:func:`sim_bridge.navigation.plan_path` on the scene's
    obstacles inflated by ``inflation_m``), for display: the server may replan on the way. None for
    another action, a goal without target, or no path.
    """
    from sim_bridge.navigation import NoPathError, grid_from_obstacles, plan_path

    if view.action != "navigate" or view.target is None or base_at_sent is None:
        return None
    grid = grid_from_obstacles(robot.obstacles).inflated(inflation_m)
    try:
        return plan_path(grid, (float(base_at_sent[0]), float(base_at_sent[1])), (view.target[0], view.target[1]))
    except NoPathError:
        return None


def planned_paths(robot: RobotSpec, goals: Sequence[GoalView], odom: Series,
                  inflation_m: float) -> dict[str, list[tuple[float, float]]]:
    """Goal id -> :func:`planned_path` from where the base stood when the goal was sent, for every goal that has one."""
    paths = {}
    for goal in goals:
        path = planned_path(robot, goal, odom.at(goal.sent), inflation_m)
        if path is not None:
            paths[goal.goal_id] = path
    return paths
