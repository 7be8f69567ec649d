"""What ``/sim`` publishes at its publication stops, and when: ``/clock``, ``/joint_states``, ``/odom``, ``/tf``, ``/objects``.

Each stream has a rate in sim time and falls due on its own grid. Only ``/clock`` and ``/joint_states``
(and any stream faster than both) set the stops the physics is stepped to; a slower stream rides along:
it is published at the first stop at or after it falls due, stamped with that exact sim time, so its
mean rate is unchanged and it adds no stop. ``/clock`` and ``/joint_states`` are serialized once and
only their numbers are written at each publish; the other streams are built only while someone
subscribes to them. The scene's fixed facts (``world -> odom``, the G1's ``/map``) go out once, latched.
"""

from __future__ import annotations

import array
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
from geometry_msgs.msg import Pose as PoseMsg, TransformStamped
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg, Odometry
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, String
from tf2_msgs.msg import TFMessage

from nodes.sim.serialized import (
    ClockTemplate,
    JointStateTemplate,
    OdometryTemplate,
    TemplateError,
    TransformTemplate,
    odometry_message,
    stamp_of,
    transform_message,
)
from nodes.sim.tf import TransformSet, link_pairs
from sim_bridge import Simulation
from sim_bridge.navigation import grid_from_obstacles
from sim_bridge.urdf import robot_urdf
from sim_interfaces.msg import ObjectStates
from sim_ros.conversions import occupancy_grid_msg
from sim_ros.names import (
    CLOCK_TOPIC,
    JOINT_STATES_TOPIC,
    LATCHED,
    MAP_TOPIC,
    OBJECTS_TOPIC,
    ODOM_TOPIC,
    ROBOT_DESCRIPTION_TOPIC,
    STREAMS,
    TF_STATIC_TOPIC,
    TF_TOPIC,
)
from sim_ros.stamps import set_time

STOP_STREAMS = ("clock", "joint_states")  # the streams that set the stepping stops
# A reliable writer keeps this many samples for a slow reader: stepped as fast as possible, /sim publishes
# in bursts a recorder on a busy machine must not lose. /clock and /joint_states keep STREAM_HISTORY_S of
# sim time at their fastest rate (sim_ros.names.STREAMS: a reader stalled for less loses nothing), the
# other streams 1000 samples (5 s at 200 Hz).
RELIABLE = QoSProfile(depth=1000)


@dataclass
class _Schedule:
    """Next sim time [s] at which each stream is due."""

    clock: float = 0.0
    joint_states: float = 0.0
    odom: float = 0.0
    link_tf: float = 0.0
    state: float = 0.0


