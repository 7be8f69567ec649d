"""The golden walk of the G1 walking controller: its scenario, and the recorder of ``walking_golden.npz``.

The scenario is a seeded core walk, driven as ``benchmarks/walk_bench.py`` drives it (a
:class:`Simulation` with a :class:`WalkingController` in the locomotion slot, one control step per
``sim.step(1)``): 0.5 m/s forward, then a turning and sidestepping stretch, a faster swing
(``step_duration`` 0.40 s) at 0.5 m/s, then a stop that closes the feet and hands the legs back to the
position servos. A seeded random horizontal force on the pelvis (redrawn every 0.1 s) keeps the step
adjustment and the CoP clipping busy.

One closed-loop run records, from the controller that was current when the file was written:

- ``checkpoint_*``: every :data:`CHECKPOINT_EVERY` control ticks, the physics state at the start of
  the tick (time, qpos, qvel, qacc_warmstart, ctrl) and the motor commands the controller wrote
  (``data.ctrl`` of the leg and waist actuators: torques [N m] while walking, position targets [rad]
  after the hand-over). A replay snaps the simulation to each recorded state before its tick, so the
  controller is compared on exactly the recorded states while its own internal state evolves as in
  the recording.
- ``free_*``: the walk itself (no snapping): base position [m] and yaw [rad] after each checkpoint
  tick, and the final qpos.

Regenerate (only when the controller's behaviour is meant to change, and say so in the commit):

    PYTHONPATH=. .venv/bin/python tests/core/data/walking_golden.py
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

import robot_models
from robot_models import g1_constants as names
from robot_models.biped import BipedDescription
from sim_bridge import Simulation, Slot
from sim_bridge.locomotion import GaitParameters, WalkingController

GOLDEN_FILE = Path(__file__).with_name("walking_golden.npz")
DURATION = 9.0  # sim time of the scenario [s]
CHECKPOINT_EVERY = 20  # control ticks between recorded states (0.08 s at 250 Hz)
DISTURBANCE_STD = 10.0  # std of the random horizontal pelvis force [N]
DISTURBANCE_EVERY = 25  # control ticks between redraws of that force (0.1 s)
SEED = 9
# (sim time since the start [s], velocity command (vx [m/s], vy [m/s], wz [rad/s]), step_duration or None)
SCHEDULE: tuple[tuple[float, tuple[float, float, float], float | None], ...] = (
    (0.0, (0.5, 0.0, 0.0), None),
    (3.0, (0.35, 0.05, 0.3), None),
    (4.5, (0.5, 0.0, 0.0), 0.40),
    (6.0, (0.0, 0.0, 0.0), None),
)
STATE_SPEC = (
    mujoco.mjtState.mjSTATE_TIME
    | mujoco.mjtState.mjSTATE_QPOS
    | mujoco.mjtState.mjSTATE_QVEL
    | mujoco.mjtState.mjSTATE_ACT
    | mujoco.mjtState.mjSTATE_WARMSTART
    | mujoco.mjtState.mjSTATE_CTRL
)
MOTOR_JOINTS = names.LEFT_LEG_JOINTS + names.RIGHT_LEG_JOINTS + names.WAIST_JOINTS


@dataclass
class Walk:
    """A G1 simulation with the walking controller installed, and the scenario's tick count."""

    sim: Simulation
    controller: WalkingController
    ticks: int
    motor_actuators: np.ndarray
    forces: np.ndarray  # (ticks // DISTURBANCE_EVERY + 1, 2) [N]
    modes: list[str] = field(default_factory=list)


