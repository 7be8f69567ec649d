"""Arm controller, IK query and pick-and-place in the simulation core (headless, deterministic)."""

from __future__ import annotations

import math

import mink
import mujoco
import numpy as np
import pytest

import robot_models
from robot_models import g1_constants, panda_constants
from sim_bridge import Pose, Simulation, Slot, UnknownNameError
from sim_bridge.arm import ArmController, ArmMode, PickPlace, PickPlaceFailure, PickPlaceGoal, PickPlaceStage, solve_ik
from sim_bridge.arm.ik_problem import OFFLINE_DT
from sim_bridge.arm.kinematics import ArmKinematics
from sim_bridge.arm.poses import quat_to_mat
from sim_bridge.errors import InvalidGoalError

TOOL_DOWN = np.array([0.0, 1.0, 0.0, 0.0])  # tool z axis pointing at the table


def _tool_down(yaw: float) -> np.ndarray:
    return np.array([0.0, math.cos(0.5 * yaw), math.sin(0.5 * yaw), 0.0])


def _run_until(sim: Simulation, condition, timeout_s: float) -> bool:
    """Step control periods until ``condition()`` holds or the sim-time deadline passes."""
    deadline = sim.time + timeout_s
    while sim.time < deadline:
        sim.step(1)
        if condition():
            return True
    return False


@pytest.fixture(scope="module")
def panda() -> robot_models.RobotSpec:
    return robot_models.load("panda")


@pytest.fixture(scope="module")
def g1() -> robot_models.RobotSpec:
    return robot_models.load("g1")


@pytest.fixture
def panda_sim(panda):
    sim = Simulation(panda)
    arm = ArmController(panda)
    sim.set_controller(Slot.ARM, arm)
    return sim, arm


@pytest.mark.parametrize("arms", [("panda", ("arm",)), ("g1", ("left_arm", "right_arm"))])
def test_controller_knows_every_arm(arms, panda, g1):
    robot = panda if arms[0] == "panda" else g1
    assert tuple(ArmController(robot).arms) == arms[1]


def test_the_ik_model_is_built_at_the_first_arm_goal_not_with_the_controller(panda_sim):
    """A robot that never moves an arm never pays for its IK model (~0.3 CPU-s for the G1's at every /sim start)."""
    sim, arm = panda_sim
    sim.step(50)
    assert arm.status("arm").mode is ArmMode.IDLE
    with pytest.raises(UnknownNameError, match="arm"):  # names are checked without it
        arm.set_target("leg", Pose(np.array([0.5, 0.2, 0.3]), TOOL_DOWN))
    assert arm._kinematics is None
    arm.set_target("arm", Pose(np.array([0.5, 0.2, 0.3]), TOOL_DOWN))
    assert arm._kinematics is not None


def test_panda_reaches_five_poses(panda_sim):
    sim, arm = panda_sim
    targets = [
        Pose(np.array([0.5, 0.2, 0.3]), _tool_down(0.3)),
        Pose(np.array([0.4, -0.3, 0.15]), _tool_down(-0.5)),
        Pose(np.array([0.6, 0.0, 0.45]), TOOL_DOWN),
        Pose(np.array([0.3, 0.3, 0.25]), _tool_down(0.8)),
        Pose(np.array([0.55, -0.1, 0.1]), _tool_down(0.0)),
    ]
    for target in targets:
        arm.set_target("arm", target, False, 0.5, 1.5)
        assert _run_until(sim, lambda: arm.status("arm").settled, 6.0), arm.status("arm")
        status = arm.status("arm")
        assert status.position_error <= 1e-3
        assert status.orientation_error <= 0.01
        assert not status.unreachable
        # The status reports the measured tool pose, not the command.
        tcp = sim.data.site(panda_constants.TCP_SITE).xpos
        assert np.linalg.norm(tcp - target.position) <= 1e-3


def test_position_only_goal_ignores_orientation(panda_sim):
    sim, arm = panda_sim
    target = Pose(np.array([0.45, 0.1, 0.35]), np.array([1.0, 0.0, 0.0, 0.0]))  # tool up: not reachable as a pose
    arm.set_target("arm", target, True, 0.5, 1.5)
    assert _run_until(sim, lambda: arm.status("arm").settled, 6.0)
    assert arm.status("arm").position_error <= 1e-3


