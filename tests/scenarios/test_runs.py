"""Scenario runs end to end: real processes over Fast DDS, lock-stepped on sim time, headless."""

from __future__ import annotations

import io
import json
import pathlib
import subprocess
import textwrap

import pytest

from sim_client.scenario.model import schema
from sim_client.scenario.outputs import recording
from sim_client.scenario.running.bringups import CLOCK_RATE_HZ, JOINT_STATE_RATE_HZ, Bringups
from sim_client.scenario.running.options import RunOptions
from sim_client.scenario.running.runner import run
from sim_ros.processes import BIN

STAND = """\
name: stand_short
robot: g1
steps:
  - reset: {}
    mark: standing
  - wait: {duration: 1.0}
expect:
  - name: never fell
    measure: {base_height_min: {from: standing}}
    gte: 0.6
  - name: pelvis height
    measure: {base_position: {axis: z}}
    near: 0.76
    tol: 0.08
  - name: one second passed
    measure: {duration: {from: standing, to: end}}
    near: 1.0
    tol: 0.03
"""


def scenario_file(tmp_path: pathlib.Path, text: str, name: str = "case") -> pathlib.Path:
    path = tmp_path / f"{name}.yaml"
    path.write_text(textwrap.dedent(text))
    return path


def run_quietly(path: pathlib.Path, out: pathlib.Path, bringups: Bringups | None = None, **options) -> object:
    return run(schema.load(path), RunOptions(out=out, quiet=True, **options), stream=io.StringIO(), bringups=bringups)


@pytest.fixture(scope="module")
def bringups():
    """The runs of this file in one bring-up while they have the same robot and scene (reset between runs, as
    ``scenario run A B C`` does; tests/scenarios/test_determinism.py shows the reports are those of fresh nodes)."""
    with Bringups(io.StringIO(), quiet=True) as shared:
        yield shared


def test_a_sim_only_scenario_runs_headless_with_a_json_report_and_an_mcap(tmp_path, bringups):
    result = run_quietly(schema.find("reset_and_stand_panda"), tmp_path, bringups, record=True)
    assert result.passed, result.report
    report = json.loads((result.folder / "report.json").read_text())
    assert report["passed"] is True and report["robot"] == "panda" and report["mode"] == "lock-step"
    assert report["sim_time_s"] == pytest.approx(2.0, abs=0.1)
    assert report["wall_time_s"] > 0 and report["wall_per_sim"] > 0
    names = [e["name"] for e in report["expectations"]]
    assert "box_1 rests at its home position" in names
    assert all(e["passed"] for e in report["expectations"])
    measured = {e["name"]: e["measured"] for e in report["expectations"]}
    assert measured["elbow at the home angle"] == pytest.approx(-2.356, abs=0.02)

    counts = recording.read_mcap_topics(pathlib.Path(report["artifacts"]["mcap"]))
    for topic in ("/clock", "/joint_states", "/odom", "/objects", "/tf", "/robot_description"):
        assert counts.get(topic, 0) > 0, f"{topic} missing from the MCAP: {counts}"  # the robot plays back in 3D
    # 2 s of sim time at the scenario bring-up's /clock and /joint_states rates
    assert counts["/clock"] >= 1.9 * CLOCK_RATE_HZ and counts["/joint_states"] >= 1.9 * JOINT_STATE_RATE_HZ
    assert "/scene_camera/image_raw" not in counts, "a run not asked for the camera leaves it unwatched (unrendered)"