def disturbance_forces(ticks: int) -> np.ndarray:
    """The seeded pelvis forces of the scenario, one (fx, fy) row per redraw, world frame [N]."""
    rng = np.random.default_rng(SEED)
    return rng.normal(0.0, DISTURBANCE_STD, (ticks // DISTURBANCE_EVERY + 1, 2))


def new_walk(robot: robot_models.RobotSpec,
             factory: Callable[[mujoco.MjModel, BipedDescription | None], WalkingController] = WalkingController) -> Walk:
    sim = Simulation(robot)
    controller = factory(sim.model, robot.biped)
    sim.set_controller(Slot.LOCOMOTION, controller)
    ticks = round(DURATION / sim.control_timestep)
    motors = np.array([sim.model.actuator(j).id for j in MOTOR_JOINTS])
    return Walk(sim, controller, ticks, motors, disturbance_forces(ticks))


def run(walk: Walk, before_tick: Callable[[int], None], after_tick: Callable[[int], None]) -> None:
    """Drive the scenario tick by tick; ``before_tick(k)`` / ``after_tick(k)`` run around control tick ``k``."""
    sim, controller = walk.sim, walk.controller
    pelvis = sim.model.body(names.ROOT_BODY).id
    start = sim.time
    schedule = list(SCHEDULE)
    for k in range(walk.ticks):
        while schedule and sim.time - start >= schedule[0][0] - 1e-9:
            _, command, step_duration = schedule.pop(0)
            if step_duration is not None:
                params = GaitParameters(**{**vars(controller.params), "step_duration": step_duration})
                controller.set_gait_parameters(params)
            controller.set_velocity_command(*command)
        if k % DISTURBANCE_EVERY == 0:
            sim.data.xfrc_applied[pelvis, :2] = walk.forces[k // DISTURBANCE_EVERY]
        before_tick(k)
        sim.step(1)
        after_tick(k)
    walk.modes.append(controller.status().mode.value)


def base_pose(sim: Simulation) -> np.ndarray:
    """Pelvis (x, y, z) [m] and yaw [rad] in world."""
    body = sim.data.body(names.ROOT_BODY)
    return np.array([*body.xpos, math.atan2(body.xmat[3], body.xmat[0])])


def record(robot: robot_models.RobotSpec) -> dict[str, np.ndarray]:
    """Run the scenario once, recording the checkpoint states, the commands written there and the base poses."""
    walk = new_walk(robot)
    states: list[np.ndarray] = []
    commands: list[np.ndarray] = []
    poses: list[np.ndarray] = []
    state = np.zeros(mujoco.mj_stateSize(walk.sim.model, STATE_SPEC))

    def before(k: int) -> None:
        if k % CHECKPOINT_EVERY == 0:
            mujoco.mj_getState(walk.sim.model, walk.sim.data, state, STATE_SPEC)
            states.append(state.copy())

    def after(k: int) -> None:
        if k % CHECKPOINT_EVERY == 0:
            commands.append(walk.sim.data.ctrl[walk.motor_actuators].copy())
            poses.append(base_pose(walk.sim))

    run(walk, before, after)
    golden = {
        "checkpoint_state": np.array(states),
        "checkpoint_command": np.array(commands),
        "free_pose": np.array(poses),
        "free_final_qpos": walk.sim.data.qpos.copy(),
        "final_mode": np.array(walk.modes[-1]),
        "steps_taken": np.array(walk.controller.status().steps_taken),
    }
    walk.sim.reset()
    return golden


def main() -> None:
    golden = record(robot_models.load("g1"))
    np.savez_compressed(
        GOLDEN_FILE,
        checkpoint_state=golden["checkpoint_state"],
        checkpoint_command=golden["checkpoint_command"],
        free_pose=golden["free_pose"],
        free_final_qpos=golden["free_final_qpos"],
        final_mode=golden["final_mode"],
        steps_taken=golden["steps_taken"],
    )
    print(f"wrote {GOLDEN_FILE} ({GOLDEN_FILE.stat().st_size / 1e3:.0f} kB): "
          f"{len(golden['checkpoint_state'])} checkpoints, {int(golden['steps_taken'])} steps, "
          f"final mode {golden['final_mode']}, final base {golden['free_pose'][-1].round(4)}")


if __name__ == "__main__":
    main()