def test_hold_mid_move_stops_the_arm(panda_sim):
    sim, arm = panda_sim
    target = Pose(np.array([0.3, 0.4, 0.15]), TOOL_DOWN)
    start = arm.status("arm").tool_pose.position.copy()
    arm.set_target("arm", target, False, 0.3, 1.0)
    sim.step(int(1.2 / sim.control_timestep))
    moving_from = arm.status("arm").tool_pose.position.copy()
    assert np.linalg.norm(moving_from - start) > 0.1  # it was moving
    arm.hold("arm")
    sim.step(1)
    ctrl_after_one_period = sim.data.ctrl[:7].copy()
    reference = arm.status("arm").reference_pose.position.copy()
    sim.step(int(0.5 / sim.control_timestep))
    status = arm.status("arm")
    assert status.mode == ArmMode.HOLDING
    # The joint targets froze (bias feed-forward aside).
    np.testing.assert_allclose(sim.data.ctrl[:7], ctrl_after_one_period, atol=1e-3)
    np.testing.assert_allclose(status.reference_pose.position, reference)
    assert np.linalg.norm(status.tool_pose.position - moving_from) < 0.01  # stopped within about one period of motion
    assert np.linalg.norm(status.tool_pose.position - target.position) > 0.1
    assert np.max(np.abs(sim.data.qvel[:7])) < 0.01


@pytest.mark.parametrize(
    ("position", "words"),
    [((1.5, 0.0, 0.3), "workspace"), ((0.5, 0.0, -0.05), "below the table"), ((0.5, 0.0, 0.004), "IK converged")],
)
def test_unreachable_pose_is_reported_with_reason(panda_sim, position, words):
    sim, arm = panda_sim
    before = sim.data.qpos[:7].copy()
    arm.set_target("arm", Pose(np.array(position), TOOL_DOWN), False, 0.5, 1.5)
    sim.step(50)
    status = arm.status("arm")
    assert status.unreachable
    assert not status.settled
    assert words in status.reason
    assert np.max(np.abs(sim.data.qpos[:7] - before)) < 1e-3  # the arm did not go anywhere


def test_solve_ik_is_pure_and_reports_errors(panda):
    data = mujoco.MjData(panda.model)
    mujoco.mj_resetDataKeyframe(panda.model, data, panda.model.key(panda.default_keyframe).id)
    qpos = data.qpos.copy()
    result = solve_ik(panda, data, "arm", Pose(np.array([0.45, -0.2, 0.25]), _tool_down(0.4)), False)
    assert result.success and result.reason == ""
    assert result.joint_names == panda_constants.ARM_JOINTS
    assert result.position_error < 1e-4 and result.orientation_error < 1e-3
    np.testing.assert_array_equal(data.qpos, qpos)
    far = solve_ik(panda, qpos, "arm", Pose(np.array([2.0, 0.0, 0.3]), TOOL_DOWN), False)
    assert not far.success and "workspace" in far.reason


def test_unknown_names_raise_with_the_valid_names(panda_sim, panda):
    sim, arm = panda_sim
    with pytest.raises(UnknownNameError, match="arms: arm"):
        arm.set_target("left_arm", Pose(np.array([0.5, 0.0, 0.3]), TOOL_DOWN), False, 0.5, 1.0)
    with pytest.raises(UnknownNameError, match="arms: arm"):
        arm.status("gripper")
    with pytest.raises(UnknownNameError, match="arms: arm"):
        solve_ik(panda, sim.data, "right_arm", Pose(np.array([0.5, 0.0, 0.3]), TOOL_DOWN), False)
    skill = PickPlace(arm)
    sim.set_controller(Slot.ARM, skill)
    with pytest.raises(UnknownNameError, match="box_0, box_1, box_2"):
        skill.start(PickPlaceGoal("box_9", (0.4, 0.3, 0.0)))
    with pytest.raises(InvalidGoalError, match="off the table"):
        skill.start(PickPlaceGoal("box_1", (1.5, 0.0, 0.0)))
    with pytest.raises(InvalidGoalError, match=r"\(0, 2"):
        arm.set_target("arm", Pose(np.array([0.5, 0.0, 0.3]), TOOL_DOWN), False, 5.0, 1.0)
    with pytest.raises(InvalidGoalError, match="width"):
        arm.set_gripper("arm", 0.2, 20.0)


def test_g1_arm_has_no_gripper(g1):
    sim = Simulation(g1)
    arm = ArmController(g1)
    sim.set_controller(Slot.ARM, arm)
    with pytest.raises(InvalidGoalError, match="no gripper"):
        arm.set_gripper("right_arm", 0.02, 10.0)
    with pytest.raises(UnknownNameError, match="left_arm, right_arm"):
        arm.hold("arm")