def test_a_run_with_the_camera_records_its_frames_and_a_contact_sheet(tmp_path, bringups):
    result = run_quietly(schema.find("head_camera_tilt"), tmp_path, bringups, record=True, camera=True)
    assert result.passed, result.report
    report = json.loads((result.folder / "report.json").read_text())
    sheet = pathlib.Path(report["artifacts"]["camera"])
    assert sheet.name == "camera.png" and sheet.stat().st_size > 10_000
    counts = recording.read_mcap_topics(pathlib.Path(report["artifacts"]["mcap"]))
    frames_due = report["sim_time_s"] * 10.0  # camera_rate 10 Hz of sim time
    assert counts.get("/head_camera/image_raw", 0) >= 0.9 * frames_due, counts
    # Every frame has its camera_info (same stamp; published right after the image), but for the newest: the
    # recording may stop between the two (a fresh clone's run once had 34 images and 33 infos).
    images, infos = (_stamps(pathlib.Path(report["artifacts"]["mcap"]), f"/head_camera/{name}")
                     for name in ("image_raw", "camera_info"))
    assert len(images) == counts["/head_camera/image_raw"] and infos, (len(images), len(infos))
    assert not set(sorted(images)[:-1]) - set(infos), f"frames without their camera_info: {sorted(set(images) - set(infos))}"


def _stamps(path: pathlib.Path, topic: str) -> list[tuple[int, int]]:
    """The header stamps [s, ns] of a topic's messages in an MCAP file."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    with open(path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        return [(decoded.header.stamp.sec, decoded.header.stamp.nanosec)
                for _schema, _channel, _message, decoded in reader.iter_decoded_messages(topics=[topic])]


def test_a_failing_expectation_fails_the_run_and_is_named(tmp_path):
    text = STAND.replace("near: 0.76\n    tol: 0.08", "near: 1.50\n    tol: 0.01")
    path = scenario_file(tmp_path, text, "fails")
    completed = subprocess.run(  # and a passing one after it, on the same bring-up (a failed expectation is no error)
        [str(BIN / "scenario"), "run", str(path), str(scenario_file(tmp_path, STAND, "passes")), "--out", str(tmp_path / "runs")],
        capture_output=True, text=True, timeout=180,
    )
    assert completed.returncode == 1, completed.stdout + completed.stderr
    assert "FAIL  pelvis height: measured 0.76" in completed.stdout
    assert "PASS  never fell" in completed.stdout
    assert "stand_short: FAILED" in completed.stdout
    assert "stand_short: PASSED" in completed.stdout and "reusing the bring-up of g1/open" in completed.stdout
    assert "1/2 scenarios passed, on 1 bring-up" in completed.stdout


def test_the_same_scenario_twice_gives_the_same_measured_values(tmp_path, bringups):
    path = scenario_file(tmp_path, STAND, "twice")
    started = bringups.started
    first = run_quietly(path, tmp_path / "a", bringups)
    second = run_quietly(path, tmp_path / "b", bringups)
    assert bringups.started <= started + 1, "the second run reuses the bring-up of the first"
    assert first.passed and second.passed
    a = {v.name: v.measured for v in first.verdicts}
    b = {v.name: v.measured for v in second.verdicts}
    assert a.keys() == b.keys()
    for name in a:
        assert a[name] == pytest.approx(b[name], abs=1e-9), name


def test_an_unknown_scenario_name_is_a_usage_error():
    completed = subprocess.run([str(BIN / "scenario"), "run", "no_such_scenario"], capture_output=True, text=True, timeout=60)
    assert completed.returncode == 2
    assert "no scenario of that name" in completed.stderr


# ----- every shipped scenario -------------------------------------------------------------------
def _params():
    """Every shipped scenario, those of one robot and scene one after the other (they share a bring-up)."""
    loaded = [(path, schema.load(path)) for path in schema.all_files()]
    for path, scenario in sorted(loaded, key=lambda item: (item[1].robot, item[1].scene, item[0].stem)):
        marks = [] if "fast" in scenario.tags else [pytest.mark.slow]
        yield pytest.param(path, id=path.stem, marks=marks)


@pytest.mark.parametrize("path", list(_params()))
def test_every_shipped_scenario_passes(tmp_path, bringups, path):
    result = run_quietly(path, tmp_path, bringups)
    failed = [v.line_text() for v in result.verdicts if not v.passed] + result.failures
    assert result.passed, "\n".join(failed)
