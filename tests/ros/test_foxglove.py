"""``bringup --foxglove``: the Foxglove app's WebSocket protocol, spoken by a plain client in this process."""

from __future__ import annotations

import json
import pathlib
import socket
import struct
import time
import xml.etree.ElementTree as ET
from typing import Any

import pytest
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage
from websockets.sync.client import ClientConnection, connect

from tests.ros.processes import running

pytestmark = pytest.mark.slow

SUBPROTOCOL = "foxglove.sdk.v1"  # foxglove-sdk 0.30's name for the protocol (once foxglove.websocket.v1)
MESSAGE_DATA = 0x01  # binary opcodes of the protocol, server to client
FETCH_ASSET_RESPONSE = 0x04


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def connected(port: int, deadline_s: float) -> ClientConnection:
    end = time.monotonic() + deadline_s
    while True:
        try:
            return connect(f"ws://127.0.0.1:{port}", subprotocols=[SUBPROTOCOL], open_timeout=5)  # type: ignore[list-item]
        except OSError:
            if time.monotonic() > end:
                raise
            time.sleep(0.2)  # the bridge is not listening yet: poll again


def until(ws: ClientConnection, found: Any, deadline_s: float, what: str) -> Any:
    """Read frames until ``found(frame)`` returns something."""
    end = time.monotonic() + deadline_s
    while time.monotonic() < end:
        frame = ws.recv(timeout=max(0.1, end - time.monotonic()))
        value = found(frame)
        if value is not None:
            return value
    raise AssertionError(f"no {what} within {deadline_s} s")


def test_the_foxglove_app_sees_the_robot_its_frames_and_its_meshes(client):
    port = free_port()
    with running(["bringup", "--robot", "panda", "--rtf", "1", "--foxglove", "--foxglove-port", str(port)]):
        with connected(port, 90.0) as ws:
            assert ws.subprotocol == SUBPROTOCOL
            channels: dict[str, dict] = {}

            def advertised(frame: Any) -> dict | None:
                if isinstance(frame, str):
                    message = json.loads(frame)
                    if message.get("op") == "advertise":
                        channels.update({c["topic"]: c for c in message["channels"]})
                wanted = ("/tf", "/robot_description", "/joint_states", "/clock")
                return channels if all(topic in channels for topic in wanted) else None

            until(ws, advertised, 60.0, "advertised /tf, /robot_description, /joint_states, /clock")
            assert channels["/tf"]["encoding"] == "cdr" and channels["/tf"]["schemaEncoding"] == "ros2msg"
            assert channels["/tf"]["schemaName"] == "tf2_msgs/msg/TFMessage"

            def bridge_reads(topic: str) -> bool:
                return any(info.node_name == "foxglove_bridge" for info in client.node.get_subscriptions_info_by_topic(topic))

            assert not bridge_reads("/tf"), "a topic nobody watches is not taken from ROS"
            ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                {"id": 1, "channelId": channels["/tf"]["id"]}, {"id": 2, "channelId": channels["/robot_description"]["id"]},
                {"id": 3, "channelId": channels["/joint_states"]["id"]}]}))
            client.wait_for(lambda: bridge_reads("/tf"), 30.0, "the bridge to subscribe to /tf once watched")
            received: dict[int, bytes] = {}

            def data(frame: Any) -> dict | None:
                if isinstance(frame, bytes) and frame[0] == MESSAGE_DATA:
                    subscription, _log_time = struct.unpack_from("<IQ", frame, 1)
                    received[subscription] = frame[13:]
                return received if {1, 2, 3} <= set(received) else None

            until(ws, data, 60.0, "messages of /tf, /robot_description and /joint_states")
            joints = deserialize_message(received[3], JointState)
            assert "panda_joint1" in joints.name and len(joints.position) == len(joints.name)
            tf = deserialize_message(received[1], TFMessage)
            assert tf.transforms and tf.transforms[0].header.frame_id
            urdf = ET.fromstring(deserialize_message(received[2], String).data)
            mesh = next(m.get("filename") for m in urdf.iter("mesh"))

            def asset(request_id: int) -> Any:
                def response(frame: Any) -> tuple[int, bytes] | None:
                    if isinstance(frame, bytes) and frame[0] == FETCH_ASSET_RESPONSE:
                        got_id, status, length = struct.unpack_from("<IBI", frame, 1)
                        if got_id == request_id:
                            return status, frame[10 + length:] if status == 0 else frame[10:10 + length]
                    return None
                return response

            ws.send(json.dumps({"op": "fetchAsset", "uri": mesh, "requestId": 7}))
            status, body = until(ws, asset(7), 30.0, "the mesh")
            assert status == 0 and body == pathlib.Path(mesh.removeprefix("file://")).read_bytes()
            ws.send(json.dumps({"op": "fetchAsset", "uri": "file:///etc/passwd", "requestId": 8}))
            status, _ = until(ws, asset(8), 30.0, "an answer for a file outside the robot models")
            assert status != 0, "nothing but the robot models' files is served"
            ws.send(json.dumps({"op": "unsubscribe", "subscriptionIds": [1]}))
            client.wait_for(lambda: not bridge_reads("/tf"), 30.0, "the bridge to let /tf go once nobody watches it")
