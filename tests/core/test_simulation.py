"""The simulation core: stepping, reset, pacing, and its independence from ROS."""

from __future__ import annotations

import ast
import math
import pathlib

import numpy as np
import pytest

import robot_models
from sim_bridge import Pacer, Simulation, UnknownNameError

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("package", ["sim_bridge", "robot_models"])
def test_core_never_imports_rclpy(package):
    offenders = []
    for path in (ROOT / package).rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = []
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            offenders += [f"{path.relative_to(ROOT)}: {n}" for n in names if n.split(".")[0] in ("rclpy", "rosidl_runtime_py")]
    assert not offenders


@pytest.fixture(scope="module")
def panda_sim():
    return Simulation(robot_models.load("panda"))


def test_control_step_is_a_whole_multiple_of_the_physics_step(panda_sim):
    ratio = panda_sim.control_timestep / panda_sim.physics_timestep
    assert ratio == pytest.approx(round(ratio)) and round(ratio) >= 1
    t0 = panda_sim.time
    panda_sim.step(10)
    assert panda_sim.time == pytest.approx(t0 + 10 * panda_sim.control_timestep)


def test_reset_restores_state_exactly_and_keeps_time_monotonic(panda_sim):
    panda_sim.servo.set_targets({"panda_joint1": 0.5})
    panda_sim.step(100)
    moved = panda_sim.snapshot()
    assert moved.joint_positions[0] > 0.3
    before = panda_sim.time
    panda_sim.reset()
    after = panda_sim.snapshot()
    assert after.time == pytest.approx(before)
    key = panda_sim.model.key("home")
    expected = [key.qpos[panda_sim.model.joint(j).qposadr[0]] for j in panda_sim.robot.actuated_joints]
    np.testing.assert_array_equal(after.joint_positions, expected)
    with pytest.raises(UnknownNameError, match="home"):
        panda_sim.reset("nope")
    assert panda_sim.snapshot().time == pytest.approx(before)


def test_servo_refuses_unknown_joints_without_changing_anything(panda_sim):
    with pytest.raises(UnknownNameError, match="panda_joint1"):
        panda_sim.servo.set_targets({"panda_joint2": 0.1, "elbow": 0.2})
    assert not panda_sim.servo.active


def test_same_commands_give_the_same_trajectory():
    runs = []
    for _ in range(2):
        sim = Simulation(robot_models.load("panda"))
        sim.servo.set_targets({"panda_joint1": 0.4, "panda_joint4": -2.0})
        sim.step(200)
        runs.append(sim.data.qpos.copy())
    np.testing.assert_array_equal(runs[0], runs[1])


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_pacer_waits_for_wall_time_and_measures_the_achieved_factor():
    clock = FakeClock()
    pacer = Pacer(2.0, clock=clock)
    assert pacer.wait_time(0.0) == 0.0  # anchors
    assert pacer.wait_time(1.0) == pytest.approx(0.5)  # 1 s of sim at 2x takes 0.5 s of wall
    for i in range(11):
        clock.now = 100.0 + 0.1 * i
        pacer.record(0.2 * i)
    assert pacer.achieved_factor() == pytest.approx(2.0)
    pacer.set_factor(0.0)
    assert pacer.wait_time(50.0) == 0.0
    with pytest.raises(ValueError, match=">= 0"):
        pacer.set_factor(-1.0)


def test_pacer_measures_the_factor_from_many_closely_spaced_samples():
    clock = FakeClock()
    pacer = Pacer(0.0, clock=clock)
    for i in range(1000):  # 1 ms of wall per 0.05 s of sim: 50x
        clock.now = 100.0 + 0.001 * i
        pacer.record(0.05 * i)
    assert pacer.achieved_factor() == pytest.approx(50.0, rel=0.01)


def test_pacer_reanchors_instead_of_bursting_after_a_stall():
    clock = FakeClock()
    pacer = Pacer(1.0, clock=clock)
    pacer.wait_time(0.0)
    clock.now += 5.0  # the sim stalled for 5 s of wall time
    assert pacer.wait_time(0.01) == 0.0
    assert pacer.wait_time(0.5) == pytest.approx(0.49)


class CountingController:
    """Records the physics time of each control update."""

    def __init__(self) -> None:
        self.times: list[float] = []

    @property
    def active(self) -> bool:
        return True

    def reset(self, model, data) -> None:
        self.times.clear()

    def update(self, model, data, control_dt: float) -> None:
        self.times.append(float(data.time))


