"""``camera.png``: a contact sheet of what the robot's camera saw during a run (``scenario run --camera``).

The frames are the ones ``/sim`` rendered and published on ``/<camera>/image_raw`` (the G1's head camera,
the Panda's scene camera), recorded by the runner; the sheet shows up to ``FRAMES`` of them, evenly
spaced in sim time from the run's start to its end, each labelled with its sim time.
"""

from __future__ import annotations

import math
import pathlib
from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure
from sensor_msgs.msg import Image

from sim_client.scenario.model.series import stamp_s

FRAMES = 8
COLUMNS = 4


def pixels(msg: Image) -> np.ndarray:
    """An rgb8 image as a (height, width, 3) uint8 array."""
    if msg.encoding != "rgb8":
        raise ValueError(f"camera image encoding {msg.encoding!r} is not rgb8")
    return np.frombuffer(bytes(msg.data), dtype=np.uint8).reshape(msg.height, msg.width, 3)


def pick(images: Sequence[Image], start: float, end: float, count: int = FRAMES) -> list[Image]:
    """Up to ``count`` images nearest to evenly spaced sim times in [start, end] (no image twice)."""
    stamped = [(stamp_s(m.header.stamp), m) for m in images]
    stamped = [(t, m) for t, m in stamped if start - 1e-6 <= t <= end + 1e-6]
    if not stamped:
        return []
    times = np.array([t for t, _ in stamped])
    wanted = np.linspace(start, end, min(count, len(stamped)))
    chosen = sorted({int(np.argmin(np.abs(times - t))) for t in wanted})
    return [stamped[i][1] for i in chosen]


def make_sheet(images: Sequence[Image], start: float, end: float, path: pathlib.Path, title: str) -> pathlib.Path | None:
    """Write the contact sheet; None when no frame falls in the run."""
    frames = pick(images, start, end)
    if not frames:
        return None
    rows = math.ceil(len(frames) / COLUMNS)
    columns = min(COLUMNS, len(frames))
    aspect = frames[0].height / frames[0].width
    figure = Figure(figsize=(3.2 * columns, 3.2 * aspect * rows + 0.6), dpi=100)
    figure.suptitle(title, fontsize=10)
    for index, msg in enumerate(frames):
        ax = figure.add_subplot(rows, columns, index + 1)
        ax.imshow(pixels(msg))
        ax.set_title(f"t = {stamp_s(msg.header.stamp) - start:.1f} s", fontsize=9)
        ax.set_axis_off()
    figure.tight_layout()
    figure.savefig(path)
    return path
