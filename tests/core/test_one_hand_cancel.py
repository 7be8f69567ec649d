"""A cancel of the one-hand fetch, stage by stage: the robot stops and stands, and the hand keeps what it holds; a
later fetch of the cube in the hand goes straight to the place (issue 21, in the core, real physics, no weld)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pytest

import robot_models
from robot_models import g1_tables
from sim_bridge.arm import PickPlaceStage
from sim_bridge.controller import Slot
from sim_bridge.fetch import FetchGoal, OneHandFetch
from sim_bridge.fetch.bimanual import tilt_of
from sim_bridge.fetch.one_hand import finger_forces, holds
from sim_bridge.fetch.rig import FetchRig
from sim_bridge.locomotion import LocomotionMode
from sim_bridge.skills import SkillRun, SkillStatus
from tests.forks import in_fork

PLACE = (1.02, -2.8)  # on the second table, 12 cm inside its edge facing the robot's side
CUBE = g1_tables.CUBE
REST = np.asarray(g1_tables.object_rest_position(CUBE))
MAX_SIM_S = 150.0
STOP_S = 15.0  # a canceled fetch ends within this [s of sim time]
SETTLE_S = 2.0  # ... and the robot stands still this long after [s]


@pytest.fixture(scope="module")
def robot() -> robot_models.RobotSpec:
    return robot_models.load(robot_models.G1, "tables")


def _step_until(rig: FetchRig, run: SkillRun, done: Callable[[], bool], deadline_s: float) -> None:
    """Step the rig's simulation until ``done()`` or the run ends; fail past ``deadline_s`` [s of sim time]."""
    while run.status is SkillStatus.RUNNING and not done():
        assert rig.sim.time < deadline_s, f"not there by {deadline_s:.0f} s of sim time"
        rig.sim.step(1)
        assert not rig.walker.status().fallen


def _cancel(rig: FetchRig, run: SkillRun, goal_id: int) -> None:
    """Cancel the fetch, wait for its end, let the robot settle; it stands and has not fallen."""
    assert rig.legs.cancel("legs", goal_id)
    _step_until(rig, run, lambda: False, rig.sim.time + STOP_S)
    assert run.outcome is not None and run.status is SkillStatus.CANCELED, run.outcome
    rig.sim.step(round(SETTLE_S / rig.sim.control_timestep))
    status = rig.walker.status()
    assert status.mode is LocomotionMode.STANDING and not status.fallen, status


def _start(rig: FetchRig, goal_id: int) -> tuple[OneHandFetch, SkillRun]:
    skill = rig.skill(FetchGoal(CUBE.name, *PLACE))
    assert isinstance(skill, OneHandFetch)
    return skill, rig.legs.start(goal_id, skill, rig.sim.model, rig.sim.data)


def _in_phase(rig: FetchRig, skill: OneHandFetch, phase: str, after_s: float) -> Callable[[], bool]:
    """A condition: ``skill`` has been in ``phase`` for ``after_s`` [s of sim time]."""
    entered_s: float | None = None

    def done() -> bool:
        nonlocal entered_s
        if skill.feedback(rig.sim.data)["phase"] != phase:
            return False
        entered_s = rig.sim.time if entered_s is None else entered_s
        return rig.sim.time - entered_s >= after_s
    return done


def _on_a_table(x: float, y: float) -> bool:
    return any(x0 <= x <= x1 and y0 <= y <= y1 for x0, x1, y0, y1 in (t.xy_bounds for t in g1_tables.TABLES))


BEFORE_THE_LIFT = (("navigate_pick", 2.0, "APPROACH"), ("reach", 0.3, "DESCEND"), ("close", 0.5, "GRASP"))


@dataclass
class Trunk:
    """One fetch of the cube, run once to 0.8 s into the lift: each cancel before the lift branched off it."""

    rig: FetchRig
    skill: OneHandFetch
    run: SkillRun
    branches: dict[str, str | None]  # phase -> why its cancel failed (None: passed)


@pytest.fixture(scope="module")
def trunk(robot) -> Trunk:
    """The fetch every test here starts with, stepped once: at each cancel point before the lift, a forked copy of
    this process cancels there and checks what the test names (:func:`tests.forks.in_fork`: the state a fresh
    run would have at that instant, exactly); the fetch itself goes on, never canceled, to the lift."""
    rig = FetchRig.of(robot)
    skill, run = _start(rig, 1)
    branches: dict[str, str | None] = {}
    for phase, after_s, stage in BEFORE_THE_LIFT:
        _step_until(rig, run, _in_phase(rig, skill, phase, after_s), MAX_SIM_S)
        assert run.status is SkillStatus.RUNNING, (run.outcome, skill.events)
        branches[phase] = in_fork(lambda phase=phase, stage=stage: _cancel_before_the_lift(rig, skill, run, phase, stage))
    _step_until(rig, run, _in_phase(rig, skill, "lift", 0.8), MAX_SIM_S)
    return Trunk(rig, skill, run, branches)


