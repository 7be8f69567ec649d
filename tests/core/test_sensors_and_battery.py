"""Sensors, battery and reset_pose in the core, in-process: gravity on the IMU, weight on the feet, drain, reset pose."""

from __future__ import annotations

import numpy as np
import pytest

import robot_models
from sim_bridge import Simulation, Slot
from sim_bridge.battery import Battery, BatteryConfig, BatteryMeter, Metered
from sim_bridge.locomotion import WalkingController
from sim_bridge.sensors import ImuNoise, SensorSuite, WristNoise
from sim_bridge.skills import SkillHost, SkillRun, SkillStatus, WalkGoal, WalkSkill
from sim_bridge.skills.battery_guard import BatteryGuard
from sim_bridge.skills.reset_pose import ResetPoseGoal, ResetPoseSkill

G = 9.81


@pytest.fixture(scope="module")
def g1() -> robot_models.RobotSpec:
    return robot_models.load("g1")


@pytest.fixture
def legs(g1):
    sim = Simulation(g1)
    walker = WalkingController(sim.model, sim.robot.biped)
    host = SkillHost(walker)
    battery = Battery()
    sim.set_controller(Slot.LOCOMOTION, Metered(host, BatteryMeter(battery)))
    yield sim, walker, host, battery
    sim.reset()


def _run_until_ended(sim: Simulation, run: SkillRun, seconds: float) -> None:
    end = sim.time + seconds
    while run.status is SkillStatus.RUNNING:
        assert sim.time < end, f"still running after {seconds} s of sim time"
        sim.step(1)


def _walk(g1, walker, battery: Battery, distance: float) -> BatteryGuard:
    assert g1.walking is not None
    return BatteryGuard(WalkSkill(walker, g1.base_body, WalkGoal(distance, 0.3, 0.0, g1.walking), {}), battery)


def test_standing_the_imu_feels_gravity_and_the_feet_carry_the_weight(g1):
    sim = Simulation(g1)
    sensors = SensorSuite(sim.model, g1.sensors)
    sim.step(250)
    imu = sensors.imu(sim.data)
    assert imu.linear_acceleration[2] == pytest.approx(G, abs=0.05)
    assert np.linalg.norm(imu.angular_velocity) < 0.05
    weight = float(sim.model.body_subtreemass[sim.model.body(g1.base_body).id]) * G
    feet = [sensors.foot_wrench(sim.data, foot.name) for foot in g1.sensors.feet]
    assert sum(w.force[2] for w in feet) == pytest.approx(weight, rel=0.01)
    assert all(w.force[2] > 0.3 * weight for w in feet), "both feet carry part of it"


def test_imu_noise_is_seeded_and_wrist_bias_drifts_slowly(g1):
    readings = []
    for drift_rate in (0.6, 0.0):
        sim = Simulation(g1)
        sensors = SensorSuite(sim.model, g1.sensors)
        sensors.set_imu_noise(ImuNoise(gyro_noise=0.01, accel_noise=0.1, gyro_bias=0.01, accel_bias=0.1, seed=7))
        sensors.set_wrist_noise(WristNoise(force_bias=1.0, force_drift=drift_rate, seed=7))
        sim.step(2500)  # 10 s
        readings.append((sensors.imu(sim.data).linear_acceleration, sensors.wrist_wrench(sim.data, "left_wrist").force))
    assert np.allclose(readings[0][0], readings[1][0]), "same seed, same noise"
    drift = np.linalg.norm(readings[0][1] - readings[1][1])
    assert drift == pytest.approx(0.6 * 10.0 / 60.0, rel=1e-3), "0.6 N/min for 10 s of sim time"


def test_walking_drains_more_than_standing_and_a_low_battery_stops_the_walk(g1, legs):
    sim, walker, host, battery = legs
    sim.step(250)
    standing = battery.consumed_j
    assert standing == pytest.approx(BatteryConfig().idle_power_w * 1.0, rel=0.05), "idle draw (the stand costs ~0 work)"
    run = host.start(1, _walk(g1, walker, battery, 1.0), sim.model, sim.data)
    _run_until_ended(sim, run, 30.0)
    assert run.outcome is not None and run.outcome.code == "SUCCESS", run.outcome
    walking_power = battery.mechanical_j / (run.ended_at - run.started_at)
    assert 10.0 < walking_power < 500.0, f"mechanical power while walking: {walking_power:.0f} W"

    battery.set_level(battery.config.low_threshold_percent - 0.1)
    refused = host.start(2, _walk(g1, walker, battery, 1.0), sim.model, sim.data)
    sim.step(1)
    assert refused.outcome is not None and refused.outcome.code == "BATTERY_LOW" and "battery low" in refused.outcome.message

    battery.set_level(battery.config.low_threshold_percent + 0.01)
    run = host.start(3, _walk(g1, walker, battery, 3.0), sim.model, sim.data)
    _run_until_ended(sim, run, 30.0)
    assert run.outcome is not None and run.outcome.code == "BATTERY_LOW", run.outcome
    assert run.status is SkillStatus.ABORTED and walker.status().mode.name == "STANDING"
    assert 0.0 < float(run.final_result["final_distance"]) < 2.0