def _pick_place(sim: Simulation, skill: PickPlace, goal: PickPlaceGoal, during=None):
    skill.start(goal)
    max_height = 0.0
    box = sim.model.body(goal.object_name).id
    stages = []
    while sim.time < 40.0:
        sim.step(1)
        progress = skill.progress()
        if not stages or stages[-1] != progress.stage:
            stages.append(progress.stage)
        if progress.stage == PickPlaceStage.TRANSPORT:
            max_height = max(max_height, float(sim.data.xpos[box][2]))
        if during is not None:
            during(progress)
        if progress.done:
            return progress, max_height, stages
    raise AssertionError("pick-and-place did not end")


def test_pick_and_place_box_by_friction(panda_sim):
    sim, arm = panda_sim
    skill = PickPlace(arm)
    sim.set_controller(Slot.ARM, skill)
    assert sim.model.neq == 0  # no weld or other equality can hold the box
    place = (0.4, 0.3, 0.0)
    progress, max_height, stages = _pick_place(sim, skill, PickPlaceGoal("box_1", place))
    assert progress.success, progress.reason
    assert stages == list(PickPlaceStage)
    assert progress.failure == PickPlaceFailure.NONE and progress.percent == pytest.approx(100.0)
    assert max_height > panda_constants.BOX_HALF_SIZE + 0.1  # it rose off the table while carried
    expected = np.array([place[0], place[1], panda_constants.TABLE_TOP_Z + panda_constants.BOX_HALF_SIZE])
    error = np.linalg.norm(sim.data.body("box_1").xpos - expected)
    assert error < 0.005 and progress.placement_error == pytest.approx(error, abs=1e-4)
    assert arm.status("arm").gripper.contact_bodies == ()  # released


def test_pick_place_detects_a_dropped_object(panda_sim):
    sim, arm = panda_sim
    skill = PickPlace(arm)
    sim.set_controller(Slot.ARM, skill)

    def open_fingers_in_transport(progress):
        if progress.stage == PickPlaceStage.TRANSPORT and not progress.done:
            arm.set_gripper("arm", 0.08, 20.0)  # a fault opens the hand mid-air

    progress, _, _ = _pick_place(sim, skill, PickPlaceGoal("box_1", (0.4, 0.3, 0.0)), open_fingers_in_transport)
    assert not progress.success
    assert progress.failure in (PickPlaceFailure.OBJECT_DROPPED, PickPlaceFailure.OBJECT_SLIPPED)
    assert progress.stage == PickPlaceStage.TRANSPORT and "box_1" in progress.reason


def test_pick_place_detects_a_missed_grasp(panda_sim):
    sim, arm = panda_sim
    skill = PickPlace(arm)
    sim.set_controller(Slot.ARM, skill)
    adr = int(sim.model.joint("box_1").qposadr[0])

    def take_the_box_away(progress):
        if progress.stage == PickPlaceStage.DESCEND and progress.stage_progress > 0.5 and sim.data.qpos[adr] < 0.7:
            sim.data.qpos[adr : adr + 3] = [0.8, 0.4, 0.02]  # someone removes the box

    progress, _, _ = _pick_place(sim, skill, PickPlaceGoal("box_1", (0.4, 0.3, 0.0)), take_the_box_away)
    assert not progress.success
    assert progress.failure == PickPlaceFailure.GRASP_MISSED and "without holding" in progress.reason


def _tilt_deg(pose: Pose) -> float:
    return math.degrees(math.acos(min(1.0, quat_to_mat(pose.orientation_wxyz)[2, 2])))


def test_g1_right_arm_reaches_while_standing(g1):
    sim = Simulation(g1)
    arm = ArmController(g1)
    sim.set_controller(Slot.ARM, arm)
    sim.step(125)
    pelvis = sim.base_state().pose
    legs = [sim.model.actuator(j).id for j in g1_constants.LEFT_LEG_JOINTS + g1_constants.RIGHT_LEG_JOINTS]
    left_arm = [sim.model.actuator(j).id for j in g1_constants.LEFT_ARM_JOINTS]
    ctrl_before = sim.data.ctrl.copy()
    start = arm.status("right_arm").tool_pose
    target = Pose(start.position + np.array([0.15, 0.05, 0.15]), start.orientation_wxyz)
    arm.set_target("right_arm", target, False, 0.15, 0.5)
    assert _run_until(sim, lambda: arm.status("right_arm").settled, 6.0), arm.status("right_arm")
    status = arm.status("right_arm")
    assert status.position_error <= 1e-3 and status.orientation_error <= 0.01
    np.testing.assert_array_equal(sim.data.ctrl[legs], ctrl_before[legs])  # legs and other arm untouched
    np.testing.assert_array_equal(sim.data.ctrl[left_arm], ctrl_before[left_arm])
    after = sim.base_state().pose
    assert abs(after.position[2] - pelvis.position[2]) < 0.01
    # The legs are plain PD servos (no balance loop): the arm motion makes the body sway by about a degree.
    assert abs(_tilt_deg(after) - _tilt_deg(pelvis)) < 2.0, _tilt_deg(after)


