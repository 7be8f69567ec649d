"""Physics walking for the G1: DCM footstep planning and a whole-body torque QP, run in the control step.

Usage::

    sim = Simulation(robot_models.load("g1"))
    walker = WalkingController(sim.model)
    sim.set_controller(Slot.LOCOMOTION, walker)
    walker.set_velocity_command(0.3, 0.0, 0.0)  # [m/s, m/s, rad/s] in the heading frame
    sim.step(1000)
    walker.set_velocity_command(0.0, 0.0, 0.0)  # closes the feet and stands; servos take over
    walker.status()  # LocomotionStatus(mode=..., steps_taken=..., measured=...)

Gait parameters change live with ``walker.set_gait_parameters(dataclasses.replace(walker.params, ...))``;
an out-of-range value raises ``InvalidGoalError`` naming the range in :data:`PARAMETER_RANGES`.
"""

from sim_bridge.locomotion.controller import WalkingController
from sim_bridge.locomotion.params import PARAMETER_RANGES, GaitParameters
from sim_bridge.locomotion.types import LocomotionMode, LocomotionStatus, Twist2D

__all__ = ["PARAMETER_RANGES", "GaitParameters", "LocomotionMode", "LocomotionStatus", "Twist2D", "WalkingController"]