class Publications:
    """The streams of one simulation and their schedule.

    Args:
        node: the sim node (the publishers are created on it).
        sim: its simulation.
        publish_state: called when the state streams fall due (the in-loop controllers' topics), with the sim time.
    """

    def __init__(self, node: Node, sim: Simulation, publish_state: Callable[[float], None]) -> None:
        self._sim = sim
        self._publish_state = publish_state
        self._periods: dict[str, float] = {}
        self._stops: tuple[str, ...] = ()
        self._schedule = _Schedule()
        self._next_stop = 0.0  # the earliest of the stop streams' due times [s]
        self._clock_pub = node.create_publisher(Clock, CLOCK_TOPIC, STREAMS)
        self._joint_pub = node.create_publisher(JointState, JOINT_STATES_TOPIC, STREAMS)
        self._odom_pub = node.create_publisher(Odometry, ODOM_TOPIC, RELIABLE)
        self._tf_pub = node.create_publisher(TFMessage, TF_TOPIC, RELIABLE)  # 25 s at 40 Hz for a reader that lags
        self._tf_static_pub = node.create_publisher(TFMessage, TF_STATIC_TOPIC, LATCHED)
        self._rtf_pub = node.create_publisher(Float64, "~/real_time_factor", RELIABLE)
        self._objects_pub = node.create_publisher(ObjectStates, OBJECTS_TOPIC, RELIABLE)
        self._description_pub = node.create_publisher(String, ROBOT_DESCRIPTION_TOPIC, LATCHED)
        self._description_pub.publish(String(data=robot_urdf(sim.model, sim.robot)))

        robot = sim.robot
        self._clock_msg = Clock()
        self._joint_msg = JointState()
        self._joint_msg.name = list(robot.actuated_joints)
        try:  # the two streams published at every stop: serialized once, numbers patched in
            self._clock_template: ClockTemplate | None = ClockTemplate()
            self._joint_template: JointStateTemplate | None = JointStateTemplate(list(robot.actuated_joints))
        except TemplateError as error:
            node.get_logger().warning(f"{error}; publishing {CLOCK_TOPIC} and {JOINT_STATES_TOPIC} the ordinary way")
            self._clock_template = self._joint_template = None
        self._odom_frame = "odom" if robot.floating_base else "world"
        self._base_frame = robot.base_body
        try:  # /odom and the odom -> base transform: serialized once, numbers patched in
            self._odom_template: OdometryTemplate | None = OdometryTemplate(self._odom_frame, self._base_frame)
            self._base_tf_template: TransformTemplate | None = TransformTemplate(self._odom_frame, self._base_frame)
        except TemplateError as error:
            node.get_logger().warning(f"{error}; publishing {ODOM_TOPIC} and the base's {TF_TOPIC} the ordinary way")
            self._odom_template = self._base_tf_template = None
        self._object_tf = TransformSet(sim, [("world", name) for name in robot.objects])
        self._link_tf = TransformSet(sim, link_pairs(sim))
        if robot.floating_base:
            self._map_pub = node.create_publisher(OccupancyGridMsg, MAP_TOPIC, LATCHED)
            self._map_pub.publish(occupancy_grid_msg(grid_from_obstacles(robot.obstacles)))
        self._objects_msg = ObjectStates(names=list(robot.objects), poses=[PoseMsg() for _ in robot.objects])
        self._objects_msg.header.frame_id = "world"
        if robot.floating_base:
            identity = TransformStamped()
            identity.header.frame_id = "world"
            identity.child_frame_id = "odom"
            identity.transform.rotation.w = 1.0
            self._tf_static_pub.publish(TFMessage(transforms=[identity]))

    # ----- the schedule --------------------------------------------------------------------
    def set_rates(self, rates: Mapping[str, float]) -> None:
        """Each stream's rate [Hz of sim time] (0 = off) by name: clock, joint_states, odom, link_tf, state."""
        self._periods = {name: 1.0 / rate if rate > 0 else math.inf for name, rate in rates.items()}
        fastest = min(self._periods[name] for name in STOP_STREAMS)
        self._stops = tuple(name for name, p in self._periods.items() if name in STOP_STREAMS or p < fastest)
        self._update_next_stop()

    def next_stop(self) -> float:
        """Sim time [s] of the next publication that stepping must stop for."""
        return self._next_stop

    def _update_next_stop(self) -> None:
        schedule = self._schedule
        self._next_stop = min((getattr(schedule, name) for name in self._stops), default=math.inf)

    def restart(self) -> None:
        """Every stream falls due again from t = 0 (sim time was reset)."""
        self._schedule = _Schedule()
        self._update_next_stop()

    # ----- publishing ----------------------------------------------------------------------
    def publish_due(self, now: float, force: bool = False) -> None:
        """Publish the streams due at ``now`` [s] (every stream if ``force``); under the simulation's lock."""
        sim = self._sim
        schedule = self._schedule
        periods = self._periods
        eps = 1e-9
        # A stream is published when due or forced; only a due one moves on along its grid (a forced
        # publication off the grid, e.g. at a reset, leaves the grid alone).
        due = now + eps >= schedule.clock
        if force or due:
            if self._clock_template is not None:
                self._clock_pub.publish(self._clock_template.serialize(now))
            else:
                set_time(self._clock_msg.clock, now)
                self._clock_pub.publish(self._clock_msg)
            if due:
                schedule.clock = next_due(schedule.clock, periods["clock"], now)
        due = now + eps >= schedule.joint_states
        if force or due:
            self._publish_joint_states(now)
            if due:
                schedule.joint_states = next_due(schedule.joint_states, periods["joint_states"], now)
        # The streams below are built and published only while someone subscribes; /clock and
        # /joint_states are always published (gated on the writer's subscriber count too, a lock-stepped
        # walk_2m's lowest base height differed run to run in tests/scenarios/test_determinism.py).
        due = now + eps >= schedule.odom
        if force or due:
            self._publish_odom(now)
            if due:
                schedule.odom = next_due(schedule.odom, periods["odom"], now)
        due = now + eps >= schedule.link_tf
        if len(self._link_tf) and (force or due):
            if self._tf_pub.get_subscription_count() > 0:
                self._tf_pub.publish(self._link_tf.update(sim.data, now))
            if due:
                schedule.link_tf = next_due(schedule.link_tf, periods["link_tf"], now)
        due = now + eps >= schedule.state
        if force or due:
            if len(self._object_tf):
                self._publish_objects(now)
            self._publish_state(now)
            if due:
                schedule.state = next_due(schedule.state, periods["state"], now)
        self._update_next_stop()

    def publish_rtf(self, factor: float) -> None:
        """``~/real_time_factor``: sim seconds per wall second."""
        self._rtf_pub.publish(Float64(data=factor))

    def _publish_joint_states(self, now: float) -> None:
        positions, velocities, efforts = self._sim.joint_arrays()
        if self._joint_template is not None:
            self._joint_pub.publish(self._joint_template.serialize(now, positions, velocities, efforts))
            return
        msg = self._joint_msg
        set_time(msg.header.stamp, now)
        # array.array takes the generated setters' fast path (no per-element checks).
        msg.position = _float64_array(positions)
        msg.velocity = _float64_array(velocities)
        msg.effort = _float64_array(efforts)
        self._joint_pub.publish(msg)

    def _publish_odom(self, now: float) -> None:
        """/odom and the odom -> base transform on /tf, each while someone subscribes."""
        odom_wanted = self._odom_pub.get_subscription_count() > 0
        tf_wanted = self._tf_pub.get_subscription_count() > 0
        if not (odom_wanted or tf_wanted):
            return
        base = self._sim.base_state()
        position, orientation = base.pose.position, base.pose.orientation_wxyz
        if odom_wanted:
            template = self._odom_template
            self._odom_pub.publish(
                template.serialize(now, position, orientation, base.linear_velocity_body, base.angular_velocity_body)
                if template is not None else
                odometry_message(self._odom_frame, self._base_frame, stamp_of(now), position, orientation,
                                 base.linear_velocity_body, base.angular_velocity_body))
        if tf_wanted:
            base_tf = self._base_tf_template
            self._tf_pub.publish(base_tf.serialize(now, position, orientation) if base_tf is not None else
                                 transform_message(self._odom_frame, self._base_frame, stamp_of(now), position, orientation))

    def _publish_objects(self, now: float) -> None:
        """World -> object transforms on /tf and /objects, each while someone subscribes."""
        tf_wanted = self._tf_pub.get_subscription_count() > 0
        objects_wanted = self._objects_pub.get_subscription_count() > 0
        if not (tf_wanted or objects_wanted):
            return
        tf = self._object_tf.update(self._sim.data, now)
        if tf_wanted:
            self._tf_pub.publish(tf)
        if not objects_wanted:
            return
        msg = self._objects_msg
        set_time(msg.header.stamp, now)
        for pose, transform in zip(msg.poses, tf.transforms, strict=False):
            t, r = transform.transform.translation, transform.transform.rotation
            pose.position.x, pose.position.y, pose.position.z = t.x, t.y, t.z
            pose.orientation.w, pose.orientation.x, pose.orientation.y, pose.orientation.z = r.w, r.x, r.y, r.z
        self._objects_pub.publish(msg)


def next_due(previous: float, period: float, now: float) -> float:
    """Next due time [s] on the period grid, skipping slots already in the past (never, for an infinite period)."""
    if math.isinf(period):
        return math.inf
    nxt = previous + period
    if nxt <= now:
        nxt = now + period - ((now - previous) % period)
    return nxt


def _float64_array(values: np.ndarray) -> array.array:
    result = array.array("d")
    result.frombytes(values.tobytes())  # MuJoCo's arrays are float64; tobytes copies in C order
    return result