# ----- pinned behaviour of the IK tick -------------------------------------------------------------
# Recorded with the mink.solve_ik implementation of the tracking loop (before the arm-only QP):
# measured arm joint positions [rad] mid-motion and after arrival of three Panda moves (the last one
# 3 cm above the table, where the collision limit is active), and of one G1 right-arm reach.
PANDA_MOVES = [((0.5, 0.2, 0.3), 0.3), ((0.4, -0.3, 0.15), -0.5), ((0.55, -0.1, 0.03), 0.0)]
PANDA_REFERENCE_Q = [
    [0.0363043114890333, -0.6977854932293404, 0.04898161807227216, -2.3797113840238167,
     0.030918013789797076, 1.6908389943724205, 0.8021804015138048],
    [0.1904819445283996, 0.001512786296130546, 0.19008587384890022, -2.141246243162898,
     -0.0003397736528366497, 2.142731588756163, 0.8661522241596948],
    [0.16429292473965718, -0.028618845208922793, 0.1713288911474294, -2.2018594136815954,
     0.006467112945510656, 2.171325529726756, 0.8602636884303086],
    [-0.36264760712283894, 0.15743196963916878, -0.27536635075303917, -2.397515883496651,
     0.07626815875094234, 2.547761652835699, 0.5874391168353043],
    [-0.3121673302295488, 0.23494448749283808, -0.1867984334925798, -2.3847379739108137,
     0.09026836995423075, 2.6206048681763905, 0.5768141934205768],
    [-0.17093061699086784, 0.5612908646274087, -0.0079626968851923, -2.156938149702933,
     0.010314783328112365, 2.7181933897345996, 0.5983249588200644],
]
PANDA_REFERENCE_TOOL = [0.5499984167300606, -0.10000009722286976, 0.030006033406905247]
# The G1 reach was re-recorded (same code) when the G1 got its Dex3-1 hands: heavier hands, the hand site at the palm.
G1_REFERENCE_Q = [
    [0.0591352706456177, -0.23796667974633529, 0.01195477564545524, 0.7128572610031049,
     0.008224951512672473, 0.14111335892491664, -0.005326597980396338],
    [-0.21670148452193963, -0.22548522857256909, 0.008148578158841112, -0.051844819855968186,
     0.04930245719681658, 1.1388989306751502, -0.0630909373723532],
]
PICK_REFERENCE_END_TIME = 9.292  # [s]
PICK_REFERENCE_BOX = [0.40018514739274097, 0.2999597538815929, 0.01996072516015629]
PINNED_Q_TOLERANCE = 1e-6  # [rad]


def test_panda_tracking_matches_the_recorded_reference(panda_sim):
    sim, arm = panda_sim
    adr = arm.arms["arm"].qpos_adr
    measured = []
    for position, yaw in PANDA_MOVES:
        arm.set_target("arm", Pose(np.array(position), _tool_down(yaw)), False, 0.5, 1.5)
        sim.step(100)  # mid-motion
        measured.append(sim.data.qpos[adr].copy())
        sim.step(400)  # arrived
        measured.append(sim.data.qpos[adr].copy())
    np.testing.assert_allclose(measured, PANDA_REFERENCE_Q, rtol=0.0, atol=PINNED_Q_TOLERANCE)
    np.testing.assert_allclose(sim.data.site(panda_constants.TCP_SITE).xpos, PANDA_REFERENCE_TOOL, rtol=0.0, atol=1e-6)


def test_g1_tracking_matches_the_recorded_reference(g1):
    sim = Simulation(g1)
    arm = ArmController(g1)
    sim.set_controller(Slot.ARM, arm)
    sim.step(125)
    adr = arm.arms["right_arm"].qpos_adr
    start = arm.status("right_arm").tool_pose
    arm.set_target("right_arm", Pose(start.position + np.array([0.15, 0.05, 0.15]), start.orientation_wxyz), False, 0.15, 0.5)
    sim.step(150)
    measured = [sim.data.qpos[adr].copy()]
    sim.step(350)
    measured.append(sim.data.qpos[adr].copy())
    np.testing.assert_allclose(measured, G1_REFERENCE_Q, rtol=0.0, atol=PINNED_Q_TOLERANCE)


