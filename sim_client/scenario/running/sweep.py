"""``scenario sweep``: one scenario over a grid of values and seeds, in parallel on Ray, one table and a plot.

A grid key is a dotted path into the scenario file (list items by index), e.g.
``steps.0.send_goal.goal.speed``; its values are a YAML list (``[0.3, 0.5, 0.8]``) or a range
``start:stop:step`` (stop included). Every combination runs once per seed (the seed is written into
the scenario's ``seed``). Each point is validated before anything starts, then runs on a worker: a Ray
actor with a ROS domain of its own (localhost discovery) that keeps its bring-up warm for the points it
runs (:mod:`~sim_client.scenario.running.sweep_worker`): a local Ray instance by default, a Ray cluster
when given its address (every node needs the project installed at the same path). The sweep writes
``sweep.csv`` and ``sweep.json`` (one row per run: the point, passed, each expectation's measured value,
sim and wall time, the worker, whether it started a bring-up, the run folder) and ``sweep.png``.
"""

from __future__ import annotations

import csv
import itertools
import json
import math
import os
import pathlib
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, TextIO

import yaml

from sim_client.scenario.model import schema
from sim_client.scenario.running.sweep_worker import WORKER_TAG_VARIABLE, SweepWorker
from sim_ros.processes import stop_tagged_processes

DOMAIN_IDS = 101  # Fast DDS domain ids 1..101 are safe for its port scheme; 0 is everyone's default
RUN_WALL_LIMIT_S = 1800.0  # [s] a point running longer has hung: its worker and its processes are stopped


class SweepError(Exception):
    """A sweep cannot start as asked; the message says what is wrong and what is allowed."""


@dataclass(frozen=True)
class Point:
    """One run of the sweep: its index, the grid values, the seed and the scenario text to run."""

    index: int
    values: dict[str, Any]
    seed: int
    text: str


@dataclass
class SweepResult:
    folder: pathlib.Path
    rows: list[dict[str, Any]] = field(default_factory=list)

    @property
    def passed(self) -> int:
        return sum(1 for row in self.rows if row["passed"])


def parse_values(key: str, text: str) -> list[Any]:
    """The values of one grid key: a YAML list, or ``start:stop:step`` (numbers, stop included)."""
    if text.count(":") == 2 and not text.strip().startswith("["):
        try:
            start, stop, step = (float(part) for part in text.split(":"))
        except ValueError:
            raise SweepError(f"grid {key}: {text!r} is not start:stop:step with numbers") from None
        if step <= 0 or stop < start:
            raise SweepError(f"grid {key}: {text!r} needs step > 0 and stop >= start")
        count = math.floor((stop - start) / step + 1e-9) + 1
        return [round(start + i * step, 10) for i in range(count)]
    try:
        values = yaml.safe_load(text)
    except yaml.YAMLError as error:
        raise SweepError(f"grid {key}: {text!r} is not a YAML list ({error})") from None
    if not isinstance(values, list) or not values:
        raise SweepError(f"grid {key}: give a non-empty list like [0.3, 0.5] or a range like 0.3:0.8:0.1, not {text!r}")
    return values


def parse_grid(items: Sequence[str]) -> dict[str, list[Any]]:
    """``KEY=VALUES`` arguments into an ordered grid."""
    grid: dict[str, list[Any]] = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise SweepError(f"grid item {item!r}: write KEY=VALUES, e.g. steps.0.send_goal.goal.speed=[0.3,0.5]")
        grid[key.strip()] = parse_values(key.strip(), text)
    return grid


def set_path(document: Any, path: str, value: Any) -> None:
    """Set ``value`` at a dotted ``path`` of a loaded YAML document (list items by index)."""
    parts = path.split(".")
    node = document
    for depth, part in enumerate(parts):
        last = depth == len(parts) - 1
        where = ".".join(parts[:depth]) or "the file"
        if isinstance(node, list):
            if not part.isdigit() or int(part) >= len(node):
                raise SweepError(f"grid {path}: {where} is a list of {len(node)} items; {part!r} is not an index of it")
            if last:
                node[int(part)] = value
            else:
                node = node[int(part)]
        elif isinstance(node, dict):
            if last:
                node[part] = value
            elif part not in node:
                raise SweepError(f"grid {path}: {where} has no {part!r}; it has: {', '.join(map(str, node)) or 'nothing'}")
            else:
                node = node[part]
        else:
            raise SweepError(f"grid {path}: {where} is a value, not a mapping or a list")


