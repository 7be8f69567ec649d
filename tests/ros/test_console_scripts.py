"""Console scripts answer --help at once and end a bad start in one line that says what is allowed."""

from __future__ import annotations

import os
import pathlib
import subprocess
import tomllib

import pytest

from sim_ros.processes import BIN

ROOT = pathlib.Path(__file__).resolve().parents[2]
SCRIPTS = sorted(tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"])
# Wall-clock bound for a process that must end by itself (no /sim is running in these tests: a node
# that waited for one would run into it). Generous for a loaded 2-core machine; it is a hang guard.
END_WALL_S = 60.0


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(BIN / args[0]), *args[1:]], capture_output=True, text=True, timeout=END_WALL_S,
                          env=dict(os.environ))


@pytest.mark.parametrize("script", SCRIPTS)
def test_every_console_script_answers_help_without_ros(script):
    done = run(script, "--help")
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.startswith("usage:") or "\nusage:" in done.stdout[:200], done.stdout[:500]
    assert "Traceback" not in done.stderr


def test_node_help_lists_parameters_with_defaults_and_ranges():
    page = run("locomotion_server", "--help").stdout
    assert "walking_speed" in page and "default" in page and " from 0.05 to " in page
    page = run("sim_node", "--help").stdout
    assert "real_time_factor" in page and "from 0 to 1000" in page and "read-only" in page


@pytest.mark.parametrize(("args", "expected"), [
    (("locomotion_server", "--ros-args", "-p", "robot:=g1", "-p", "walking_speed:=9.0"),
     ("walking_speed", "9.0", "from 0.05 to")),
    (("locomotion_server", "--ros-args", "-p", "robot:=g1", "-p", "walking_speed:=fast"),
     ("walking_speed", "'fast'", "wrong type")),
    (("locomotion_server", "--ros-args", "-p", "robot:=panda"), ("'panda' cannot walk", "g1")),
    (("arm_server", "--ros-args", "-p", "robot:=panda", "-p", "max_velocity_scaling:=-1.0"),
     ("max_velocity_scaling", "-1.0", "from")),
    (("arm_server", "--ros-args", "-p", "robot:=atlas"), ("unknown robot 'atlas'", "g1, panda")),
    (("arm_server", "--ros-args", "-p", "robot:=g1", "-p", "scene:=moon"), ("unknown scene 'moon'", "open, course, tables")),
    (("sim_node", "--ros-args", "-p", "real_time_factor:=-1.0"), ("real_time_factor", "-1.0", "from 0 to 1000")),
    (("sim_node", "--ros-args", "-p", "robot:=atlas"), ("cannot configure /sim", "unknown robot 'atlas'", "g1, panda")),
    (("sim_node", "--ros-args", "-p", "gait.step_duration:=9.0"), ("gait.step_duration", "9.0", "from")),
])
def test_a_bad_start_up_parameter_ends_in_one_line_naming_it(args, expected):
    done = run(*args)
    assert done.returncode == 2, (done.returncode, done.stderr[-2000:])
    assert "Traceback" not in done.stderr, done.stderr[-3000:]
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith(f"{args[0]}: "), last
    for part in expected:
        assert part in last, last


def test_an_unreadable_params_file_is_named_in_one_line(tmp_path):
    broken = tmp_path / "broken.yaml"
    broken.write_text("sim: [\n")
    done = run("sim_node", "--ros-args", "--params-file", str(broken))
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr[-3000:]
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("sim_node: cannot read the ROS arguments") and str(broken) in last, last

    out_of_range = tmp_path / "params.yaml"
    out_of_range.write_text("sim:\n  ros__parameters:\n    joint_state_rate: 5000.0\n")
    done = run("sim_node", "--ros-args", "--params-file", str(out_of_range))
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr[-3000:]
    last = done.stderr.strip().splitlines()[-1]
    assert "joint_state_rate" in last and "5000.0" in last and "from 1 to 500" in last, last
