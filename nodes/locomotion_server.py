"""The ``/locomotion`` node: Walk and NavigateToPose action servers for the G1.

The walking itself (footsteps, balance, torque control) runs inside the simulation's control
step in ``/sim``; this node plans and supervises by commanding ``/cmd_vel`` and reading ``/odom``
and ``/sim/locomotion_state``. ``walking_speed`` sets the pace of both actions and can change
while a goal runs. One goal at a time: a new goal preempts the running one.
"""

from __future__ import annotations

import collections
import math
import os
import sys
import time

import numpy as np
from geometry_msgs.msg import PoseStamped, Twist
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from nav_msgs.msg import Odometry
from rclpy.action import ActionServer, CancelResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile

import robot_models
from nodes.common import (
    ActiveGoal, GoalOwnership, GoalRejected, Latest, OnDemandTopic, finish_goal, goal_validator, guarded, spin_server,
)
from nodes.conversions import duration_msg, grid_from_msg, seconds_of, yaw_of
from nodes.parameters import ParameterSpec, declare
from sim_bridge.navigation import NoPathError, PathFollower, plan_path
from sim_bridge.navigation.follower import wrap_angle
from sim_bridge.navigation.planner import path_length
from sim_interfaces.action import NavigateToPose, Walk
from sim_interfaces.msg import LocomotionState

NODE_NAME = "locomotion"
LEGS = "legs"
ACK_TIMEOUT_S = 15.0  # wall seconds to wait for /odom and /sim/locomotion_state
MAX_WALK_DISTANCE_M = 100.0
FALL_HEIGHT_M = 0.45
MAX_CORRECTIONS = 2  # short, slow walks after the first stop to land within distance_tolerance
CORRECTION_SPEED = 0.1  # [m/s]
WORLD_FRAMES = ("", "world", "odom", "map")
FRESH_START_S = 1.0  # a reset seen this soon after a goal began restarts the goal from the new pose [s of sim time]
FRESH_START_M = 0.1  # ... provided the walk had not moved farther than this [m]
MAX_RESTARTS = 3


class _ResetAtStart(Exception):
    """/sim was reset just before the goal began: odometry from before the reset reached this node first.

    Messages published before a reset can still sit in this node's queue when the goal arrives, so the
    first "fresh" odometry may predate the reset. The goal starts over from the pose after the reset.
    """

PARAMETERS = (
    ParameterSpec("walking_speed", 0.3, "pace of Walk and NavigateToPose [m/s]; changes apply to running goals", 0.05, 0.6),
    ParameterSpec("max_yaw_rate", 0.6, "turning rate limit while navigating [rad/s]", 0.1, 1.0),
    ParameterSpec("obstacle_detection_threshold", 0.15, "clearance kept from obstacles beyond the robot radius [m]", 0.0, 1.0),
    ParameterSpec("robot_radius", 0.30, "footprint radius used to inflate obstacles [m]", 0.1, 1.0),
    ParameterSpec("xy_goal_tolerance", 0.15, "NavigateToPose position tolerance [m]", 0.03, 1.0),
    ParameterSpec("yaw_goal_tolerance", 0.15, "NavigateToPose heading tolerance [rad]", 0.03, 1.0),
    ParameterSpec("command_rate", 20.0, "/cmd_vel rate while a goal runs [Hz of sim time]", 5.0, 100.0),
    ParameterSpec("feedback_rate", 5.0, "action feedback rate [Hz of sim time]", 1.0, 50.0),
    ParameterSpec("stop_gain", 1.0, "Walk slows to stop_gain x remaining distance near the end [1/s]", 0.2, 5.0),
    ParameterSpec("stop_lead_time", 0.3, "Walk stops when the remaining distance is speed x this [s]", 0.0, 2.0),
    ParameterSpec("distance_tolerance", 0.015, "Walk corrects (slowly) when it stopped farther than this from the goal [m]", 0.005, 0.5),
    ParameterSpec("replan_distance", 0.6, "NavigateToPose replans when this far off the path [m]", 0.2, 3.0),
)


