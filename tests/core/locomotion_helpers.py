"""Array-form wrappers of the walking controller's float geometry, for readable unit tests.

The controller works on plain ``(x, y)`` tuples (:mod:`sim_bridge.locomotion.geometry`) and a reused
:class:`~sim_bridge.locomotion.preview.ZmpPreview`; these take and return numpy arrays.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from sim_bridge.locomotion.geometry import clip_point, hull_of
from sim_bridge.locomotion.preview import DcmReference, ZmpPreview


@dataclass(frozen=True)
class ZmpSegment:
    """A piece of the ZMP reference that moves linearly from ``start`` to ``end``.

    Attributes:
        duration: length of the segment [s].
        start: ZMP at the start, shape (2,) [m].
        end: ZMP at the end, shape (2,) [m].
    """

    duration: float
    start: np.ndarray
    end: np.ndarray


def dcm_reference(segments: Sequence[ZmpSegment], elapsed: float, omega: float) -> DcmReference:
    """DCM reference at ``elapsed`` seconds into the first segment (see :class:`ZmpPreview`).

    Args:
        segments: ZMP pieces, the first one being the current one.
        elapsed: time already spent in the first segment [s].
        omega: LIPM natural frequency sqrt(g / z_c) [1/s].
    """
    preview = ZmpPreview()
    for segment in segments:
        preview.add(float(segment.duration), (float(segment.start[0]), float(segment.start[1])),
                    (float(segment.end[0]), float(segment.end[1])))
    return preview.reference(elapsed, omega, preview.dcm_at_first_end(omega))


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull of 2-D points, shape (k, 2) (array form of :func:`hull_of`)."""
    return np.array(hull_of([(float(p[0]), float(p[1])) for p in np.asarray(points, dtype=float)]))


def clip_to_polygon(point: np.ndarray, hull: np.ndarray) -> np.ndarray:
    """The point itself if it is inside the counter-clockwise convex polygon, else the nearest boundary point."""
    vertices = [(float(p[0]), float(p[1])) for p in hull]
    return np.array(clip_point(float(point[0]), float(point[1]), vertices))