def points(scenario_path: pathlib.Path, grid: dict[str, list[Any]], seeds: Sequence[int]) -> list[Point]:
    """Every combination of the grid, once per seed, each validated as a scenario."""
    base_text = scenario_path.read_text()
    result: list[Point] = []
    keys = list(grid)
    for combination in itertools.product(*(grid[key] for key in keys)):
        for seed in seeds:
            document = yaml.safe_load(base_text)
            values = dict(zip(keys, combination, strict=True))
            for key, value in values.items():
                set_path(document, key, value)
            document["seed"] = int(seed)
            text = yaml.safe_dump(document, sort_keys=False)
            try:
                schema.parse(text, f"{scenario_path} with {values}, seed {seed}")
            except schema.ScenarioError as error:
                raise SweepError(f"point {values}, seed {seed} is not a valid scenario: {error}") from None
            result.append(Point(len(result), values, int(seed), text))
    return result


def run_sweep(scenario_path: pathlib.Path, grid: dict[str, list[Any]], seeds: Sequence[int], out: pathlib.Path,
              address: str | None = None, workers: int | None = None, rtf: float | None = None,
              stream: TextIO = sys.stdout) -> SweepResult:
    """Run every point on Ray (local by default, or the cluster at ``address``); write the table and plot."""
    import ray

    todo = points(scenario_path, grid, seeds)
    name = schema.parse(scenario_path.read_text(), str(scenario_path)).name
    folder = out / f"sweep-{name}-{time.strftime('%Y%m%d-%H%M%S')}"
    folder.mkdir(parents=True, exist_ok=True)
    stream.write(f"sweep of {name}: {len(todo)} runs ({' x '.join(f'{len(v)} {k}' for k, v in grid.items()) or 'no grid'}"
                 f" x {len(seeds)} seeds) into {folder}\n")
    # Local: as many runs at once as asked (each run, a sim and its servers, takes one CPU of Ray's); a
    # cluster schedules by its own resources.
    init: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False, "configure_logging": False}
    if address:
        init["address"] = address
    else:
        init["num_cpus"] = max(1, workers or (os.cpu_count() or 1))
        init["object_store_memory"] = 128 * 1024 * 1024  # rows are small; the default reserves a third of RAM
    started = time.monotonic()
    ray.init(**init)
    rows: list[dict[str, Any]] = []
    sweep_tag = f"{os.getpid()}-{time.monotonic_ns()}"
    try:
        # One worker per CPU asked for (or per point, if fewer), each a process with its own ROS domain and a
        # bring-up kept warm for the points it is handed, one at a time, as it finishes the last.
        count = min(len(todo), int(init.get("num_cpus") or workers or len(todo)))
        base = int(os.environ.get("ROS_DOMAIN_ID", "0") or 0)
        actor = ray.remote(num_cpus=1, max_restarts=0)(SweepWorker)

        def new_worker(k: int) -> Any:
            return actor.remote(k, 1 + (base + 1 + k) % DOMAIN_IDS, rtf, f"{sweep_tag}/{k}")

        pool: list[Any] = [new_worker(k) for k in range(count)]
        queue = list(todo)
        pending: dict[Any, tuple[int, Point, float]] = {}  # a point's result -> its worker, the point, its deadline

        def hand_out(k: int) -> None:
            if queue:
                point = queue.pop(0)
                pending[pool[k].run.remote(point, folder)] = (k, point, time.monotonic() + RUN_WALL_LIMIT_S)

        for k in range(count):
            hand_out(k)
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1, timeout=max(0.0, min(d for _, _, d in pending.values())
                                                                          - time.monotonic()))
            late = [ref for ref, (_, _, deadline) in pending.items() if deadline <= time.monotonic()]
            for ref in done or late[:1]:
                k, point, _ = pending.pop(ref)
                try:
                    if not done:  # hung past the limit: the worker, and every process it started, is stopped
                        ray.kill(pool[k])
                        stop_tagged_processes(WORKER_TAG_VARIABLE, f"{sweep_tag}/{k}")
                        raise TimeoutError(f"the run took longer than {RUN_WALL_LIMIT_S:.0f} s")
                    row = ray.get(ref)
                except (ray.exceptions.RayError, TimeoutError) as error:  # the point fails, a new worker takes over
                    row = {"point": point.index, **point.values, "seed": point.seed, "passed": False, "worker": k,
                           "failures": f"the worker died or hung: {type(error).__name__}: {error}"}
                    pool[k] = new_worker(k)
                rows.append(row)
                hand_out(k)
                verdict = "PASS" if row["passed"] else "FAIL"
                warm = "" if row.get("new_bringup", True) else ", warm bring-up"
                stream.write(f"  [{len(rows)}/{len(todo)}] {verdict}  {point.values} seed {point.seed}"
                             f"  ({row.get('process_wall_s', 0.0):.1f} s wall incl. start-up{warm})\n")
        started_bringups = sum(ray.get([worker.close.remote() for worker in pool]))
        stream.write(f"{len(todo)} runs on {count} workers, {started_bringups} bring-ups\n")
    finally:
        ray.shutdown()
        stop_tagged_processes(WORKER_TAG_VARIABLE, f"{sweep_tag}/")  # (none after a sweep that ended well)
    rows.sort(key=lambda row: row["point"])
    result = SweepResult(folder, rows)
    write_table(result, grid)
    plot_sweep(result, grid, name)
    stream.write(f"{result.passed}/{len(rows)} passed in {time.monotonic() - started:.1f} s; "
                 f"{folder / 'sweep.csv'}, {folder / 'sweep.png'}\n")
    return result


