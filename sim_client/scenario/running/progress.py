"""What a run says while it runs: one status line, and a few words on a goal's feedback."""

from __future__ import annotations

import time
from typing import Any, TextIO


class Progress:
    """One status line, rewritten in place on a terminal; plain lines otherwise."""

    def __init__(self, stream: TextIO, quiet: bool) -> None:
        self.stream = stream
        self.quiet = quiet
        self.tty = stream.isatty()
        self._last = 0.0
        self._width = 0

    def update(self, text: str) -> None:
        if self.quiet:
            return
        now = time.monotonic()
        if self.tty:
            if now - self._last < 0.1:
                return
            self._last = now
            padded = text[:160].ljust(self._width)
            self._width = len(text[:160])
            self.stream.write("\r" + padded)
            self.stream.flush()
        elif now - self._last >= 2.0:
            self._last = now
            self.stream.write(text + "\n")
            self.stream.flush()

    def say(self, text: str) -> None:
        if self.quiet:
            return
        if self.tty and self._width:
            self.stream.write("\r" + " " * self._width + "\r")
            self._width = 0
        self.stream.write(text + "\n")
        self.stream.flush()


def feedback_summary(feedback: Any) -> str:
    """A few words from any action's feedback message: its stage, distances, speed, error, percentage."""
    parts = []
    for name in ("stage_name", "distance_walked", "current_speed", "distance_remaining", "position_error", "percent_complete"):
        value = getattr(feedback, name, None)
        if isinstance(value, str) and value:
            parts.append(value)
        elif isinstance(value, (int, float)):
            parts.append(f"{name}={value:.3g}")
    return " ".join(parts)
