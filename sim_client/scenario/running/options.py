"""How to run a scenario: pace, which artifacts to make, where, and whether to start the nodes."""

from __future__ import annotations

import pathlib
from dataclasses import dataclass


@dataclass(frozen=True)
class RunOptions:
    """How to run: ``rtf`` None = the scenario's own; 0 = as fast as possible, > 0 paced to that factor."""

    rtf: float | None = None
    record: bool = False
    video: bool = False
    plots: bool = False
    camera: bool = False  # record the robot's camera (images in the MCAP, camera.png); costs a rendering per frame
    out: pathlib.Path = pathlib.Path("scenario_runs")
    quiet: bool = False
    launch: bool = True  # False: use nodes already running (``sim up``)
    namespace: str = ""  # the bring-up's namespace ("" = the root): started there, or found there with launch False
