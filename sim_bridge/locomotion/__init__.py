"""Physics walking for bipeds: DCM footstep planning and a whole-body torque QP, run in the control step.

Usage::

    sim = Simulation(robot_models.load(robot_models.G1))
    walker = WalkingController(sim.model, sim.robot.biped)
    sim.set_controller(Slot.LOCOMOTION, walker)
    walker.set_velocity_command(0.3, 0.0, 0.0)  # [m/s, m/s, rad/s] in the heading frame
    sim.step(1000)
    walker.set_velocity_command(0.0, 0.0, 0.0)  # closes the feet and stands; servos take over
    walker.status()  # LocomotionStatus(mode=..., steps_taken=..., measured=...)

The robot comes in as a :class:`~robot_models.biped.BipedDescription` (its names, walking crouch,
step geometry and limits), the ``biped`` of its :class:`~robot_models.RobotSpec`. Gait parameters change live with
``walker.set_gait_parameters(dataclasses.replace(walker.params, ...))``; an out-of-range value raises
``InvalidGoalError`` naming the range in :data:`PARAMETER_RANGES`.

Modules, one concept each: :mod:`.controller` (the public API, composing the parts), :mod:`.command`
(command filtering), :mod:`.phases` (the gait phase machine), :mod:`.footsteps` (footstep planning),
:mod:`.path` (line keeping, pace integral), :mod:`.stopping` (stop point and heading), :mod:`.preview`
(the ZMP/DCM preview), :mod:`.tracking` (DCM tracking, foot loads), :mod:`.adjustment` (step position
and timing), :mod:`.swing` (swing trajectory), :mod:`.estimation` (measurements, fall detection),
:mod:`.actuation` (servo/torque hand-over), :mod:`.wbc` and :mod:`.wbc_layout` (the torque QP),
:mod:`.geometry` (floor-plane geometry), :mod:`.params` and :mod:`.types` (configuration, reports).
"""

from sim_bridge.locomotion.controller import WalkingController
from sim_bridge.locomotion.params import PARAMETER_RANGES, GaitParameters
from sim_bridge.locomotion.types import GaitPhase, LocomotionMode, LocomotionStatus, Twist2D

__all__ = [
    "PARAMETER_RANGES", "GaitParameters", "GaitPhase", "LocomotionMode", "LocomotionStatus", "Twist2D", "WalkingController",
]