class StepCounter:
    """Steps taken since a goal began, from the controller's running count.

    The count restarts at 0 when /sim is reset, and a count from before a reset can still
    arrive after the goal began; a drop of the count is taken as such a restart.
    """

    def __init__(self) -> None:
        self._last: int | None = None
        self.total = 0

    def update(self, count: int) -> int:
        if self._last is not None:
            self.total += count - self._last if count >= self._last else count
        self._last = count
        return self.total


class LocomotionServer(Node):
    """Serves ``/walk`` and ``/navigate_to_pose`` for the G1 of ``/sim``."""

    def __init__(self, robot: str, **kwargs) -> None:
        super().__init__(NODE_NAME, **kwargs)
        declare(self, (ParameterSpec("robot", robot, "robot whose legs are served", read_only=True), *PARAMETERS))
        spec = robot_models.load(robot)
        if not spec.feet_sites:
            raise GoalRejected(f"robot {robot!r} cannot walk; walking robots: g1")
        self._ownership = GoalOwnership(first_seq=1 + os.getpid() % 100_000)
        self._map: Latest[OccupancyGridMsg] = Latest()
        group = ReentrantCallbackGroup()
        # /odom and the controller state only while a goal runs: an idle /locomotion receives nothing but /map.
        self._odom: OnDemandTopic[Odometry] = OnDemandTopic(self, Odometry, "/odom", 10, group)
        self._state: OnDemandTopic[LocomotionState] = OnDemandTopic(self, LocomotionState, "/sim/locomotion_state", 10, group)
        self._cmd_pub = self.create_publisher(Twist, "/cmd_vel", 10)
        self.create_subscription(OccupancyGridMsg, "/map", self._map.put,
                                 QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL), callback_group=group)
        self._walk_server = ActionServer(
            self, Walk, "/walk", execute_callback=guarded(self, Walk, self._execute_walk), goal_callback=goal_validator(self, "Walk", self._validate_walk),
            handle_accepted_callback=lambda handle: handle.execute(),
            cancel_callback=lambda _goal: CancelResponse.ACCEPT, callback_group=group,
        )
        self._nav_server = ActionServer(
            self, NavigateToPose, "/navigate_to_pose", execute_callback=guarded(self, NavigateToPose, self._execute_navigate),
            goal_callback=goal_validator(self, "NavigateToPose", self._validate_navigate), handle_accepted_callback=lambda handle: handle.execute(),
            cancel_callback=lambda _goal: CancelResponse.ACCEPT, callback_group=group,
        )
        self.get_logger().info(f"serving /walk and /navigate_to_pose for {robot}")

    def _param(self, name: str) -> float:
        return float(self.get_parameter(name).value)

    # ----- shared ------------------------------------------------------------------------
    def _command(self, vx: float, wz: float = 0.0, vy: float = 0.0) -> None:
        msg = Twist()
        msg.linear.x, msg.linear.y, msg.angular.z = float(vx), float(vy), float(wz)
        self._cmd_pub.publish(msg)

    def _wait_inputs(self) -> tuple[Odometry, LocomotionState] | None:
        """The first /odom to arrive after the goal, and a controller state at least as new.

        /sim publishes the odometry and the controller state of an instant one after the other, on
        two topics: when the odometry arrives, that instant's state may still be on its way, so the
        state must carry a stamp at least as late as the odometry's. Both may still predate a reset
        the client made just before sending the goal, when this node's queue lags: a position jump
        is caught by the supervisor (the goal starts over), a fall must hold FRESH_START_S first.
        """
        deadline = time.monotonic() + ACK_TIMEOUT_S
        odom = None
        while odom is None and time.monotonic() < deadline:
            if self._odom.latest.wait_next(0.1):
                odom = self._odom.latest.get()
        first: float | None = None
        while odom is not None and time.monotonic() < deadline:
            state = self._state.latest.get()
            if state is not None and seconds_of(state.header.stamp) >= seconds_of(odom.header.stamp):
                # "Fallen" at the very start may still be news from before a reset that this node's
                # queue has not caught up with: believe it once it has held FRESH_START_S of sim time.
                first = seconds_of(odom.header.stamp) if first is None else first
                if not self._fallen(odom, state) or seconds_of(odom.header.stamp) - first > FRESH_START_S:
                    return odom, state
            if self._state.latest.wait_next(0.1):
                odom = self._odom.latest.get() or odom
        return None

    @staticmethod
    def _jumped(previous: Odometry, odom: Odometry) -> bool:
        """A base displacement no walk can make between two odometry messages: the sim was reset."""
        dt = max(seconds_of(odom.header.stamp) - seconds_of(previous.header.stamp), 1e-3)
        a, b = previous.pose.pose.position, odom.pose.pose.position
        return math.hypot(b.x - a.x, b.y - a.y) > 0.25 + 2.0 * dt

    def _next_odom(self) -> Odometry:
        self._odom.latest.wait_next(1.0)
        odom = self._odom.latest.get()
        assert odom is not None
        return odom

    @staticmethod
    def _raise_if_fresh(elapsed_s: float, moved_m: float) -> None:
        """On a reset seen at a goal's very start, raise :class:`_ResetAtStart` (the goal starts over)."""
        if elapsed_s <= FRESH_START_S and moved_m <= FRESH_START_M:
            raise _ResetAtStart()

    @staticmethod
    def _fallen(odom: Odometry, state: LocomotionState | None) -> str:
        if state is not None and state.mode == LocomotionState.FALLEN:
            return state.message or "the robot fell"
        if odom.pose.pose.position.z < FALL_HEIGHT_M:
            return f"the pelvis dropped to {odom.pose.pose.position.z:.2f} m"
        return ""

    def _stop_and_settle(self, timeout_s: float = 4.0) -> None:
        """Command zero and wait (in sim time) until the controller no longer walks."""
        self._command(0.0)
        start = None
        while True:
            odom = self._next_odom()
            now = seconds_of(odom.header.stamp)
            start = now if start is None else start
            state = self._state.latest.get()
            if state is None or state.mode in (LocomotionState.STANDING, LocomotionState.FALLEN) or now - start > timeout_s:
                return
            self._command(0.0)

    def _interrupted(self, goal_handle: ServerGoalHandle, owner: ActiveGoal, result, codes) -> object | None:
        """Handle preemption and cancel; returns the finished result or None to continue."""
        if owner.preempted.is_set():
            return finish_goal(self, goal_handle, result, codes.PREEMPTED, "preempted by a newer goal", abort=True)
        if goal_handle.is_cancel_requested:
            self._stop_and_settle()
            return finish_goal(self, goal_handle, result, codes.CANCELED, "canceled: the robot stopped and stands", cancel=True)
        return None

    def _execute_restartable(self, goal_handle: ServerGoalHandle, action_type, supervise, what: str):
        """Run ``supervise`` owning the legs; start it over when a reset is seen as it begins."""
        result = action_type.Result()
        with self._ownership.owned(LEGS) as owner, self._odom.held(), self._state.held():
            for _ in range(MAX_RESTARTS):
                try:
                    return supervise(goal_handle, goal_handle.request, owner, result)
                except _ResetAtStart:
                    self.get_logger().info(f"the sim was reset as the {what} began; starting over from the new pose")
            return finish_goal(self, goal_handle, result, action_type.Result.SIM_FAULT,
                               f"the simulation kept being reset as the {what} began", abort=True)

    # ----- Walk --------------------------------------------------------------------------
    def _validate_walk(self, goal: Walk.Goal) -> None:
        values = {"distance": goal.distance, "speed": goal.speed, "timeout": goal.timeout}
        bad = [name for name, value in values.items() if not math.isfinite(value)]
        if bad:
            raise GoalRejected(f"{', '.join(bad)} must be finite numbers")
        if not 0.0 < abs(goal.distance) <= MAX_WALK_DISTANCE_M:
            raise GoalRejected(f"distance must be non-zero and within +-{MAX_WALK_DISTANCE_M:.0f} m, got {goal.distance}")
        low, high = 0.05, 0.6
        if goal.speed != 0.0 and not low <= goal.speed <= high:
            raise GoalRejected(f"speed must be in [{low}, {high}] m/s (0 = the walking_speed parameter), got {goal.speed}")
        if goal.timeout < 0.0:
            raise GoalRejected(f"timeout must be >= 0 s (0 = automatic), got {goal.timeout}")

    def _execute_walk(self, goal_handle: ServerGoalHandle) -> Walk.Result:
        return self._execute_restartable(goal_handle, Walk, self._supervise_walk, "walk")

    def _supervise_walk(self, goal_handle: ServerGoalHandle, goal: Walk.Goal, owner: ActiveGoal, result: Walk.Result) -> Walk.Result:
        inputs = self._wait_inputs()
        if inputs is None:
            return finish_goal(self, goal_handle, result, Walk.Result.SIM_FAULT,
                               "no /odom or /sim/locomotion_state: is /sim running with the g1?", abort=True)
        odom, state = inputs
        start = np.array([odom.pose.pose.position.x, odom.pose.pose.position.y])
        heading = yaw_of(_quat_wxyz(odom))
        forward = np.array([math.cos(heading), math.sin(heading)])
        start_time = seconds_of(odom.header.stamp)
        steps = StepCounter()
        steps.update(state.steps_taken)
        sign = 1.0 if goal.distance > 0 else -1.0
        speed0 = goal.speed or self._param("walking_speed")
        timeout = goal.timeout or (abs(goal.distance) / speed0 * 2.5 + 10.0)
        command_period = 1.0 / self._param("command_rate")
        feedback_period = 1.0 / self._param("feedback_rate")
        last_command = last_feedback = -math.inf
        history: collections.deque[tuple[float, float]] = collections.deque()
        corrections = 0
        cap = math.inf  # speed cap of a correction after the first stop [m/s]
        while True:
            walked = self._distance_along(odom, start, forward)
            self._fill_walk(result, odom, walked)
            finished = self._interrupted(goal_handle, owner, result, Walk.Result)
            if finished is not None:
                return finished
            now = seconds_of(odom.header.stamp)
            fell = self._fallen(odom, self._state.latest.get())
            if fell:
                self._command(0.0)
                return finish_goal(self, goal_handle, result, Walk.Result.FELL, f"fell after {walked:.2f} m: {fell}", abort=True)
            if now - start_time > timeout:
                self._stop_and_settle()
                self._fill_walk(result, self._odom.latest.get() or odom, self._distance_along(self._odom.latest.get() or odom, start, forward))
                return finish_goal(self, goal_handle, result, Walk.Result.TIMEOUT,
                                   f"timed out after {timeout:.1f} s of sim time having walked {walked:.2f} m", abort=True)
            history.append((now, walked))
            while len(history) > 2 and now - history[0][0] > 0.4:
                history.popleft()
            pace = abs(history[-1][1] - history[0][1]) / max(history[-1][0] - history[0][0], 1e-3)
            to_go = goal.distance - walked  # signed, along the start heading
            direction = 1.0 if to_go >= 0.0 else -1.0
            speed = min(goal.speed or self._param("walking_speed"), cap)
            # Stop early by what the robot still travels while it closes its feet.
            overshot = direction != sign
            if overshot or abs(to_go) <= max(0.01, pace * self._param("stop_lead_time")):
                self._stop_and_settle()
                odom = self._odom.latest.get() or odom
                walked = self._distance_along(odom, start, forward)
                self._fill_walk(result, odom, walked)
                off = goal.distance - walked
                if abs(off) > self._param("distance_tolerance") and corrections < MAX_CORRECTIONS:
                    corrections += 1
                    cap = CORRECTION_SPEED
                    sign = 1.0 if off > 0 else -1.0
                    history.clear()
                    odom = self._next_odom()
                    continue
                return finish_goal(self, goal_handle, result, Walk.Result.SUCCESS,
                                   f"walked {walked:.3f} m of {goal.distance:.3f} m ({corrections} corrections)")
            remaining = abs(to_go)
            if now - last_command >= command_period:
                last_command = now
                lateral = float(np.cross(forward, np.array([odom.pose.pose.position.x, odom.pose.pose.position.y]) - start))
                yaw_error = wrap_angle(heading - yaw_of(_quat_wxyz(odom)))
                vx = sign * min(speed, self._param("stop_gain") * remaining + 0.02)
                self._command(vx, wz=float(np.clip(1.0 * yaw_error - sign * 0.5 * lateral, -0.3, 0.3)))
            if now - last_feedback >= feedback_period:
                last_feedback = now
                state = self._state.latest.get()
                feedback = Walk.Feedback(distance_walked=walked, current_speed=odom.twist.twist.linear.x,
                                         steps_taken=steps.update(state.steps_taken) if state else steps.total,
                                         percent_complete=float(np.clip(100.0 * walked / goal.distance, 0.0, 100.0)))
                feedback.elapsed = duration_msg(now - start_time)
                goal_handle.publish_feedback(feedback)
            previous, odom = odom, self._next_odom()
            if self._jumped(previous, odom):
                self._command(0.0)
                self._raise_if_fresh(now - start_time, abs(walked))
                return finish_goal(self, goal_handle, result, Walk.Result.SIM_FAULT,
                                   "the simulation was reset during the walk", abort=True)

    @staticmethod
    def _distance_along(odom: Odometry, start: np.ndarray, forward: np.ndarray) -> float:
        position = np.array([odom.pose.pose.position.x, odom.pose.pose.position.y])
        return float((position - start) @ forward)

    @staticmethod
    def _fill_walk(result: Walk.Result, odom: Odometry, walked: float) -> None:
        result.final_distance = walked
        result.final_pose = PoseStamped(header=odom.header, pose=odom.pose.pose)

    # ----- NavigateToPose ----------------------------------------------------------------
    def _validate_navigate(self, goal: NavigateToPose.Goal) -> tuple[float, float, float]:
        p, o = goal.pose.pose.position, goal.pose.pose.orientation
        if not all(math.isfinite(v) for v in (p.x, p.y, p.z, o.x, o.y, o.z, o.w)):
            raise GoalRejected("goal pose has NaN or infinite values")
        if math.sqrt(o.x ** 2 + o.y ** 2 + o.z ** 2 + o.w ** 2) < 1e-6:
            raise GoalRejected("goal orientation quaternion cannot be normalised (norm 0)")
        if goal.pose.header.frame_id not in WORLD_FRAMES:
            raise GoalRejected(f"unknown frame {goal.pose.header.frame_id!r}; allowed: {', '.join(f or '(empty)' for f in WORLD_FRAMES)}")
        return p.x, p.y, yaw_of(np.array([o.w, o.x, o.y, o.z]))

    def _plan(self, x: float, y: float, goal_xy: tuple[float, float]) -> list[tuple[float, float]]:
        waited = 0.0
        while self._map.get() is None and waited < ACK_TIMEOUT_S:
            self._map.wait_next(0.1)
            waited += 0.1
        grid_msg = self._map.get()
        if grid_msg is None:
            raise NoPathError("no /map received from /sim")
        inflation = self._param("robot_radius") + self._param("obstacle_detection_threshold")
        return plan_path(grid_from_msg(grid_msg).inflated(inflation), (x, y), goal_xy)

    def _execute_navigate(self, goal_handle: ServerGoalHandle) -> NavigateToPose.Result:
        return self._execute_restartable(goal_handle, NavigateToPose, self._supervise_navigate, "navigation")

    def _supervise_navigate(self, goal_handle: ServerGoalHandle, goal: NavigateToPose.Goal, owner: ActiveGoal,
                            result: NavigateToPose.Result) -> NavigateToPose.Result:
        codes = NavigateToPose.Result
        gx, gy, gyaw = self._validate_navigate(goal)
        inputs = self._wait_inputs()
        if inputs is None:
            return finish_goal(self, goal_handle, result, codes.SIM_FAULT,
                               "no /odom or /sim/locomotion_state: is /sim running with the g1?", abort=True)
        odom, _ = inputs
        x, y = odom.pose.pose.position.x, odom.pose.pose.position.y
        start_x, start_y = x, y
        try:
            path = self._plan(x, y, (gx, gy))
        except NoPathError as error:
            code = codes.GOAL_IN_OBSTACLE if "inside an obstacle" in str(error) else codes.NO_VALID_PATH
            result.final_pose = PoseStamped(header=odom.header, pose=odom.pose.pose)
            return finish_goal(self, goal_handle, result, code, str(error), abort=True)
        follower = self._follower(path, gyaw)
        start_time = seconds_of(odom.header.stamp)
        timeout = path_length(path) / self._param("walking_speed") * 3.0 + 30.0
        recoveries = 0
        command_period = 1.0 / self._param("command_rate")
        feedback_period = 1.0 / self._param("feedback_rate")
        last_command = last_feedback = -math.inf
        last_progress_time, best_remaining = start_time, math.inf
        while True:
            result.final_pose = PoseStamped(header=odom.header, pose=odom.pose.pose)
            finished = self._interrupted(goal_handle, owner, result, codes)
            if finished is not None:
                return finished
            now = seconds_of(odom.header.stamp)
            fell = self._fallen(odom, self._state.latest.get())
            if fell:
                self._command(0.0)
                return finish_goal(self, goal_handle, result, codes.FELL, f"fell while navigating: {fell}", abort=True)
            if now - start_time > timeout:
                self._stop_and_settle()
                return finish_goal(self, goal_handle, result, codes.TIMEOUT,
                                   f"timed out after {timeout:.0f} s of sim time", abort=True)
            x, y = odom.pose.pose.position.x, odom.pose.pose.position.y
            yaw = yaw_of(_quat_wxyz(odom))
            speed = self._param("walking_speed")
            command = follower.command(x, y, yaw, speed, self._param("max_yaw_rate"))
            if command.distance_remaining < best_remaining - 0.05:
                best_remaining, last_progress_time = command.distance_remaining, now
            blocked = command.phase == "follow" and now - last_progress_time > 15.0
            if command.cross_track_error > self._param("replan_distance") or blocked:
                recoveries += 1
                try:
                    path = self._plan(x, y, (gx, gy))
                except NoPathError as error:
                    self._stop_and_settle()
                    return finish_goal(self, goal_handle, result, codes.NO_VALID_PATH, f"replanning failed: {error}", abort=True)
                follower = self._follower(path, gyaw)
                last_progress_time, best_remaining = now, math.inf
                continue
            if command.phase == "arrived":
                self._stop_and_settle()
                odom = self._odom.latest.get() or odom
                result.final_pose = PoseStamped(header=odom.header, pose=odom.pose.pose)
                error = math.dist((odom.pose.pose.position.x, odom.pose.pose.position.y), (gx, gy))
                return finish_goal(self, goal_handle, result, codes.SUCCESS,
                                   f"arrived {error:.2f} m from the goal after {recoveries} recoveries")
            if now - last_command >= command_period:
                last_command = now
                self._command(command.vx, wz=command.wz)
            if now - last_feedback >= feedback_period:
                last_feedback = now
                feedback = NavigateToPose.Feedback(number_of_recoveries=recoveries,
                                                   distance_remaining=float(command.distance_remaining),
                                                   message=command.phase)
                feedback.current_pose = PoseStamped(header=odom.header, pose=odom.pose.pose)
                feedback.navigation_time = duration_msg(now - start_time)
                feedback.estimated_time_remaining = duration_msg(command.distance_remaining / max(speed, 1e-3))
                goal_handle.publish_feedback(feedback)
            previous, odom = odom, self._next_odom()
            if self._jumped(previous, odom):
                self._command(0.0)
                self._raise_if_fresh(now - start_time, math.dist((x, y), (start_x, start_y)))
                return finish_goal(self, goal_handle, result, codes.SIM_FAULT,
                                   "the simulation was reset during the navigation", abort=True)

    def _follower(self, path: list[tuple[float, float]], goal_yaw: float) -> PathFollower:
        return PathFollower(path, goal_yaw, xy_tolerance=self._param("xy_goal_tolerance"),
                            yaw_tolerance=self._param("yaw_goal_tolerance"))


def _quat_wxyz(odom: Odometry) -> np.ndarray:
    o = odom.pose.pose.orientation
    return np.array([o.w, o.x, o.y, o.z])


def main(args: list[str] | None = None) -> int:
    """Console entry point: ``locomotion_server`` (asks /sim for its robot)."""
    return spin_server(lambda robot, overrides: LocomotionServer(robot, parameter_overrides=overrides), NODE_NAME, args)


if __name__ == "__main__":
    sys.exit(main())