def test_controllers_run_on_the_control_grid_whatever_the_physics_chunks():
    from sim_bridge import Slot

    sim = Simulation(robot_models.load("panda"))
    counter = CountingController()
    sim.set_controller(Slot.ARM, counter)
    t0 = sim.time
    for chunk in (1, 3, 2, 5, 1, 4):  # 16 physics steps in uneven chunks
        sim.step_physics(chunk)
    assert sim.time == pytest.approx(t0 + 16 * sim.physics_timestep)
    expected = [t0 + k * sim.control_timestep for k in range(16 // sim.decimation)]
    np.testing.assert_allclose(counter.times, expected, atol=1e-9)


def test_batched_idle_stepping_keeps_the_control_grid_for_a_controller_that_starts_later():
    from sim_bridge import Slot

    sim = Simulation(robot_models.load("panda"))
    t0 = sim.time
    for chunk in (3, 2, 2):  # no controller active: each chunk is one batched mj_step call
        sim.step_physics(chunk)
    counter = CountingController()
    sim.set_controller(Slot.ARM, counter)
    sim.step_physics(6)
    dt, control_dt = sim.physics_timestep, sim.control_timestep
    first_boundary = t0 + math.ceil(7 / sim.decimation) * control_dt  # the first grid time at or after step 7
    expected = [first_boundary + k * control_dt for k in range(len(counter.times))]
    assert counter.times, "the controller ran"
    assert counter.times[0] >= t0 + 7 * dt - 1e-9
    np.testing.assert_allclose(counter.times, expected, atol=1e-9)


def test_a_push_acts_for_exactly_its_duration_and_imparts_its_impulse():
    sim = Simulation(robot_models.load("panda"))
    box = sim.robot.objects[0]
    body = sim.model.body(box)
    mass = float(body.mass[0])
    gravity = -float(sim.model.opt.gravity[2])
    force = 3.0 * mass * gravity  # lifts the box off the table: only gravity and the push act on it
    sim.step(10)
    start = sim.time
    end = sim.push(box, (0.0, 0.0, force), (0.0, 0.0, 0.0), 0.1)
    assert end == pytest.approx(start + 0.1)
    while sim.time < end - 1e-9:
        assert sim.pushing
        sim.step_physics(3)  # chunks that do not divide the push: it must still end on its step
    assert not sim.pushing and not np.any(sim.data.xfrc_applied)
    velocity = sim.data.qvel[sim.model.joint(box).dofadr[0] + 2]
    # Impulse balance at the push's end (the box flew from its first step): m v = (F - m g) T,
    # minus the fall during the steps stepped past the end.
    past = sim.time - end
    assert velocity == pytest.approx((force / mass - gravity) * 0.1 - gravity * past, rel=0.02)


def test_a_pushs_bound_follows_the_mass_it_moves():
    g1 = Simulation(robot_models.load("g1"))
    assert g1.push("pelvis", (0.0, 3000.0, 0.0), (0.0, 0.0, 0.0), 0.05) > 0  # 34.4 kg: a 3 kN shove is allowed
    with pytest.raises(ValueError, match=r"impulse .* up to 241 N s"):
        g1.push("pelvis", (0.0, 1000.0, 0.0), (0.0, 0.0, 0.0), 0.3)


def test_bad_pushes_are_refused_and_change_nothing(panda_sim):
    before = panda_sim.data.qpos.copy()
    with pytest.raises(UnknownNameError, match=r"bodies: .*panda_link0"):
        panda_sim.push("no_such_body", (1.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.1)
    for force, torque, duration, reason in [
        ((math.nan, 0.0, 0.0), (0.0, 0.0, 0.0), 0.1, "finite"),
        ((1e5, 0.0, 0.0), (0.0, 0.0, 0.0), 0.1, r"up to 4.9\d* N"),  # 10 g on the 50 g box
        ((0.0, 0.0, 0.0), (0.0, 0.0, 5e3), 0.1, r"up to 1.4\d* N m"),
        ((0.0, 0.0, 4.0), (0.0, 0.0, 0.0), 1.0, r"impulse 4 N s .* up to 0.35 N s"),  # it used to fly 87 km high
        ((1.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0, r"\(0, 10\]"),
    ]:
        with pytest.raises(ValueError, match=reason):
            panda_sim.push(panda_sim.robot.objects[0], force, torque, duration)
    assert not panda_sim.pushing and not np.any(panda_sim.data.xfrc_applied)
    np.testing.assert_array_equal(panda_sim.data.qpos, before)


def test_reset_ends_a_push(panda_sim):
    panda_sim.push(panda_sim.robot.objects[0], (0.0, 0.0, 0.8), (0.0, 0.0, 0.0), 0.2)
    panda_sim.step(1)
    panda_sim.reset()
    assert not panda_sim.pushing and not np.any(panda_sim.data.xfrc_applied)
