"""``recording.mcap``: every topic of a run, as rosbag2 writes it, so Foxglove and rosbag2 read it.

Serialized CDR with ROS 2 message definitions (profile ``ros2``, schema encoding ``ros2msg``);
action feedback and status included. The definitions are read from the installed interfaces.
"""

from __future__ import annotations

import pathlib
import struct
import threading
from typing import Any

from sim_ros.interfaces import import_type, matching_qos, message_definition

# A stamp further than this from the newest /clock [ns] is on another clock (a node on wall time stamps its log and
# parameter events with it): such a message is logged at the newest /clock instead. Lock-stepped, a stride's burst
# may bring a stream's messages up to a stride (1 s of sim time) ahead of /clock's.
STAMP_WINDOW_NS = 5_000_000_000


# ----- MCAP recording -----------------------------------------------------------------------
class McapRecorder:
    """Subscribes to every topic it discovers (raw CDR) and writes them into an MCAP file.

    Call :meth:`discover` now and then (new topics appear as nodes start); :meth:`close` at the
    end. Log and publish times [ns of sim time] are a message's own stamp where its type starts with one (a header,
    or /clock's time) within ``STAMP_WINDOW_NS`` of the newest /clock recorded, else that /clock: the sim time the
    message belongs to, read from the messages, so the recorder needs no /clock subscription of its own to keep time
    (one process less that /sim writes every /clock message to; /clock itself is recorded like any topic).
    """

    def __init__(self, session: Any, path: pathlib.Path, exclude: tuple[str, ...] = (), namespace: str = "") -> None:
        from mcap.writer import CompressionType, Writer

        self.session = session
        self.path = path
        self._stream = open(path, "wb")  # noqa: SIM115 - closed in close()
        self._writer = Writer(self._stream, compression=CompressionType.ZSTD)
        self._writer.start(profile="ros2", library="sim scenario runner")
        self._lock = threading.Lock()
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._subscriptions: dict[str, Any] = {}  # topic -> its subscription
        self._sequence = 0
        self._exclude = exclude
        self._prefix = f"{namespace}/" if namespace else ""  # a namespaced run records its own bring-up's topics only
        self.counts: dict[str, int] = {}
        self.latest_stamp_s: dict[str, float] = {}  # topic -> stamp [s] of the newest message, for stamped types
        self._stamped: set[str] = set()
        self._clock_topic = f"{namespace}/clock"
        self._clock_ns = 0  # the newest /clock recorded [ns of sim time]: the recorder's sim time, without a subscription
        self.skipped: dict[str, str] = {}
        self._closed = False

    def discover(self) -> None:
        from sim_ros.session import quiet_events

        node = self.session.node
        for topic, types in node.get_topic_names_and_types():
            if topic in self._channels or topic in self.skipped or topic in self._exclude or not types \
                    or not topic.startswith(self._prefix):
                continue
            type_name = types[0]
            try:
                msg_type = import_type(type_name)
                definition = message_definition(type_name)
            except (ImportError, AttributeError, KeyError, ValueError) as error:
                self.skipped[topic] = f"{type_name}: {error}"
                continue
            qos = matching_qos(node.get_publishers_info_by_topic(topic))
            with self._lock:
                if type_name not in self._schemas:
                    self._schemas[type_name] = self._writer.register_schema(type_name, "ros2msg", definition.encode())
                self._channels[topic] = self._writer.register_channel(topic, "cdr", self._schemas[type_name])
                self.counts[topic] = 0
                if _starts_with_stamp(msg_type):
                    self._stamped.add(topic)
            self._subscriptions[topic] = node.create_subscription(
                msg_type, topic, lambda data, topic=topic: self._on_message(topic, data), qos, raw=True,
                event_callbacks=quiet_events())

    def matched(self) -> dict[str, int]:
        """The publishers each recorded topic's subscription has matched, by topic."""
        return {topic: subscription.get_publisher_count() for topic, subscription in self._subscriptions.items()}

    def _on_message(self, topic: str, data: bytes) -> None:
        with self._lock:
            if self._closed:
                return
            if topic in self._stamped:
                stamp_ns = _cdr_leading_stamp_ns(data)
                self.latest_stamp_s[topic] = stamp_ns * 1e-9
                if topic == self._clock_topic:
                    self._clock_ns = stamp_ns  # (a reset takes sim time back to 0: the newest, not the largest)
                elif abs(stamp_ns - self._clock_ns) > STAMP_WINDOW_NS:
                    stamp_ns = self._clock_ns  # stamped on another clock (a node on wall time): at the sim time it came
            else:
                stamp_ns = self._clock_ns
            self._sequence += 1
            self._writer.add_message(self._channels[topic], log_time=stamp_ns, data=data, publish_time=stamp_ns,
                                     sequence=self._sequence)
            self.counts[topic] += 1

    def close(self) -> None:
        subscriptions, self._subscriptions = self._subscriptions, {}
        for subscription in subscriptions.values():
            self.session.destroy_subscription(subscription)
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._writer.finish()
            self._stream.close()


def _starts_with_stamp(msg_type: Any) -> bool:
    """Whether a message's first field is a time stamp (a ``std_msgs/Header`` or a ``builtin_interfaces/Time``)."""
    fields = list(msg_type.get_fields_and_field_types().values())
    return bool(fields) and fields[0] in ("std_msgs/Header", "builtin_interfaces/Time")


def _cdr_leading_stamp_ns(data: bytes) -> int:
    """The leading stamp [ns] of a serialized message that starts with one (sec int32, nanosec uint32); 0 before t = 0.

    Bytes 0-3 are the CDR encapsulation header; byte 1 says the byte order (1: little-endian).
    """
    order = "<" if data[1] == 1 else ">"
    sec, nanosec = struct.unpack_from(order + "iI", data, 4)
    return max(0, sec * 1_000_000_000 + nanosec)


def read_mcap_topics(path: pathlib.Path) -> dict[str, int]:
    """Message count per topic of an MCAP file (decodes every message to check it reads)."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    counts: dict[str, int] = {}
    with open(path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        for _schema, channel, _message, _decoded in reader.iter_decoded_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    return counts
