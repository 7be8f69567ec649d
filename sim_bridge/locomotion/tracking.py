"""DCM tracking: from the DCM reference to a desired CoP, hence a CoM acceleration; and the feet's loads.

With the linear inverted pendulum, the DCM xi = c + c_dot / omega diverges from the CoP p as
xi_dot = omega (xi - p). Tracking the reference with gain k asks for the CoP
p = p_ref + (1 + k / omega) (xi - xi_ref), clipped to the support polygon; the CoM then accelerates
as omega^2 (c - p), and its height is held by a PD.
"""

from __future__ import annotations

import math

import numpy as np

from sim_bridge.locomotion.geometry import Point, Vec3, clip_point
from sim_bridge.locomotion.phases import GaitState, Phase
from sim_bridge.locomotion.preview import DcmReference
from sim_bridge.locomotion.wbc import GRAVITY

DCM_GAIN = 6.0  # DCM tracking gain k [1/s]
HEIGHT_KP, HEIGHT_KD = 100.0, 20.0  # CoM height PD [1/s^2, 1/s]
LOAD_RAMP = 0.03  # time for a touching-down foot to take full load [s]


class DcmTracking:
    """DCM tracking at a constant CoM height.

    Args:
        com_height: CoM height the walk keeps above the floor [m].

    Attributes:
        omega: LIPM natural frequency sqrt(g / com_height) [1/s].
    """

    def __init__(self, com_height: float) -> None:
        self.com_height = com_height
        self.omega = math.sqrt(GRAVITY / com_height)

    def cop(self, reference: DcmReference, dcm: Point, support: list[Point]) -> Point:
        """The desired CoP [m] for the measured ``dcm`` [m], within the ``support`` polygon (counter-clockwise)."""
        gain = 1.0 + DCM_GAIN / self.omega
        cop_x = reference.zmp_x + gain * (dcm[0] - reference.dcm_x)
        cop_y = reference.zmp_y + gain * (dcm[1] - reference.dcm_y)
        return clip_point(cop_x, cop_y, support)

    def com_acceleration(self, com: Vec3, com_vz: float, cop: Point) -> np.ndarray:
        """The CoM acceleration [m/s^2], shape (3,), for the CoM ``com`` [m], its vertical speed [m/s] and the CoP [m]."""
        cx, cy, cz = com
        omega2 = self.omega**2
        return np.array([
            omega2 * (cx - cop[0]),
            omega2 * (cy - cop[1]),
            HEIGHT_KP * (self.com_height - cz) - HEIGHT_KD * com_vz,
        ])


def foot_loads(gait: GaitState) -> tuple[float, float]:
    """The (left, right) bound on each foot's normal force as a fraction of full load, in [0, 1].

    The swing foot carries nothing; in double support the foot that just landed takes its load
    over :data:`LOAD_RAMP` while the other one gives it up over the phase.
    """
    load = [1.0, 1.0]
    stance = gait.stance
    if gait.phase is Phase.SINGLE:
        load[stance.other.index] = 0.0
    elif gait.phase is Phase.DOUBLE:
        load[stance.index] = min(1.0, gait.elapsed / LOAD_RAMP)
        load[stance.other.index] = max(0.0, 1.0 - gait.elapsed / max(gait.duration, 1e-6))
    return load[0], load[1]