def test_pick_and_place_matches_the_recorded_reference(panda_sim):
    sim, arm = panda_sim
    skill = PickPlace(arm)
    sim.set_controller(Slot.ARM, skill)
    progress, _, _ = _pick_place(sim, skill, PickPlaceGoal("box_1", (0.4, 0.3, 0.0)))
    assert progress.success, progress.reason
    assert sim.time == pytest.approx(PICK_REFERENCE_END_TIME, abs=1e-9)  # the same control step ends it
    np.testing.assert_allclose(sim.data.body("box_1").xpos, PICK_REFERENCE_BOX, rtol=0.0, atol=1e-5)


@pytest.mark.parametrize(("robot_name", "arm_name"), [("panda", "arm"), ("g1", "right_arm")])
@pytest.mark.parametrize("kind", ["tracking", "offline"])
def test_arm_only_ik_step_equals_mink_solve_ik(robot_name, arm_name, kind, panda, g1):
    """The arm-only QP gives the displacement of mink.solve_ik on the full problem (frozen DoFs by equality)."""
    robot = panda if robot_name == "panda" else g1
    kinematics = ArmKinematics(robot)
    problem = (kinematics.tracking if kind == "tracking" else kinematics.offline)[arm_name]
    info = problem.info
    dt = robot.control_timestep / kinematics.config.max_ik_iterations_per_tick if kind == "tracking" else OFFLINE_DT
    frozen = np.setdiff1d(np.arange(problem.model.nv), info.dof_adr)
    lower, upper = problem.model.jnt_range[[problem.model.joint(j).id for j in info.joints]].T
    rng = np.random.default_rng(7)
    with_collision_rows = 0
    for trial in range(60):
        qpos = kinematics.posture_qpos.copy()
        qpos[info.qpos_adr] = lower + (upper - lower) * rng.uniform(0.05, 0.95, size=len(info.joints))
        if robot_name == "panda" and trial % 2:  # the hand a few cm above the table: collision rows
            low = Pose(np.array([rng.uniform(0.35, 0.6), rng.uniform(-0.3, 0.3), rng.uniform(0.01, 0.05)]), TOOL_DOWN)
            qpos[info.qpos_adr] = kinematics.solve(arm_name, kinematics.posture_qpos, low, False).positions
        problem.set_configuration(qpos)
        tool = problem.tool_pose()
        if robot_name == "panda":  # low targets bring the hand near the table
            position = np.array([rng.uniform(0.3, 0.65), rng.uniform(-0.35, 0.35), rng.uniform(0.0, 0.3)])
        else:
            position = tool.position + rng.uniform(-0.2, 0.2, size=3)
        problem.set_target(Pose(position, TOOL_DOWN if robot_name == "panda" else tool.orientation_wxyz), trial % 3 == 0)
        velocity = problem.velocity(dt)
        assert velocity is not None
        expected = mink.solve_ik(problem.configuration, [problem.frame_task, problem.posture_task], dt, "daqp",
                                 damping=1e-9, limits=problem.limits, constraints=problem.constraints)
        np.testing.assert_allclose(expected[frozen], 0.0, atol=1e-12)
        np.testing.assert_allclose(velocity * dt, expected[info.dof_adr] * dt, rtol=0.0, atol=1e-9)
        constraint = problem.collision_limit.compute_qp_inequalities(problem.configuration, dt)
        with_collision_rows += int(np.isfinite(constraint.h).any())
    assert with_collision_rows >= 5  # the collision rows were exercised


def test_g1_collision_model_has_the_robot_kinematics_and_mesh_hulls(g1):
    """The IK model is recompiled so the visual meshes the arm avoids get convex hulls; nothing else changes."""
    kinematics = ArmKinematics(g1)
    problem = kinematics.tracking["right_arm"]
    model = problem.model
    for name in ("body_pos", "body_quat", "jnt_pos", "jnt_axis", "site_pos", "geom_pos", "geom_size", "geom_rbound"):
        np.testing.assert_array_equal(getattr(model, name), getattr(g1.model, name), err_msg=name)
    data, reference = mujoco.MjData(model), mujoco.MjData(g1.model)
    data.qpos[:] = reference.qpos[:] = kinematics.posture_qpos
    mujoco.mj_kinematics(model, data)
    mujoco.mj_kinematics(g1.model, reference)
    np.testing.assert_array_equal(data.site_xpos, reference.site_xpos)
    meshes = {int(model.geom_dataid[g]) for pair in problem.collision_limit.geom_id_pairs for g in pair
              if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH}
    assert meshes and all(model.mesh_graphadr[m] >= 0 for m in meshes)
