"""The ``/foxglove_bridge`` node: the ROS topics a person watches, live in the Foxglove app.

It serves Foxglove's WebSocket protocol (subprotocol ``foxglove.websocket.v1``, through the
``foxglove-sdk`` package; ``foxglove_bridge``, the usual C++ node, is not on PyPI) on ``host``:``port``
(default 127.0.0.1:8765: this machine only). Each watched topic that exists is advertised as a channel
with its ROS 2 schema (``ros2msg``) and its messages are forwarded as they come, serialized (CDR, never
decoded here), logged at their sim time. Topics that appear later (a camera started, a goal's
markers) are picked up within ``DISCOVERY_PERIOD_S``. A topic is taken from ROS only while a client
watches it (latched ones always, to hand a late client their message): with nobody watching, the bridge
costs next to nothing.

Meshes: Foxglove asks the server for the files ``/robot_description`` names (``file://`` URIs); only
files below the robot models' directory (example-robot-data's) are served, nothing else on disk.

Nothing is bridged back: clients cannot publish, call services or set parameters through it.
"""

from __future__ import annotations

import pathlib
import sys
import threading
from collections.abc import Callable
from typing import Any

from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy

from nodes.runtime.parameters import ParameterSpec, declare
from nodes.runtime.serve import spin_server
from sim_ros.interfaces import import_type, matching_qos, message_definition
from sim_ros.names import (
    CLOCK_TOPIC,
    GOAL_MARKERS_TOPIC,
    JOINT_STATES_TOPIC,
    MAP_TOPIC,
    OBJECTS_TOPIC,
    ODOM_TOPIC,
    PLAN_TOPIC,
    ROBOT_DESCRIPTION_TOPIC,
    TF_STATIC_TOPIC,
    TF_TOPIC,
)

NODE_NAME = "foxglove_bridge"
DISCOVERY_PERIOD_S = 1.0  # [s of wall time] between looks for watched topics not bridged yet
DEFAULT_PORT = 8765  # Foxglove's default
# What a person watches: the robot (description, frames, joints, odometry), the scene (map, objects),
# the goals (plan, markers), and the sensors and power when the robot has them.
WATCHED_TOPICS = (
    ROBOT_DESCRIPTION_TOPIC, TF_TOPIC, TF_STATIC_TOPIC, JOINT_STATES_TOPIC, ODOM_TOPIC, CLOCK_TOPIC, MAP_TOPIC,
    OBJECTS_TOPIC, PLAN_TOPIC, GOAL_MARKERS_TOPIC, "imu", "battery_state", "head_camera/image_raw",
    "head_camera/camera_info", "scene_camera/image_raw", "scene_camera/camera_info",
)


def _asset_root() -> pathlib.Path:
    from robot_models.spec import example_robot_data_root

    return example_robot_data_root().resolve()


def mesh_asset(uri: str, root: pathlib.Path) -> bytes | None:
    """The bytes of a ``file://`` mesh below ``root``, or None (anything else is not served)."""
    if not uri.startswith("file://"):
        return None
    path = pathlib.Path(uri.removeprefix("file://")).resolve()
    if not path.is_file() or not path.is_relative_to(root):
        return None
    return path.read_bytes()


