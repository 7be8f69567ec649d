"""Text drawn over a video frame: the sim time and what each goal is doing.

Glyphs come from FreeType through matplotlib's ``ft2font`` and the DejaVu Sans Mono font that
matplotlib ships, so no extra dependency; each line is blended onto the RGB frame through its
anti-aliased glyph coverage, over a dark translucent band.
"""

from __future__ import annotations

import pathlib
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from sim_client.scenario.outputs.goalview import GoalView

WHITE = (255, 255, 255)
RUNNING = (255, 214, 90)  # amber
SUCCEEDED = (120, 230, 120)  # green
FAILED = (255, 120, 100)  # red
GREY = (200, 200, 200)
SHOW_ENDED_S = 4.0  # an ended goal stays on screen this long [s of sim time] (the last one: to the end)
MAX_GOAL_LINES = 4


@dataclass(frozen=True)
class Line:
    """One line of overlay text and its colour (r, g, b)."""

    text: str
    colour: tuple[int, int, int] = WHITE


def overlay_lines(title: str, t: float, start: float, goals: Sequence[GoalView]) -> list[Line]:
    """The overlay at sim time ``t`` [s]: the run's name and time since ``start``, then one line per goal shown.

    A goal is shown while it runs and for ``SHOW_ENDED_S`` after it ends; the goal that ended last
    stays on screen when nothing else is going on, so the end of a video says how it went.
    """
    lines = [Line(f"{title}   t = {t - start:6.2f} s")]
    shown = [g for g in goals if g.sent <= t + 1e-9 and (not g.ended_by(t) or t - (g.done or t) <= SHOW_ENDED_S)]
    if not shown:
        shown = [g for g in goals if g.ended_by(t)][-1:]
    for goal in shown[-MAX_GOAL_LINES:]:
        ended = goal.ended_by(t) and bool(goal.status)
        colour = (SUCCEEDED if goal.succeeded else FAILED) if ended else RUNNING
        lines.append(Line(f"{goal.label()}: {goal.state_at(t)}", colour))
    return lines


def _font_path() -> pathlib.Path:
    import matplotlib

    return pathlib.Path(matplotlib.get_data_path()) / "fonts" / "ttf" / "DejaVuSansMono.ttf"


class TextPainter:
    """Draws lines of text onto RGB frames (uint8, (h, w, 3)), in place.

    Args:
        size_px: glyph size [px]; the line pitch is 1.4 times that.
    """

    def __init__(self, size_px: int = 14) -> None:
        from matplotlib import ft2font

        self._ft2font = ft2font
        self._font = ft2font.FT2Font(str(_font_path()))
        self.size_px = size_px
        self.pitch = round(1.4 * size_px)
        self._drawn: dict[str, tuple[np.ndarray, int]] = {}  # text -> its glyphs: most lines repeat frame after frame

    def _glyphs(self, text: str) -> tuple[np.ndarray, int]:
        """Coverage (0..1, (h, w)) of ``text`` and the depth of its lowest pixel below the baseline [px]."""
        if text not in self._drawn:
            if len(self._drawn) >= 256:
                self._drawn.clear()
            self._drawn[text] = self._draw_glyphs(text)
        return self._drawn[text]

    def _draw_glyphs(self, text: str) -> tuple[np.ndarray, int]:
        font = self._font
        font.set_size(self.size_px, 72)
        font.set_text(text, 0.0, flags=self._ft2font.LoadFlags.FORCE_AUTOHINT)
        font.draw_glyphs_to_bitmap(antialiased=True)
        coverage = np.asarray(font.get_image(), dtype=np.float32) / 255.0
        return coverage, round(font.get_descent() / 64)

    def draw(self, frame: np.ndarray, lines: Sequence[Line], corner: str = "top-left", band: bool = True) -> None:
        """Draw ``lines`` in a corner (``top-left``, ``bottom-right``...) of ``frame``, over a dark band."""
        height, width = frame.shape[:2]
        margin = max(4, self.size_px // 2)
        rendered = [(self._glyphs(line.text), line.colour) for line in lines if line.text]
        if not rendered:
            return
        block_w = max(coverage.shape[1] for (coverage, _), _ in rendered) + 2 * margin
        block_h = self.pitch * len(rendered) + margin
        x0 = margin if corner.endswith("left") else width - block_w - margin
        y0 = 0 if corner.startswith("top") else height - block_h - margin
        x0, y0 = max(0, x0), max(0, y0)
        if band:
            region = frame[y0:y0 + block_h, x0:x0 + block_w]
            region[...] = (region.astype(np.float32) * 0.45).astype(np.uint8)
        for i, ((coverage, descent), colour) in enumerate(rendered):
            baseline = y0 + margin // 2 + (i + 1) * self.pitch - max(2, self.pitch - self.size_px) // 2
            top = baseline - (coverage.shape[0] - descent)
            left = x0 + margin
            _blend(frame, coverage, top, left, colour)


def _blend(frame: np.ndarray, coverage: np.ndarray, top: int, left: int, colour: tuple[int, int, int]) -> None:
    """Blend ``colour`` onto ``frame`` through ``coverage`` placed at (top, left), clipped to the frame."""
    height, width = frame.shape[:2]
    y0, x0 = max(top, 0), max(left, 0)
    y1, x1 = min(top + coverage.shape[0], height), min(left + coverage.shape[1], width)
    if y1 <= y0 or x1 <= x0:
        return
    alpha = coverage[y0 - top:y1 - top, x0 - left:x1 - left, None]
    region = frame[y0:y1, x0:x1].astype(np.float32)
    frame[y0:y1, x0:x1] = (region * (1.0 - alpha) + np.array(colour, dtype=np.float32) * alpha).astype(np.uint8)
