"""The physics walking controller: standing, walking, turning, live changes, validation, falls."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np
import pytest

import robot_models
from robot_models import RobotModelError, g1_constants as names
from robot_models.g1_gait import BIPED as G1_BIPED
from sim_bridge import InvalidGoalError, Simulation, Slot
from sim_bridge.locomotion import PARAMETER_RANGES, GaitParameters, LocomotionMode, WalkingController, wbc
from sim_bridge.locomotion.geometry import Footstep, Side
from tests.core.locomotion_helpers import ZmpSegment, clip_to_polygon, convex_hull, dcm_reference

SWITCHES = {"timing_adaptation", "timing_crossover"}  # the gait's on/off switches (not in PARAMETER_RANGES)


@pytest.fixture(scope="module")
def g1_robot():
    return robot_models.load("g1")


@pytest.fixture(scope="module")
def panda_robot():
    return robot_models.load("panda")


@pytest.fixture
def walker(g1_robot):
    """A fresh G1 simulation with a walking controller installed."""
    sim = Simulation(g1_robot)
    controller = WalkingController(sim.model, G1_BIPED)
    sim.set_controller(Slot.LOCOMOTION, controller)
    yield sim, controller
    sim.reset()  # restores the servos' gains on the shared model


def _xy(sim: Simulation) -> np.ndarray:
    return sim.data.body(names.ROOT_BODY).xpos[:2].copy()


def _yaw(sim: Simulation) -> float:
    mat = sim.data.body(names.ROOT_BODY).xmat
    return math.atan2(mat[3], mat[0])


def _run(sim: Simulation, controller: WalkingController, seconds: float) -> None:
    """Step for ``seconds`` of sim time, failing as soon as the robot falls or more than its soles touch."""
    soles = {sim.model.geom(names.LEFT_SOLE_GEOM).id, sim.model.geom(names.RIGHT_SOLE_GEOM).id}
    floor = sim.model.geom(names.FLOOR_GEOM).id
    for _ in range(round(seconds / sim.control_timestep)):
        sim.step(1)
        assert not controller.status().fallen, f"fell at t={sim.time:.2f} s: {controller.status().message}"
        for contact in sim.data.contact[: sim.data.ncon]:
            other = {int(contact.geom1), int(contact.geom2)} - {floor}
            assert other <= soles, f"{sim.model.geom(other.pop()).name} touched the floor at t={sim.time:.2f} s"


def _run_until(sim: Simulation, controller: WalkingController, done: Callable[[], bool], deadline: float) -> None:
    """Step until ``done()`` holds, failing on a fall or when ``deadline`` seconds of sim time pass."""
    end = sim.time + deadline
    while not done():
        assert sim.time < end, f"condition not reached within {deadline} s of sim time"
        _run(sim, controller, sim.control_timestep)


def _stop_and_settle(sim: Simulation, controller: WalkingController, deadline: float = 4.0) -> None:
    controller.set_velocity_command(0.0, 0.0, 0.0)
    _run_until(sim, controller, lambda: not controller.active, deadline)
    assert controller.status().mode is LocomotionMode.STANDING


# ----- fast unit tests ---------------------------------------------------------------------
def test_parameter_ranges_cover_every_field_and_hold_the_defaults():
    defaults = GaitParameters()
    assert set(PARAMETER_RANGES) == set(vars(defaults)) - SWITCHES
    for name, (low, high, description) in PARAMETER_RANGES.items():
        assert low <= getattr(defaults, name) <= high
        assert description
    assert all(getattr(defaults, name) is True for name in SWITCHES)


@pytest.mark.parametrize(
    "field, value", [("step_duration", 0.1), ("double_support_duration", 1.0), ("max_forward_speed", float("nan")),
                     ("step_height", -0.01)]
)
def test_invalid_gait_parameters_are_refused_with_the_allowed_range(field, value):
    low, high, _ = PARAMETER_RANGES[field]
    with pytest.raises(InvalidGoalError, match=rf"{field}.*\[{low}, {high}\]"):
        GaitParameters(**{field: value})


def test_a_gait_switch_must_be_a_bool():
    with pytest.raises(InvalidGoalError, match="timing_adaptation"):
        GaitParameters(timing_adaptation=1)  # type: ignore[arg-type]
    assert not dataclasses.replace(GaitParameters(), timing_crossover=False).timing_crossover


def test_the_robot_s_spec_carries_its_biped_and_a_robot_without_one_cannot_walk(g1_robot, panda_robot):
    assert g1_robot.biped is G1_BIPED
    assert panda_robot.biped is None
    with pytest.raises(RobotModelError, match="no biped description"):
        WalkingController(panda_robot.model, panda_robot.biped)
    with pytest.raises(TypeError, match="BipedDescription"):
        WalkingController(g1_robot.model, GaitParameters())  # type: ignore[arg-type]


def test_set_gait_parameters_refuses_other_types_and_applies_new_limits(g1_robot):
    controller = WalkingController(g1_robot.model, G1_BIPED)
    with pytest.raises(InvalidGoalError, match="GaitParameters"):
        controller.set_gait_parameters({"step_duration": 0.4})  # type: ignore[arg-type]
    controller.set_velocity_command(0.5, 0.0, 0.0)
    controller.set_gait_parameters(GaitParameters(max_forward_speed=0.3))
    assert controller.status().commanded.vx == pytest.approx(0.3)


def test_velocity_command_is_clamped_and_non_finite_values_are_refused(g1_robot):
    params = GaitParameters()
    controller = WalkingController(g1_robot.model, G1_BIPED)
    controller.set_velocity_command(5.0, -5.0, 5.0)
    commanded = controller.status().commanded
    assert (commanded.vx, commanded.vy, commanded.wz) == pytest.approx(
        (params.max_forward_speed, -params.max_lateral_speed, params.max_yaw_rate)
    )
    controller.set_velocity_command(-5.0, 0.0, -5.0)
    assert controller.status().commanded.vx == pytest.approx(-params.max_backward_speed)
    with pytest.raises(InvalidGoalError):
        controller.set_velocity_command(float("inf"), 0.0, 0.0)


def test_cadence_follows_speed_above_0_6_m_s():
    params = GaitParameters()
    assert params.timing(0.5) == pytest.approx((0.35, 0.10))
    assert params.timing(-0.6) == pytest.approx((0.35, 0.10))
    assert params.timing(0.8) == pytest.approx((0.30, 0.08))
    assert params.timing(1.0) == pytest.approx((0.30, 0.08))
    swing, double = params.timing(0.7)
    assert 0.30 < swing < 0.35 and 0.08 < double < 0.10
    assert GaitParameters(step_duration=0.40).timing(0.8)[0] == pytest.approx(0.40 * 0.30 / 0.35)
    assert params.speed_limits(G1_BIPED.steps)[0] == pytest.approx(0.8)


def test_dcm_reference_is_the_zmp_when_it_stays_put_and_leads_a_moving_zmp():
    still = dcm_reference([ZmpSegment(1.0, np.array([0.1, 0.2]), np.array([0.1, 0.2]))], 0.3, 3.8)
    assert still.dcm == pytest.approx([0.1, 0.2])
    moving = dcm_reference(
        [ZmpSegment(0.5, np.zeros(2), np.array([0.1, 0.0])), ZmpSegment(2.0, np.array([0.1, 0.0]), np.array([0.1, 0.0]))],
        0.0, 3.8,
    )
    assert moving.zmp == pytest.approx([0.0, 0.0])
    assert 0.0 < moving.dcm[0] < 0.1 and moving.dcm[1] == pytest.approx(0.0)


def test_cop_clipping_keeps_inside_points_and_projects_outside_ones():
    hull = convex_hull(np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]], dtype=float))
    assert len(hull) == 4
    assert clip_to_polygon(np.array([0.3, 0.4]), hull) == pytest.approx([0.3, 0.4])
    assert clip_to_polygon(np.array([2.0, 0.5]), hull) == pytest.approx([1.0, 0.5])
    assert Footstep(Side.LEFT, 0.0, 0.0, 0.0).side.other is Side.RIGHT


# ----- closed-loop tests ----------------------------------------------------------------------
def test_stands_still_with_a_zero_command(walker):
    sim, controller = walker
    start = _xy(sim)
    controller.set_velocity_command(0.0, 0.0, 0.0)
    _run(sim, controller, 5.0)
    assert np.linalg.norm(_xy(sim) - start) < 0.02
    assert controller.status().mode is LocomotionMode.STANDING
    assert not controller.active


@pytest.mark.slow
def test_walks_forward_two_metres_at_the_commanded_pace(walker):
    sim, controller = walker
    start = _xy(sim)
    controller.set_velocity_command(0.3, 0.0, 0.0)
    _run(sim, controller, 3.0)
    assert controller.status().mode is LocomotionMode.WALKING
    window_start, t0 = _xy(sim), sim.time
    _run_until(sim, controller, lambda: _xy(sim)[0] - start[0] >= 2.0, deadline=10.0)
    pace = (_xy(sim)[0] - window_start[0]) / (sim.time - t0)
    assert pace == pytest.approx(0.3, abs=0.04)
    _stop_and_settle(sim, controller)
    travelled = _xy(sim) - start
    assert 2.0 <= travelled[0] < 2.4
    assert abs(travelled[1]) < 0.10
    assert abs(math.degrees(_yaw(sim))) < 5.0
    assert controller.status().steps_taken >= 10


@pytest.mark.slow
def test_walks_at_0_8_m_s_on_its_line(walker):
    sim, controller = walker
    start = _xy(sim)
    controller.set_velocity_command(0.8, 0.0, 0.0)
    _run_until(sim, controller, lambda: _xy(sim)[0] - start[0] >= 3.0, deadline=8.0)
    window_start, t0 = _xy(sim), sim.time
    _run_until(sim, controller, lambda: _xy(sim)[0] - start[0] >= 12.0, deadline=15.0)
    pace = (_xy(sim)[0] - window_start[0]) / (sim.time - t0)
    assert pace == pytest.approx(0.8, rel=0.03)
    travelled = _xy(sim) - start
    assert abs(travelled[1]) / travelled[0] < 0.02  # lateral drift per metre
    _stop_and_settle(sim, controller)


@pytest.mark.slow
def test_a_live_change_from_0_5_to_0_8_m_s_reaches_the_new_pace_within_2_s(walker):
    sim, controller = walker
    controller.set_velocity_command(0.5, 0.0, 0.0)
    _run(sim, controller, 5.0)
    controller.set_velocity_command(0.8, 0.0, 0.0)
    _run(sim, controller, 2.0)
    x0, t0 = _xy(sim)[0], sim.time
    _run(sim, controller, 3.04)  # eight 0.38 s steps
    assert (_xy(sim)[0] - x0) / (sim.time - t0) == pytest.approx(0.8, abs=0.03)


@pytest.mark.slow
@pytest.mark.parametrize("direction_deg", [90.0, 270.0])
def test_absorbs_a_10_n_s_sideways_push_in_mid_swing_and_walks_on(walker, direction_deg):
    sim, controller = walker
    controller.set_velocity_command(0.5, 0.0, 0.0)
    _run(sim, controller, 4.0)
    _run_until(sim, controller, lambda: controller.gait_phase().kind == "double", deadline=1.0)
    _run_until(sim, controller, lambda: controller.gait_phase().kind == "single"
               and controller.gait_phase().elapsed >= 0.12, deadline=1.0)
    angle = _yaw(sim) + math.radians(direction_deg)
    sim.push(names.ROOT_BODY, [100.0 * math.cos(angle), 100.0 * math.sin(angle), 0.0], [0.0, 0.0, 0.0], 0.1)
    _run(sim, controller, 4.0)
    x0, t0 = _xy(sim)[0], sim.time
    _run(sim, controller, 2.0)
    assert (_xy(sim)[0] - x0) / (sim.time - t0) == pytest.approx(0.5, abs=0.1)
    _stop_and_settle(sim, controller, deadline=6.0)


@pytest.mark.slow
def test_walks_backward_half_a_metre_and_stops(walker):
    sim, controller = walker
    start = _xy(sim)
    controller.set_velocity_command(-0.3, 0.0, 0.0)
    _run_until(sim, controller, lambda: _xy(sim)[0] - start[0] <= -0.5, deadline=5.0)
    _stop_and_settle(sim, controller)
    travelled = _xy(sim) - start
    assert -0.8 < travelled[0] <= -0.5
    assert abs(travelled[1]) < 0.08


@pytest.mark.slow
def test_walks_sideways(walker):
    sim, controller = walker
    start = _xy(sim)
    controller.set_velocity_command(0.0, 0.15, 0.0)
    _run(sim, controller, 4.0)
    _stop_and_settle(sim, controller)
    travelled = _xy(sim) - start
    assert 0.35 < travelled[1] < 0.7
    assert abs(travelled[0]) < 0.08
    assert abs(math.degrees(_yaw(sim))) < 5.0


@pytest.mark.slow
def test_turns_in_place_by_ninety_degrees(walker):
    sim, controller = walker
    start = _xy(sim)
    controller.set_velocity_command(0.0, 0.0, 0.5)
    _run_until(sim, controller, lambda: _yaw(sim) >= math.radians(85.0), deadline=8.0)
    _stop_and_settle(sim, controller)
    assert 85.0 <= math.degrees(_yaw(sim)) <= 105.0
    assert np.linalg.norm(_xy(sim) - start) < 0.15


@pytest.mark.slow
def test_live_speed_change_changes_the_measured_pace(walker):
    sim, controller = walker

    def pace(seconds: float) -> float:
        x0, t0 = _xy(sim)[0], sim.time
        _run(sim, controller, seconds)
        return (_xy(sim)[0] - x0) / (sim.time - t0)

    controller.set_velocity_command(0.2, 0.0, 0.0)
    _run(sim, controller, 3.0)
    slow = pace(2.7)
    controller.set_velocity_command(0.4, 0.0, 0.0)
    _run(sim, controller, 2.0)
    fast = pace(2.7)
    assert slow == pytest.approx(0.2, abs=0.04)
    assert fast == pytest.approx(0.4, abs=0.05)
    assert controller.status().measured.vx == pytest.approx(0.4, abs=0.1)


@pytest.mark.slow
def test_a_fall_is_detected_and_a_reset_lets_it_stand_and_walk_again(walker):
    sim, controller = walker
    controller.set_velocity_command(0.3, 0.0, 0.0)
    _run(sim, controller, 2.0)
    pelvis = sim.model.body(names.ROOT_BODY).id
    sim.data.xfrc_applied[pelvis, 1] = 400.0  # a shove no controller can absorb
    end = sim.time + 3.0
    while not controller.status().fallen and sim.time < end:
        sim.step(1)
    status = controller.status()
    assert status.fallen and status.mode is LocomotionMode.FALLEN and "reset" in status.message
    assert not controller.active
    sim.data.xfrc_applied[pelvis] = 0.0

    sim.reset()
    assert controller.status().mode is LocomotionMode.STANDING
    start = _xy(sim)
    _run(sim, controller, 3.0)
    assert np.linalg.norm(_xy(sim) - start) < 0.02
    controller.set_velocity_command(0.3, 0.0, 0.0)
    _run(sim, controller, 3.0)
    assert _xy(sim)[0] - start[0] > 0.3


@pytest.mark.slow
def test_release_gives_the_legs_back_to_the_position_servos(walker):
    sim, controller = walker
    knee = sim.model.actuator(names.LEFT_LEG_JOINTS[3]).id
    servo_gain = float(sim.model.actuator_gainprm[knee, 0])
    controller.set_velocity_command(0.2, 0.0, 0.0)
    _run(sim, controller, 1.0)
    assert controller.active and sim.model.actuator_gainprm[knee, 0] == 1.0  # torque mode while walking
    controller.release(sim.model, sim.data)
    assert not controller.active
    assert sim.model.actuator_gainprm[knee, 0] == servo_gain
    assert controller.status().mode is LocomotionMode.STANDING


def test_a_failed_torque_qp_is_counted_logged_and_holds_the_previous_contact_forces(walker, monkeypatch, caplog):
    sim, controller = walker
    controller.set_velocity_command(0.2, 0.0, 0.0)
    _run(sim, controller, 0.2)  # balancing under the QP, in torque mode
    qp = controller._wbc
    forces = qp.last_force.copy()
    assert np.any(forces != 0.0)

    def fail(*args, **kwargs):
        return np.zeros(qp.nz), 0.0, -1, {}

    monkeypatch.setattr(qp, "_solve_qp", lambda hessian, gradient, support: (np.zeros(qp.nz), -1))
    monkeypatch.setattr(wbc.daqp, "solve", fail)
    with caplog.at_level("WARNING", logger=wbc.__name__):
        sim.step(1)
    assert (qp.relaxed_count, qp.fallback_count, controller.qp_fallback_count) == (1, 1, 1)
    assert "torque QP failed" in caplog.text
    np.testing.assert_array_equal(qp.last_force, forces)  # held, not replaced
    motors = [sim.model.actuator(j).id for j in G1_BIPED.motor_joints]
    torques = sim.data.ctrl[motors]
    assert np.all(np.isfinite(torques))
    assert np.all((qp.torque_limit[:, 0] <= torques) & (torques <= qp.torque_limit[:, 1]))