def write_table(result: SweepResult, grid: dict[str, list[Any]]) -> None:
    columns: list[str] = []
    for row in result.rows:
        columns += [key for key in row if key not in columns]
    with open(result.folder / "sweep.csv", "w", newline="") as stream:
        writer = csv.DictWriter(stream, fieldnames=columns)
        writer.writeheader()
        for row in result.rows:
            writer.writerow({key: json.dumps(v) if isinstance(v, (list, dict)) else v for key, v in row.items()})
    (result.folder / "sweep.json").write_text(json.dumps({"grid": grid, "rows": result.rows}, indent=2, default=str))


def plot_sweep(result: SweepResult, grid: dict[str, list[Any]], name: str) -> None:
    """Each expectation's measured value over the first grid key (passed: filled, failed: red x)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    measures = [key for key in (result.rows[0] if result.rows else {}) if key.startswith("measured: ")]
    numeric = [m for m in measures if all(isinstance(row.get(m), (int, float)) for row in result.rows)]
    keys = list(grid)
    x_key = keys[0] if keys else "seed"
    panels = max(1, len(numeric))
    figure, axes = plt.subplots(panels, 1, figsize=(7, 2.4 * panels + 0.6), squeeze=False)
    for axis, measure in zip(axes[:, 0], numeric or ["passed"], strict=False):
        for row in result.rows:
            x = row.get(x_key)
            x_plot = x if isinstance(x, (int, float)) else str(x)
            y = row.get(measure) if measure != "passed" else float(row["passed"])
            axis.plot([x_plot], [y], marker="o" if row["passed"] else "x", color="tab:blue" if row["passed"] else "tab:red",
                      linestyle="none")
        axis.ticklabel_format(axis="y", useOffset=False, style="plain")
        axis.set_title(measure.removeprefix("measured: "), fontsize=9)
        axis.grid(alpha=0.3)
    axes[-1, 0].set_xlabel(x_key)
    figure.suptitle(f"sweep of {name}: {result.passed}/{len(result.rows)} passed (o pass, x fail)", fontsize=10)
    figure.tight_layout()
    figure.savefig(result.folder / "sweep.png", dpi=100)
    plt.close(figure)
