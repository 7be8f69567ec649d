"""``scenario sweep``: a grid of values and seeds over one scenario, run on a local Ray instance."""

from __future__ import annotations

import csv
import io
import json
import os

import pytest

from sim_client.scenario.model import schema
from sim_client.scenario.running.sweep import SweepError, parse_grid, parse_values, points, run_sweep, set_path


def test_grid_values_are_yaml_lists_or_ranges():
    assert parse_values("k", "[0.3, 0.5]") == [0.3, 0.5]
    assert parse_values("k", "0.3:0.8:0.1") == [0.3, 0.4, 0.5, 0.6, 0.7, 0.8]
    assert parse_values("k", "[[0.4, 0.3, 0.0], [0.5, 0.2, 0.0]]") == [[0.4, 0.3, 0.0], [0.5, 0.2, 0.0]]
    for bad in ("0.3", "[]", "1:0:0.1", "a:b:c", "[0.3"):
        with pytest.raises(SweepError):
            parse_values("k", bad)
    with pytest.raises(SweepError, match="KEY=VALUES"):
        parse_grid(["steps.0.wait.duration"])


def test_a_path_that_is_not_in_the_file_says_what_is_there():
    document = {"steps": [{"wait": {"duration": 1.0}}]}
    set_path(document, "steps.0.wait.duration", 2.0)
    assert document["steps"][0]["wait"]["duration"] == 2.0
    with pytest.raises(SweepError, match="list of 1 items"):
        set_path(document, "steps.3.wait.duration", 2.0)
    with pytest.raises(SweepError, match="has no 'walk'"):
        set_path(document, "steps.0.walk.speed", 2.0)


def test_every_point_is_validated_before_anything_runs():
    path = schema.find("walk_2m")
    grid = parse_grid(["steps.0.send_goal.goal.speed=[0.3, 0.5]"])
    runs = points(path, grid, [0, 1])
    assert [(p.values["steps.0.send_goal.goal.speed"], p.seed) for p in runs] == [(0.3, 0), (0.3, 1), (0.5, 0), (0.5, 1)]
    assert schema.parse(runs[3].text).seed == 1
    with pytest.raises(SweepError, match="not a valid scenario"):
        points(path, parse_grid(["steps.0.send_goal.goal.speed=[fast]"]), [0])


def test_a_small_sweep_runs_on_ray_on_warm_workers_and_writes_its_table_and_plot(tmp_path):
    """Three points on two workers: two bring-ups, the third point on the warm one of the worker that finished first."""
    path = schema.find("reset_and_stand_panda")
    out = io.StringIO()
    result = run_sweep(path, parse_grid(["steps.1.wait.duration=[0.4, 0.8, 1.2]"]), [0], tmp_path, workers=2, stream=out)
    assert len(result.rows) == 3 and result.passed == 3, out.getvalue()
    assert "3 runs on 2 workers, 2 bring-ups" in out.getvalue(), out.getvalue()
    assert sorted(row["new_bringup"] for row in result.rows) == [False, True, True]
    rows = list(csv.DictReader(io.StringIO((result.folder / "sweep.csv").read_text())))
    assert [float(row["steps.1.wait.duration"]) for row in rows] == [0.4, 0.8, 1.2]
    # each run really ran its own value, the warm one too: the sim time of the run follows the grid
    assert [float(row["sim_time_s"]) for row in rows] == [pytest.approx(v, abs=0.05) for v in (0.4, 0.8, 1.2)]
    assert all(row["passed"] == "True" for row in rows)
    assert json.loads((result.folder / "sweep.json").read_text())["grid"] == {"steps.1.wait.duration": [0.4, 0.8, 1.2]}
    assert (result.folder / "sweep.png").stat().st_size > 10_000


def test_a_point_that_runs_past_the_limit_fails_and_its_worker_and_bring_up_are_stopped(tmp_path, monkeypatch):
    """A hung worker would hold the sweep for ever: past the limit its point fails, the worker and the processes it
    started end, and the sweep goes on. Here the limit is 10 s and the point waits 120 s at real time."""
    from sim_client.scenario.running import sweep
    from sim_client.scenario.running.sweep_worker import WORKER_TAG_VARIABLE
    from sim_ros.processes import tagged_processes

    monkeypatch.setattr(sweep, "RUN_WALL_LIMIT_S", 10.0)
    path = schema.find("reset_and_stand_panda")
    out = io.StringIO()
    result = run_sweep(path, parse_grid(["steps.1.wait.duration=[120.0]"]), [0], tmp_path, workers=1, rtf=1.0, stream=out)
    assert result.passed == 0 and "took longer than 10 s" in result.rows[0]["failures"], out.getvalue()
    assert not tagged_processes(WORKER_TAG_VARIABLE, f"{os.getpid()}-"), "the worker's bring-up was stopped"
