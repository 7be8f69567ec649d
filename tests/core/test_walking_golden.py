"""The walking controller reproduces its golden walk (``tests/core/data/walking_golden.npz``).

The golden file was recorded from the controller before its rewrite for speed (scenario and recorder
in ``tests/core/data/walking_golden.py``); these tests pin the behaviour through any refactoring:

- on the recorded walking states, the commands the controller writes equal the recorded ones within
  :data:`COMMAND_TOLERANCE` (the simulation is snapped to each recorded state before its tick);
- the same seeded walk, run freely, keeps the base within :data:`POSITION_TOLERANCE` of the recorded
  trajectory at every checkpoint, ends within it, and takes the same number of steps.

Measured margin: white noise of 1e-3 N m added to every torque of every tick moves the free walk's
base by at most 0.1 mm, so both tolerances leave room for rounding while a change of behaviour fails.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import robot_models
from tests.core.data import walking_golden as golden_walk

COMMAND_TOLERANCE = 1e-3  # [N m] for torques (and [rad] for the position targets after the hand-over)
POSITION_TOLERANCE = 1e-3  # base position [m]
YAW_TOLERANCE = 1e-3  # base yaw [rad]


@pytest.fixture(scope="module")
def golden() -> dict[str, np.ndarray]:
    with np.load(golden_walk.GOLDEN_FILE) as data:
        return dict(data)


@pytest.fixture(scope="module")
def g1_robot() -> robot_models.RobotSpec:
    return robot_models.load("g1")


def test_commands_on_the_recorded_states_equal_the_golden_ones(golden, g1_robot):
    walk = golden_walk.new_walk(g1_robot)
    model, data = walk.sim.model, walk.sim.data
    states, expected = golden["checkpoint_state"], golden["checkpoint_command"]
    commands: list[np.ndarray] = []

    def before(k: int) -> None:
        if k % golden_walk.CHECKPOINT_EVERY == 0:
            mujoco.mj_setState(model, data, states[k // golden_walk.CHECKPOINT_EVERY], golden_walk.STATE_SPEC)

    def after(k: int) -> None:
        if k % golden_walk.CHECKPOINT_EVERY == 0:
            commands.append(data.ctrl[walk.motor_actuators].copy())

    try:
        golden_walk.run(walk, before, after)
    finally:
        walk.sim.reset()
    error = np.abs(np.array(commands) - expected)
    worst = np.unravel_index(np.argmax(error), error.shape)
    assert error.max() <= COMMAND_TOLERANCE, (
        f"command {worst[1]} at checkpoint {worst[0]} (t={states[worst[0], 0]:.3f} s) differs by {error.max():.2e} "
        f"(golden {expected[worst]:.4f}, now {commands[worst[0]][worst[1]]:.4f}); tolerance {COMMAND_TOLERANCE}"
    )


def test_the_seeded_walk_follows_the_golden_trajectory(golden, g1_robot):
    walk = golden_walk.new_walk(g1_robot)
    poses: list[np.ndarray] = []

    def after(k: int) -> None:
        if k % golden_walk.CHECKPOINT_EVERY == 0:
            poses.append(golden_walk.base_pose(walk.sim))

    try:
        golden_walk.run(walk, lambda k: None, after)
        steps = walk.controller.status().steps_taken
    finally:
        walk.sim.reset()
    expected = golden["free_pose"]
    position_error = np.linalg.norm(np.array(poses)[:, :3] - expected[:, :3], axis=1)
    yaw_error = np.abs(np.array(poses)[:, 3] - expected[:, 3])
    worst = int(np.argmax(position_error))
    assert position_error.max() <= POSITION_TOLERANCE, (
        f"base {1e3 * position_error.max():.3f} mm off the golden walk at checkpoint {worst}; "
        f"tolerance {1e3 * POSITION_TOLERANCE:g} mm"
    )
    assert yaw_error.max() <= YAW_TOLERANCE, f"base yaw {yaw_error.max():.2e} rad off the golden walk"
    assert walk.modes[-1] == str(golden["final_mode"])
    assert steps == int(golden["steps_taken"])
