"""One worker of a sweep: a Ray actor with a ROS domain of its own and one bring-up kept warm for its points.

A worker runs its points one after another through the scenario runner, in its own process, on one bring-up
(:class:`~sim_client.scenario.running.bringups.Bringups`): a point after the first costs its run and a reset
(and the load of its scene when it has another), not a start-up, and its report is the one fresh nodes give.
A point that ends in an error gets a failed row and the next one a fresh bring-up.
"""

from __future__ import annotations

import json
import os
import pathlib
import time
import traceback
from typing import Any

WORKER_TAG_VARIABLE = "SIM_SWEEP_WORKER"  # in the environment of a worker and of everything it starts


class SweepWorker:
    """Runs points on one ROS domain (set before rclpy is imported in this process) and one warm bring-up.

    Args:
        index: the worker's number (in the rows).
        domain_id: its ROS domain.
        rtf: the pace of every run (None: each scenario's own).
        tag: set in the environment as ``SIM_SWEEP_WORKER``, which every process the worker starts inherits.
    """

    def __init__(self, index: int, domain_id: int, rtf: float | None, tag: str) -> None:
        os.environ[WORKER_TAG_VARIABLE] = tag  # its bring-ups inherit it: stopped by it if the worker hangs
        os.environ["ROS_DOMAIN_ID"] = str(domain_id)
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
        os.environ.setdefault("MUJOCO_GL", "egl")
        from sim_client.scenario.running.bringups import Bringups

        self.index = index
        self._rtf = rtf
        self._bringups = Bringups(quiet=True)

    def run(self, point: Any, out: pathlib.Path) -> dict[str, Any]:
        """Run one point (a :class:`~sim_client.scenario.running.sweep.Point`) into ``out/point-NNNN/``; its row of the
        sweep's table."""
        from sim_client.scenario.model import schema
        from sim_client.scenario.running.options import RunOptions
        from sim_client.scenario.running.runner import run

        folder = out / f"point-{point.index:04d}"
        folder.mkdir(parents=True, exist_ok=True)
        file = folder / "scenario.yaml"
        file.write_text(point.text)
        started = time.monotonic()
        bringups_before = self._bringups.started
        row: dict[str, Any] = {"point": point.index, **point.values, "seed": point.seed, "passed": False,
                               "worker": self.index}
        with open(folder / "run.log", "w") as log:
            try:
                result = run(schema.load(file), RunOptions(out=folder, rtf=self._rtf), stream=log, bringups=self._bringups)
            except Exception:  # noqa: BLE001 - the point fails with the reason; the worker goes on with the next
                log.write(traceback.format_exc())
                row.update(failures=f"the run raised; see {folder / 'run.log'}",
                           process_wall_s=round(time.monotonic() - started, 3))
                return row
        report = json.loads((result.folder / "report.json").read_text()) if (result.folder / "report.json").exists() \
            else result.report
        row.update(passed=bool(result.passed), sim_time_s=report.get("sim_time_s"), wall_time_s=report.get("wall_time_s"),
                   startup_wall_s=round(result.startup_time, 3), new_bringup=self._bringups.started > bringups_before,
                   process_wall_s=round(time.monotonic() - started, 3), folder=str(result.folder),
                   failures="; ".join(report.get("failures", [])))
        for expectation in report.get("expectations", []):
            row[f"measured: {expectation['name']}"] = expectation.get("measured")
        return row

    def close(self) -> int:
        """Stop the worker's bring-up; returns how many bring-ups it started."""
        self._bringups.close()
        return self._bringups.started
