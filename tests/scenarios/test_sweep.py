"""``scenario sweep``: a grid of values and seeds over one scenario, run on a local Ray instance."""

from __future__ import annotations

import csv
import io
import json

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


def test_a_small_sweep_runs_on_ray_and_writes_its_table_and_plot(tmp_path):
    path = schema.find("reset_and_stand_panda")
    out = io.StringIO()
    result = run_sweep(path, parse_grid(["steps.1.wait.duration=[0.4, 0.8]"]), [0], tmp_path, workers=2, stream=out)
    assert len(result.rows) == 2 and result.passed == 2, out.getvalue()
    rows = list(csv.DictReader(io.StringIO((result.folder / "sweep.csv").read_text())))
    assert [float(row["steps.1.wait.duration"]) for row in rows] == [0.4, 0.8]
    # each run really ran its own value: the sim time of the run follows the grid
    assert [float(row["sim_time_s"]) for row in rows] == [pytest.approx(0.4, abs=0.05), pytest.approx(0.8, abs=0.05)]
    assert all(row["passed"] == "True" for row in rows)
    assert json.loads((result.folder / "sweep.json").read_text())["grid"] == {"steps.1.wait.duration": [0.4, 0.8]}
    assert (result.folder / "sweep.png").stat().st_size > 10_000


def test_a_worker_keeps_its_bring_up_warm_for_the_points_it_runs(tmp_path):
    """Three points on one worker: one bring-up; the later points start in a reset, not a start-up, and each
    runs its own value."""
    path = schema.find("reset_and_stand_panda")
    out = io.StringIO()
    result = run_sweep(path, parse_grid(["steps.1.wait.duration=[0.4, 0.8, 1.2]"]), [0], tmp_path, workers=1, stream=out)
    assert result.passed == 3, out.getvalue()
    assert "3 runs on 1 workers, 1 bring-ups" in out.getvalue(), out.getvalue()
    assert [row["new_bringup"] for row in result.rows] == [True, False, False]
    assert [row["sim_time_s"] for row in result.rows] == [pytest.approx(v, abs=0.05) for v in (0.4, 0.8, 1.2)]