def test_reset_pose_after_a_walk_returns_to_the_default_posture(g1, legs):
    sim, walker, host, battery = legs
    run = host.start(1, _walk(g1, walker, battery, 0.6), sim.model, sim.data)
    _run_until_ended(sim, run, 30.0)
    reset = host.start(2, ResetPoseSkill(walker, g1, ResetPoseGoal()), sim.model, sim.data)
    _run_until_ended(sim, reset, 25.0)
    assert reset.outcome is not None and reset.outcome.code == "SUCCESS", reset.outcome
    assert float(reset.final_result["max_joint_error"]) <= 0.05


def test_reset_pose_leaves_the_head_camera_where_its_owner_pointed_it(g1, legs):
    sim, walker, host, _ = legs
    camera = next(c for c in g1.cameras if c.tilt_joint is not None)
    sim.set_camera_tilt(camera.name, 0.3)
    reset = host.start(3, ResetPoseSkill(walker, g1, ResetPoseGoal()), sim.model, sim.data)
    _run_until_ended(sim, reset, 25.0)
    assert reset.outcome is not None and reset.outcome.code == "SUCCESS", reset.outcome
    assert sim.camera_tilt(camera.name) == pytest.approx(0.3, abs=0.01)


def test_reset_pose_preempts_a_walk_and_refuses_a_fallen_robot(g1, legs):
    sim, walker, host, battery = legs
    walk = host.start(1, _walk(g1, walker, battery, 3.0), sim.model, sim.data)
    sim.step(300)
    reset = host.start(2, ResetPoseSkill(walker, g1, ResetPoseGoal()), sim.model, sim.data)
    assert walk.outcome is not None and walk.outcome.code == "PREEMPTED"
    _run_until_ended(sim, reset, 25.0)
    assert reset.outcome is not None and reset.outcome.code == "SUCCESS", reset.outcome

    sim.push(g1.base_body, (0.0, 400.0, 0.0), (0.0, 0.0, 0.0), 0.5)
    sim.step(750)
    assert walker.status().fallen
    refused = host.start(3, ResetPoseSkill(walker, g1, ResetPoseGoal()), sim.model, sim.data)
    sim.step(1)
    assert refused.outcome is not None and refused.outcome.code == "FALLEN"
    assert "fallen: reset the simulation" in refused.outcome.message


@pytest.mark.parametrize("name", robot_models.ROBOT_NAMES)
def test_the_sensor_layout_is_known_without_building_the_model(name):
    assert robot_models.sensors_of(name) == robot_models.load(name).sensors


def test_standing_the_meter_lets_the_physics_batch_and_counts_every_step_however_split(g1):
    consumed = []
    for split in (2, 5, 25):  # every control step; /sim's stops at 100 Hz; its longest stretch (50 ms)
        sim = Simulation(g1)
        battery = Battery()
        metered = Metered(SkillHost(WalkingController(sim.model, sim.robot.biped)), BatteryMeter(battery))
        sim.set_controller(Slot.LOCOMOTION, metered)
        assert not metered.active, "standing, the slot is idle: the physics runs in batched mj_step calls"
        for _ in range(999 // split):
            sim.step_physics(split)
        sim.step_physics(1000 - split * (999 // split))
        assert sim.time == pytest.approx(2.0)
        consumed.append(battery.consumed_j)
    # 2 s of idle draw and the settling after the keyframe (about 4 J since the arms carry the hands).
    idle = BatteryConfig().idle_power_w * 2.0
    assert idle < consumed[0] < idle * 1.05, "2 s of idle draw (and the settling)"
    # Standing, the power is held over a stretch: a longer stretch misses more of the settling after the keyframe
    # (the only work there is while standing).
    assert consumed[1] == pytest.approx(consumed[0], rel=1e-4) and consumed[2] == pytest.approx(consumed[0], rel=2e-3)
