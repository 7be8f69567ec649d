"""The MuJoCo physics options of a robot scene, set in one place for every robot."""

from __future__ import annotations

import mujoco


def set_physics_options(spec: mujoco.MjSpec, *, timestep_s: float, impratio: float) -> None:
    """Set the integrator and contact model every robot scene is simulated with.

    - ``implicitfast``: integrates joint damping and the position servos' velocity gains implicitly,
      so stiff servos stay stable at a step of a few milliseconds.
    - An elliptic friction cone with ``impratio`` > 1: frictional contacts (a sole on the floor, fingers
      squeezing a box) stick instead of creeping, as friction does.

    Args:
        spec: the scene, before compiling.
        timestep_s: physics step [s].
        impratio: ratio of frictional to normal constraint impedance (MuJoCo's ``impratio``).
    """
    spec.option.timestep = timestep_s
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = impratio
