"""Pacing simulated time against wall time at a requested real-time factor."""

from __future__ import annotations

import collections
import time
from collections.abc import Callable


class Pacer:
    """Decides how long to wait so that sim time advances at ``factor`` x wall time.

    A factor of 0 means as fast as possible. When the simulation falls behind (it cannot keep
    up, or it was paused), the pacer re-anchors instead of running a catch-up burst.

    Args:
        factor: requested sim seconds per wall second (0 = unpaced).
        clock: monotonic wall clock [s]; injectable for tests.
        window_s: wall-time window over which the achieved factor is measured [s].
    """

    MAX_LAG_S = 0.1
    SAMPLE_SPACING_S = 0.01

    def __init__(self, factor: float, clock: Callable[[], float] = time.monotonic, window_s: float = 1.0) -> None:
        self._clock = clock
        self._window_s = window_s
        self._samples: collections.deque[tuple[float, float]] = collections.deque()
        self._anchor: tuple[float, float] | None = None
        self._factor = 0.0
        self.set_factor(factor)

    @property
    def factor(self) -> float:
        return self._factor

    def set_factor(self, factor: float) -> None:
        if not factor >= 0.0:
            raise ValueError(f"real-time factor must be >= 0 (0 = as fast as possible), got {factor}")
        self._factor = float(factor)
        self._anchor = None

    def reanchor(self) -> None:
        """Forget the pacing anchor (after a pause, or a jump of sim time)."""
        self._anchor = None
        self._samples.clear()

    def wait_time(self, sim_time: float) -> float:
        """Wall seconds to wait before the simulation may be at ``sim_time``."""
        now = self._clock()
        if self._factor == 0.0:
            return 0.0
        if self._anchor is None:
            self._anchor = (now, sim_time)
            return 0.0
        wall0, sim0 = self._anchor
        due = wall0 + (sim_time - sim0) / self._factor
        if now - due > self.MAX_LAG_S:
            self._anchor = (now, sim_time)
            return 0.0
        return max(0.0, due - now)

    def pace(self, sim_time: float) -> None:
        """Record that the simulation reached ``sim_time``, then sleep until it is due on the wall clock.

        This is the real-time loop's own rhythm (not a wait for an event); a sleep is at most
        one stretch of stepping long, so a stop request is seen within that time.
        """
        self.record(sim_time)
        wait = self.wait_time(sim_time)
        if wait > 0.0:
            time.sleep(wait)

    def record(self, sim_time: float) -> None:
        """Record that the simulation reached ``sim_time`` now (for the achieved factor)."""
        now = self._clock()
        samples = self._samples
        if len(samples) >= 2 and now - samples[-2][0] < self.SAMPLE_SPACING_S:
            samples[-1] = (now, sim_time)  # keep the window short: overwrite the newest sample
            return
        samples.append((now, sim_time))
        while len(samples) > 2 and now - samples[0][0] > self._window_s:
            samples.popleft()

    def achieved_factor(self) -> float:
        """Sim seconds per wall second over the last window (0 until two samples exist)."""
        if len(self._samples) < 2:
            return 0.0
        (wall0, sim0), (wall1, sim1) = self._samples[0], self._samples[-1]
        if wall1 <= wall0:
            return 0.0
        return (sim1 - sim0) / (wall1 - wall0)