def _cancel_before_the_lift(rig: FetchRig, skill: OneHandFetch, run: SkillRun, phase: str, stage: str) -> None:
    _cancel(rig, run, 1)
    assert run.outcome is not None and f"canceled in stage {stage}" in run.outcome.message, run.outcome
    cube = rig.sim.data.body(CUBE.name)
    print(f"canceled in {phase}: {run.outcome.message}; the cube at {np.round(cube.xpos, 4)}, {rig.sim.time:.1f} s sim")
    assert cube.xpos[2] > g1_tables.TABLE_TOP_Z_M, "not knocked off the table"
    assert np.linalg.norm(cube.xpos - REST) < 0.01 and math.degrees(tilt_of(cube.xquat)) < 3.0, cube.xpos
    if phase == "close":  # half a second of closing: the thumb and a finger have it, and keep it
        assert "holding the object" in run.outcome.message
        forces = finger_forces(rig.sim.model, rig.sim.data, skill.hand, rig.sim.model.body(CUBE.name).id)
        assert holds(forces, skill.hand, skill.hand_config.hold_force_n), forces


@pytest.mark.parametrize("phase", [phase for phase, _, _ in BEFORE_THE_LIFT])
def test_a_cancel_before_the_lift_stops_and_stands_and_the_cube_stays_on_its_table(trunk, phase):
    """Walking to the cube, reaching for it, closing the fingers on it (then the hand holds it where it rests)."""
    failure = trunk.branches[phase]
    assert failure is None, f"the cancel in {phase}, in its branch of the fetch:\n{failure}"


def test_a_cancel_lifting_or_carrying_keeps_the_cube_in_the_hand_and_a_new_fetch_goes_straight_to_the_place(trunk):
    rig, skill, run = trunk.rig, trunk.skill, trunk.run
    sim = rig.sim
    body = sim.model.body(CUBE.name).id

    def held_up(fetch: OneHandFetch, rise_m: float) -> None:
        forces = finger_forces(sim.model, sim.data, fetch.hand, body)
        assert holds(forces, fetch.hand, fetch.hand_config.hold_force_n), forces
        assert sim.data.xpos[body][2] > REST[2] + rise_m, "held up above the table"

    # Lifting (the trunk stopped 0.8 s into the lift): the robot stands at the table holding the cube where the lift stopped.
    _cancel(rig, run, 1)
    assert run.outcome is not None and "canceled in stage LIFT" in run.outcome.message
    assert "holding the object" in run.outcome.message, run.outcome
    held_up(skill, 0.01)
    lifted_z = float(sim.data.xpos[body][2])  # the carry keeps it where the lift stopped

    # A new fetch of the cube in the hand: straight to the place (no walk to the object, no reach); canceled carrying.
    carried, second = _start(rig, 2)
    assert carried.stage is PickPlaceStage.TRANSPORT, carried.events
    _step_until(rig, second, _in_phase(rig, carried, "navigate_place", 2.0), sim.time + MAX_SIM_S)
    assert rig.walker.status().mode is LocomotionMode.WALKING
    _cancel(rig, second, 2)
    assert second.outcome is not None and "canceled in stage TRANSPORT" in second.outcome.message
    assert "holding the object" in second.outcome.message, second.outcome
    held_up(carried, 0.01)
    assert sim.data.xpos[body][2] > lifted_z - 0.005, "not sagging in the hand"
    x, y = sim.data.xpos[body][:2]
    assert not _on_a_table(float(x), float(y)), "carried between the tables"

    # And again: it carries the cube on to the place and puts it down.
    last, third = _start(rig, 3)
    stages: list[int] = []
    _step_until(rig, third, lambda: stages.append(last.milestone) is not None, sim.time + MAX_SIM_S)
    assert third.status is SkillStatus.SUCCEEDED, (third.outcome, last.events)
    for fetch in (carried, last):
        phases = {event.split()[2] for event in fetch.events}
        assert not phases & {"navigate_pick", "ready_pick", "beside", "reach", "close"}, fetch.events
    assert stages[0] == PickPlaceStage.TRANSPORT and stages == sorted(stages), sorted(set(stages))
    error = float(np.linalg.norm(sim.data.xpos[body] - np.array([*PLACE, REST[2]])))
    print(f"canceled lifting and carrying, then placed {error * 1e3:.1f} mm from the place at {sim.time:.1f} s sim")
    assert error <= 0.02 and math.degrees(tilt_of(sim.data.xquat[body])) < 3.0, f"placed {error * 1e3:.1f} mm away"
    rig.sim.set_controller(Slot.LOCOMOTION, None)
