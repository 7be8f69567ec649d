"""What the running goals show a viewer: the planned path on ``/plan`` (nav_msgs/Path, Nav2's name) and
``/goal_markers`` (visualization_msgs/MarkerArray: the path as a line, goal poses as arrows, the planned
footsteps as boxes, the cells the robot's centre keeps out of (obstacles grown by their clearance) as a
faint red layer, targets as spheres), in the ``world`` frame (on /tf). Published when a goal starts or ends
(cleared when none runs), and when what a running goal shows changes, at most every ``CHANGE_PERIOD_S``;
latched, so a viewer that connects later sees what runs now."""

from __future__ import annotations

import math
from collections.abc import Iterable

from geometry_msgs.msg import Point, PoseStamped
from nav_msgs.msg import Path
from rclpy.node import Node
from visualization_msgs.msg import Marker, MarkerArray

from sim_bridge.skills import GoalVisuals, SkillRun, SkillStatus, visuals_of
from sim_ros.names import GOAL_MARKERS_TOPIC, LATCHED, PLAN_TOPIC
from sim_ros.stamps import set_time

FRAME = "world"
PATH_WIDTH_M = 0.03
ARROW_SIZE_M = (0.4, 0.06, 0.06)  # length, shaft and head widths of a goal pose's arrow
TARGET_DIAMETER_M = 0.05
PATH_HEIGHT_M = 0.01  # just above the floor
SOLE_SIZE_M = (0.2, 0.07, 0.01)  # a planned footstep drawn as a flat box of about a sole's size (orientation not drawn)
# The shortest time between two publications for changes of the running goals' visuals [s of sim time]. A walk
# re-plans its footsteps every step: built and published at every change, the markers (a keep-out layer of
# thousands of cells) took 30% of /sim's CPU during a lock-stepped fetch (py-spy).
CHANGE_PERIOD_S = 0.25


class GoalVisualsPublisher:
    """Publishes the running goals' :class:`GoalVisuals` whenever they change (under the simulation's lock)."""

    def __init__(self, node: Node) -> None:
        self._plan_pub = node.create_publisher(Path, PLAN_TOPIC, LATCHED)
        self._markers_pub = node.create_publisher(MarkerArray, GOAL_MARKERS_TOPIC, LATCHED)
        self._shown: dict[tuple[str, int], GoalVisuals] = {}
        self._goals: set[tuple[str, int]] = set()  # the running goals when the visuals were last read
        self._read_at = -math.inf  # sim time the visuals were last read [s]

    def update(self, runs: Iterable[SkillRun], now: float) -> None:
        """Publish if the running goals changed, or (read at most every ``CHANGE_PERIOD_S``) what they show."""
        running = [run for run in runs if run.status is SkillStatus.RUNNING and run.skill is not None]
        goals = {(run.resource, run.seq) for run in running}
        if goals == self._goals and 0.0 <= now - self._read_at < CHANGE_PERIOD_S:  # (sim time may restart at 0)
            return
        self._goals, self._read_at = goals, now
        current = {}
        for run in running:
            visuals = visuals_of(run.skill)
            if visuals is not None:
                current[(run.resource, run.seq)] = visuals
        if current == self._shown:
            return
        self._shown = current
        self._plan_pub.publish(self._path(current.values(), now))
        self._markers_pub.publish(self._markers(current, now))

    @staticmethod
    def _path(shown: Iterable[GoalVisuals], now: float) -> Path:
        path = Path()
        path.header.frame_id = FRAME
        set_time(path.header.stamp, now)
        for visuals in shown:
            for x, y in visuals.path_xy:
                pose = PoseStamped()
                pose.header = path.header
                pose.pose.position.x, pose.pose.position.y = x, y
                pose.pose.orientation.w = 1.0
                path.poses.append(pose)
            if visuals.path_xy:
                break  # one robot walks one path
        return path

    @staticmethod
    def _markers(shown: dict[tuple[str, int], GoalVisuals], now: float) -> MarkerArray:
        clear = Marker(action=Marker.DELETEALL)
        clear.header.frame_id = FRAME
        markers = [clear]

        def marker(namespace: str, seq: int, kind: int) -> Marker:
            m = Marker(ns=namespace, id=seq & 0x7FFFFFFF, type=kind, action=Marker.ADD)
            m.header.frame_id = FRAME
            set_time(m.header.stamp, now)
            m.pose.orientation.w = 1.0
            m.color.a = 0.9
            return m

        for (resource, seq), visuals in sorted(shown.items()):
            if visuals.path_xy:
                line = marker(f"{resource}/path", seq, Marker.LINE_STRIP)
                line.scale.x = PATH_WIDTH_M
                line.color.g, line.color.b = 0.8, 1.0
                line.points = [Point(x=x, y=y, z=PATH_HEIGHT_M) for x, y in visuals.path_xy]
                markers.append(line)
            if visuals.goal_pose is not None:
                x, y, yaw = visuals.goal_pose
                arrow = marker(f"{resource}/goal", seq, Marker.ARROW)
                arrow.pose.position.x, arrow.pose.position.y, arrow.pose.position.z = x, y, PATH_HEIGHT_M
                arrow.pose.orientation.z, arrow.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
                arrow.scale.x, arrow.scale.y, arrow.scale.z = ARROW_SIZE_M
                arrow.color.g = 1.0
                markers.append(arrow)
            if visuals.footsteps:
                soles = marker(f"{resource}/footsteps", seq, Marker.CUBE_LIST)
                soles.scale.x, soles.scale.y, soles.scale.z = SOLE_SIZE_M
                soles.color.r, soles.color.g, soles.color.b = 0.2, 0.4, 1.0
                soles.points = [Point(x=x, y=y, z=SOLE_SIZE_M[2] / 2) for x, y, _ in visuals.footsteps]
                markers.append(soles)
            if visuals.keep_out_xy:
                keep_out = marker(f"{resource}/keep_out", seq, Marker.CUBE_LIST)
                keep_out.scale.x = keep_out.scale.y = visuals.keep_out_cell_m
                keep_out.scale.z = 0.002
                keep_out.color.r, keep_out.color.a = 1.0, 0.25
                keep_out.points = [Point(x=x, y=y, z=0.001) for x, y in visuals.keep_out_xy]
                markers.append(keep_out)
            if visuals.target_xyz is not None:
                sphere = marker(f"{resource}/target", seq, Marker.SPHERE)
                sphere.pose.position.x, sphere.pose.position.y, sphere.pose.position.z = visuals.target_xyz
                sphere.scale.x = sphere.scale.y = sphere.scale.z = TARGET_DIAMETER_M
                sphere.color.r, sphere.color.g = 1.0, 0.6
                markers.append(sphere)
        return MarkerArray(markers=markers)