class FoxgloveBridge(Node):
    """Bridges the watched topics to Foxglove's WebSocket protocol (see the module's text)."""

    def __init__(self, robot: str, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        import foxglove

        declare(self, (
            ParameterSpec("robot", robot, "robot whose topics are bridged", read_only=True),
            ParameterSpec("host", "127.0.0.1", "address the WebSocket server listens on (0.0.0.0: every network; "
                          "anyone who reaches it sees the bridged topics)", read_only=True),
            ParameterSpec("port", DEFAULT_PORT, "TCP port of the WebSocket server (0: any free port)", 0, 65535,
                          read_only=True),
        ))
        self._foxglove = foxglove
        self._watched = [self.resolve_topic_name(topic) for topic in WATCHED_TOPICS]  # under the node's namespace
        root = _asset_root()
        self._latched: dict[str, bytes] = {}  # topic -> its latest message, for a latched topic
        self._channels: dict[str, Any] = {}
        self._sources: dict[str, tuple[Any, Any, bool]] = {}  # topic -> (message type, QoS, latched)
        self._watchers: dict[str, int] = {}  # topic -> Foxglove subscriptions to it now
        self._ros_subscriptions: dict[str, Any] = {}
        self._lock = threading.Lock()
        self._server = foxglove.start_server(
            name=f"sim {robot}", host=str(self.get_parameter("host").value), port=int(self.get_parameter("port").value),
            asset_handler=lambda uri: mesh_asset(uri, root), server_listener=self._listener())
        self.create_timer(DISCOVERY_PERIOD_S, self._discover, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(f"Foxglove WebSocket server on {self.get_parameter('host').value}:{self._server.port} "
                               f"(open it in Foxglove: ws://HOST:{self._server.port})")
        self._discover()

    @property
    def port(self) -> int:
        return int(self._server.port)

    def _discover(self) -> None:
        known = dict(self.get_topic_names_and_types())
        for topic in self._watched:
            if topic in self._channels or not known.get(topic):
                continue
            publishers = self.get_publishers_info_by_topic(topic)
            if not publishers:  # named by a subscriber only so far: the QoS (latched or not) is its publishers', later
                continue
            type_name = known[topic][0]
            try:
                msg_type = import_type(type_name)
                definition = message_definition(type_name)
            except (ImportError, AttributeError, KeyError, ValueError) as error:
                self.get_logger().warning(f"{topic} ({type_name}) is not bridged: {error}")
                self._channels[topic] = None
                continue
            schema = self._foxglove.Schema(name=type_name, encoding="ros2msg", data=definition.encode())
            channel = self._foxglove.Channel(topic, schema=schema, message_encoding="cdr")
            self._channels[topic] = channel
            qos = matching_qos(publishers, depth=10)
            latched = qos.durability == DurabilityPolicy.TRANSIENT_LOCAL
            with self._lock:
                self._sources[topic] = (msg_type, qos, latched)
                if latched or self._watchers.get(topic, 0) > 0:  # latched: always, to hand a late client its message
                    self._subscribe(topic)

    def _subscribe(self, topic: str) -> None:
        """Under the lock: take the topic from ROS (once)."""
        from sim_ros.session import quiet_events

        if topic in self._ros_subscriptions or topic not in self._sources:
            return
        msg_type, qos, latched = self._sources[topic]
        self._ros_subscriptions[topic] = self.create_subscription(
            msg_type, topic, self._forwarder(topic, self._channels[topic], latched), qos, raw=True,
            event_callbacks=quiet_events())

    def _watch(self, topic: str, change: int) -> None:
        """A Foxglove client subscribed (+1) or unsubscribed (-1): a topic nobody watches is not taken from ROS."""
        with self._lock:
            self._watchers[topic] = max(0, self._watchers.get(topic, 0) + change)
            if self._watchers[topic] > 0:
                self._subscribe(topic)
            elif topic in self._ros_subscriptions and not self._sources[topic][2]:
                self.destroy_subscription(self._ros_subscriptions.pop(topic))

    def _forwarder(self, topic: str, channel: Any, latched: bool) -> Callable[[bytes], None]:
        def forward(data: bytes) -> None:
            if latched:
                self._latched[topic] = data
            channel.log(data, log_time=self._log_time())
        return forward

    def _log_time(self) -> int | None:
        """Sim time [ns] now, or None (the server's own clock) before the first /clock came."""
        now = self.get_clock().now().nanoseconds
        return now if now > 0 else None

    def _listener(self) -> Any:
        """Takes a topic from ROS while a client watches it, and sends a latched topic's latest message to a client
        that subscribes (as a ROS subscriber with transient-local durability gets it): the robot description, the
        map and the plan come at once."""
        bridge = self

        class Listener(self._foxglove.websocket.ServerListener):  # type: ignore[name-defined]
            def on_subscribe(self, client: Any, channel: Any) -> None:
                bridge._watch(channel.topic, +1)
                data = bridge._latched.get(channel.topic)
                if data is not None:
                    bridge._channels[channel.topic].log(data, log_time=bridge._log_time())

            def on_unsubscribe(self, client: Any, channel: Any) -> None:
                bridge._watch(channel.topic, -1)

        return Listener()

    def stop(self) -> None:
        self._server.stop()


def main(args: list[str] | None = None) -> int:
    """Console entry point: ``foxglove_bridge`` (asks /sim for its robot)."""

    def build(robot: str, _scene: str, overrides: list[Any]) -> Node:
        return FoxgloveBridge(robot, parameter_overrides=overrides)

    def before_exit(node: Node, _executor: Any) -> None:
        if isinstance(node, FoxgloveBridge):
            node.stop()

    return spin_server(build, NODE_NAME, args, before_exit=before_exit)


if __name__ == "__main__":
    sys.exit(main())
