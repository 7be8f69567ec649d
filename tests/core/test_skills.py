"""Goal skills in the control step, in-process: a walk ends on its goal, resets, preemption, cancel."""

from __future__ import annotations

import pytest

import robot_models
from sim_bridge import Simulation, Slot
from sim_bridge.errors import InvalidGoalError
from sim_bridge.locomotion import LocomotionMode, WalkingController
from sim_bridge.skills import SkillHost, SkillRun, SkillStatus, WalkGoal, WalkSkill


@pytest.fixture(scope="module")
def g1() -> robot_models.RobotSpec:
    return robot_models.load("g1")


@pytest.fixture
def legs(g1):
    sim = Simulation(g1)
    walker = WalkingController(sim.model, sim.robot.biped)
    host = SkillHost(walker)
    sim.set_controller(Slot.LOCOMOTION, host)
    yield sim, walker, host
    sim.reset()


def _walk(g1, walker, distance: float, speed: float = 0.3) -> WalkSkill:
    assert g1.walking is not None
    return WalkSkill(walker, g1.base_body, WalkGoal(distance, speed, 0.0, g1.walking), {})


def _run_until_ended(sim: Simulation, run: SkillRun, seconds: float) -> None:
    end = sim.time + seconds
    while run.status is SkillStatus.RUNNING:
        assert sim.time < end, f"still running after {seconds} s of sim time"
        sim.step(1)


def test_a_walk_plans_its_last_steps_onto_the_goal_and_ends_standing_there(g1, legs):
    sim, walker, host = legs
    run = host.start(1, _walk(g1, walker, 1.0), sim.model, sim.data)
    _run_until_ended(sim, run, 20.0)
    assert run.status is SkillStatus.SUCCEEDED and run.outcome is not None and run.outcome.code == "SUCCESS"
    assert run.final_result["final_distance"] == pytest.approx(1.0, abs=0.01)
    assert walker.status().mode is LocomotionMode.STANDING


def test_a_reset_ends_the_running_goal_with_sim_fault_and_counts_an_epoch(g1, legs):
    sim, walker, host = legs
    run = host.start(2, _walk(g1, walker, 2.0), sim.model, sim.data)
    sim.step(300)
    epoch = host.epoch
    sim.reset()
    assert run.status is SkillStatus.ABORTED and run.outcome is not None and run.outcome.code == "SIM_FAULT"
    assert host.epoch == epoch + 1 and host.running("legs") is None


def test_a_new_goal_preempts_and_a_cancel_ends_once_the_robot_stands(g1, legs):
    sim, walker, host = legs
    first = host.start(3, _walk(g1, walker, 2.0), sim.model, sim.data)
    sim.step(300)
    second = host.start(4, _walk(g1, walker, 2.0), sim.model, sim.data)
    assert first.status is SkillStatus.ABORTED and first.outcome is not None and first.outcome.code == "PREEMPTED"
    sim.step(300)
    assert host.cancel("legs", 4)
    sim.step(1)
    assert second.status is SkillStatus.RUNNING, "a cancel waits until the robot is safe"
    _run_until_ended(sim, second, 10.0)
    assert second.status is SkillStatus.CANCELED
    assert walker.status().mode is LocomotionMode.STANDING


def test_bad_walk_goals_say_what_is_allowed(g1):
    assert g1.walking is not None
    with pytest.raises(InvalidGoalError, match="within"):
        WalkGoal(1e6, 0.0, 0.0, g1.walking)
    with pytest.raises(InvalidGoalError, match="speed must be in"):
        WalkGoal(1.0, 5.0, 0.0, g1.walking)
    with pytest.raises(InvalidGoalError, match="finite"):
        WalkGoal(float("nan"), 0.0, 0.0, g1.walking)
