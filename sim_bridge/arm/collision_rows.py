"""The rows of mink's collision limit an arm-only IK step needs: the pairs within the detection distance."""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy as np

if TYPE_CHECKING:
    import mink


class CollisionRows:
    """The active rows of a :class:`mink.CollisionAvoidanceLimit`, on the arm's columns.

    Row and bound of a pair are mink's: the contact normal times the difference of the two
    witness points' Jacobians, bounded by ``gain * (distance - minimum) / dt`` (``relaxation``
    once closer than the minimum). A pair farther apart than the detection distance gives no row;
    as in mink, pairs whose bounding spheres are that far apart skip the distance query when there
    are enough pairs for that test to pay.

    Args:
        limit: the mink limit (its pairs and parameters are used as they are).
        data: the IK configuration's data.
        dof_adr: the arm's DoF addresses, shape (n,).
    """

    BROADPHASE_MIN_PAIRS = 16  # as mink: below this, querying every pair is cheaper than the sphere test

    def __init__(self, limit: mink.CollisionAvoidanceLimit, data: mujoco.MjData, dof_adr: np.ndarray) -> None:
        model = limit.model
        self.model, self.data, self.dof_adr = model, data, dof_adr
        self.gain = limit.gain
        self.minimum = limit.minimum_distance_from_collisions
        self.detection = limit.collision_detection_distance
        self.relaxation = limit.bound_relaxation
        pairs = np.array(limit.geom_id_pairs, dtype=int).reshape(-1, 2)
        # (geom1, geom2, body1, body2) of each pair, as Python ints for the per-pair loop.
        self.pairs = [(int(a), int(b), int(model.geom_bodyid[a]), int(model.geom_bodyid[b])) for a, b in pairs]
        # The pairs as cells of a grid (first geoms x second geoms), so the sphere test gathers each
        # geom's position once: the squared reach of each cell (inf: always a candidate, -1: no pair).
        geom1, geom2 = pairs[:, 0], pairs[:, 1]
        self.first, self.second = np.unique(geom1), np.unique(geom2)
        row, column = np.searchsorted(self.first, geom1), np.searchsorted(self.second, geom2)
        reach = model.geom_rbound[geom1] + model.geom_rbound[geom2] + self.detection
        unbounded = (model.geom_rbound[geom1] <= 0.0) | (model.geom_rbound[geom2] <= 0.0)  # planes, height fields
        self.reach_squared = np.full((len(self.first), len(self.second)), -1.0)
        self.reach_squared[row, column] = np.where(unbounded, np.inf, reach * reach)
        self.pair_of_cell = np.full(self.reach_squared.shape, -1, dtype=int)
        self.pair_of_cell[row, column] = np.arange(len(pairs))
        self._fromto = np.empty(6)
        self._normal = np.empty(3)
        self._jac1 = np.empty((3, model.nv))
        self._jac2 = np.empty((3, model.nv))

    def candidates(self) -> list[int]:
        """Indices of the pairs that may be within the detection distance (bounding spheres, unbounded geoms)."""
        if len(self.pairs) < self.BROADPHASE_MIN_PAIRS:
            return list(range(len(self.pairs)))
        xpos = self.data.geom_xpos
        offset = xpos[self.first][:, None, :] - xpos[self.second][None, :, :]
        near = np.einsum("ijk,ijk->ij", offset, offset) <= self.reach_squared
        indices: list[int] = self.pair_of_cell[near].tolist()
        return indices

    def compute(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Rows (m, n) and bounds (m,) of the pairs within the detection distance, for a step of ``dt`` [s]."""
        model, data = self.model, self.data
        fromto, normal, jac1, jac2 = self._fromto, self._normal, self._jac1, self._jac2
        detection = self.detection
        rows: list[np.ndarray] = []
        bounds: list[float] = []
        for index in self.candidates():
            geom1, geom2, body1, body2 = self.pairs[index]
            distance = mujoco.mj_geomDistance(model, data, geom1, geom2, detection, fromto)
            if abs(distance - detection) < 1e-12:
                continue
            np.subtract(fromto[3:], fromto[:3], out=normal)
            mujoco.mju_normalize3(normal)
            mujoco.mj_jac(model, data, jac2, None, fromto[3:], body2)
            mujoco.mj_jac(model, data, jac1, None, fromto[:3], body1)
            jac2 -= jac1
            row = normal @ jac2[:, self.dof_adr]
            rows.append(-row if distance >= 0.0 else row)
            if distance > self.minimum:
                bounds.append(self.gain * (distance - self.minimum) / dt + self.relaxation)
            else:
                bounds.append(self.relaxation)
        if not rows:
            return np.zeros((0, len(self.dof_adr))), np.zeros(0)
        return np.array(rows), np.array(bounds)
