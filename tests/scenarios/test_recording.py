"""``recording.mcap`` is written by a recorder process of its own (sim_client.scenario.outputs.recorder_process):
it records what a real publisher in another process sends, closes its file when asked or when its runner is gone,
and a recorder that died is said, never taken for a recording."""

from __future__ import annotations

import os
import signal
import time

import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Header

from sim_client.scenario.outputs.recorder_process import RecordingError, RecordingProcess
from sim_client.scenario.outputs.recording import read_mcap_topics

TOPIC = "recording_test/header"  # a stamped type: the recorder follows its newest stamp


@pytest.fixture
def publishing(client):
    """``/recording_test/header`` published from the test's client at ~200 Hz, stamp = count / 100 [s], each after a
    ``/clock`` of the same time (the sim time the recorder follows)."""
    publisher = client.node.create_publisher(Header, TOPIC, 100)
    clock = client.node.create_publisher(Clock, "/clock", 100)
    sent = [0]

    def publish() -> None:
        sent[0] += 1
        message = Header(frame_id="test")
        message.stamp.sec, message.stamp.nanosec = divmod(sent[0], 100)[0], divmod(sent[0], 100)[1] * 10_000_000
        clock.publish(Clock(clock=message.stamp))
        publisher.publish(message)

    timer = client.node.create_timer(0.005, publish)
    yield sent
    client.node.destroy_timer(timer)
    client.node.destroy_publisher(publisher)
    client.node.destroy_publisher(clock)


def _wait_recorded(recording: RecordingProcess, topic: str, count: int, client) -> None:
    client.wait_for(lambda: recording.status().counts.get(topic, 0) >= count, 60.0, f"{count} messages on {topic} recorded")


def test_the_recorder_records_another_process_s_messages_and_closes_its_file(client, publishing, tmp_path):
    recording = RecordingProcess(tmp_path / "recording.mcap")
    _wait_recorded(recording, f"/{TOPIC}", 20, client)
    status = recording.status()
    assert status.latest_stamp_s[f"/{TOPIC}"] > 0.0
    final = recording.close()
    assert recording._process.poll() is not None, "the recorder still runs after close"
    assert final.counts[f"/{TOPIC}"] >= 20
    assert read_mcap_topics(tmp_path / "recording.mcap")[f"/{TOPIC}"] == final.counts[f"/{TOPIC}"]
    assert recording.status() is final  # answered from the final status, the process being gone
    # A stamped message is logged at its own stamp (the sim time it belongs to), not at its arrival.
    # (The recorder's sim time is the newest /clock; a stamp far from it, e.g. on wall time, is logged at that /clock.)
    with open(tmp_path / "recording.mcap", "rb") as stream:
        logged = [(message.log_time, message.publish_time, decoded.stamp.sec * 1_000_000_000 + decoded.stamp.nanosec)
                  for _schema, channel, message, decoded in make_reader(stream, decoder_factories=[DecoderFactory()])
                  .iter_decoded_messages() if channel.topic == f"/{TOPIC}"]
    assert len(logged) == final.counts[f"/{TOPIC}"]
    assert all(log_time == publish_time == stamp for log_time, publish_time, stamp in logged), logged[:5]


def test_a_recorder_whose_runner_is_gone_closes_its_file_and_exits(client, publishing, tmp_path):
    recording = RecordingProcess(tmp_path / "recording.mcap")
    _wait_recorded(recording, f"/{TOPIC}", 5, client)
    assert recording._process.stdin is not None
    recording._process.stdin.close()  # what the runner's exit does to the pipe
    code = recording._process.wait(timeout=30.0)
    assert code == 0, (tmp_path / "recorder.log").read_text()
    assert read_mcap_topics(tmp_path / "recording.mcap")[f"/{TOPIC}"] >= 5  # a finished, readable file


def test_a_recorder_that_died_is_said_with_its_log(tmp_path):
    recording = RecordingProcess(tmp_path / "recording.mcap")
    os.kill(recording._process.pid, signal.SIGKILL)
    recording._process.wait(timeout=30.0)
    started = time.monotonic()
    with pytest.raises(RecordingError, match="exited") as raised:
        recording.status()
    assert "recorder.log" in str(raised.value)
    with pytest.raises(RecordingError, match="did not close"):
        recording.close()
    assert time.monotonic() - started < 30.0  # said at once, not after the answer's deadline
