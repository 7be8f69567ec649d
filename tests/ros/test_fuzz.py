"""Fuzzing goals and parameters (hypothesis): every bad input is refused or ended with a code and a reason.

- In-process, hundreds of goals per action through the validation the servers run at the goal
  callback (``nodes.servers.protocol``): a goal passes or is refused with :class:`InvalidGoalError` and a
  message, never another exception.
- Through ROS, against real servers: random goals (malformed and finite-but-wrong ones: off the table,
  unreachable, inside obstacles, absurd timeouts) are each rejected, or accepted and ended with a
  result code and a reason; the server keeps serving and the next valid goal succeeds. Random
  parameter messages are answered per parameter, refused ones with a reason, and leave every
  parameter in its range.

``make test`` runs a few hundred examples; ``FUZZ_EXAMPLES=2000 pytest tests/ros/test_fuzz.py``
runs more.
"""

from __future__ import annotations

import math
import os

import pytest
from action_msgs.msg import GoalStatus
from hypothesis import HealthCheck, given, settings, strategies as st
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import DescribeParameters, GetParameters, ListParameters, SetParameters

import robot_models
from nodes.servers.protocol import BINDINGS
from sim_bridge.errors import InvalidGoalError
from sim_interfaces.action import MoveArm, NavigateToPose, PickPlace, ResetPose, Walk
from tests.ros.actions import ready_client, result, send
from tests.ros.processes import running

pytestmark = pytest.mark.slow

SCALE = max(1, int(os.environ.get("FUZZ_EXAMPLES", "0")) // 100)
READY_S = 90.0
NUMBERS = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=64),
                    st.sampled_from([0.0, -1.0, 1.0, 1e-9, 1e9, -1e9, 0.5, 2.0, 100.0]))
NAMES = st.one_of(st.sampled_from(["", "world", "odom", "map", "panda_link0", "panda_hand", "pelvis", "box_0", "box_1",
                                   "arm", "left_arm", "right_arm", "moon", "x" * 10_000]),
                  st.text(max_size=40))


def pose_fields(draw: st.DrawFn, pose: object) -> None:
    position, orientation = pose.position, pose.orientation  # type: ignore[attr-defined]
    position.x, position.y, position.z = draw(NUMBERS), draw(NUMBERS), draw(NUMBERS)
    orientation.x, orientation.y, orientation.z, orientation.w = (draw(NUMBERS), draw(NUMBERS), draw(NUMBERS),
                                                                  draw(NUMBERS))


@st.composite
def walk_goals(draw: st.DrawFn) -> Walk.Goal:
    return Walk.Goal(distance=draw(NUMBERS), speed=draw(NUMBERS), timeout=draw(NUMBERS))


@st.composite
def navigate_goals(draw: st.DrawFn) -> NavigateToPose.Goal:
    goal = NavigateToPose.Goal()
    goal.pose.header.frame_id = draw(NAMES)
    pose_fields(draw, goal.pose.pose)
    return goal


@st.composite
def move_goals(draw: st.DrawFn) -> MoveArm.Goal:
    goal = MoveArm.Goal(end_effector=draw(NAMES), position_tolerance=draw(NUMBERS), orientation_tolerance=draw(NUMBERS),
                        max_velocity_scaling=draw(NUMBERS), timeout=draw(NUMBERS))
    goal.target.header.frame_id = draw(NAMES)
    pose_fields(draw, goal.target.pose)
    return goal


@st.composite
def pick_goals(draw: st.DrawFn) -> PickPlace.Goal:
    goal = PickPlace.Goal(object_id=draw(NAMES), end_effector=draw(NAMES), grasp_force=draw(NUMBERS),
                          approach_height=draw(NUMBERS), lift_height=draw(NUMBERS), timeout=draw(NUMBERS))
    goal.pick_pose.header.frame_id = draw(NAMES)
    goal.place_pose.header.frame_id = draw(NAMES)
    pose_fields(draw, goal.pick_pose.pose)
    pose_fields(draw, goal.place_pose.pose)
    return goal


@st.composite
def reset_pose_goals(draw: st.DrawFn) -> ResetPose.Goal:
    return ResetPose.Goal(tolerance=draw(NUMBERS), timeout=draw(NUMBERS))


STRATEGIES = {"reset_pose": reset_pose_goals(), "walk": walk_goals(), "navigate_to_pose": navigate_goals(),
              "move_arm": move_goals(), "pick_place": pick_goals()}


def test_every_action_with_goal_fields_is_fuzzed():
    unfuzzed = [s for s in BINDINGS if s not in STRATEGIES and BINDINGS[s].action_type.Goal.get_fields_and_field_types()]
    assert not unfuzzed, f"add a goal strategy for {unfuzzed}"


@pytest.mark.parametrize("robot_name", ["g1", "panda"])
@pytest.mark.parametrize("skill", list(STRATEGIES))
def test_the_goal_callback_judges_any_goal_with_a_reason(skill, robot_name):
    binding = BINDINGS[skill]
    robot = robot_models.load(robot_name)

    @settings(max_examples=150 * SCALE, deadline=None, derandomize=True)
    @given(STRATEGIES[skill])
    def judged(goal: object) -> None:
        try:
            binding.validate(goal, robot)
            binding.resource(goal, robot)
        except InvalidGoalError as error:
            assert str(error), "a refusal says why"

    judged()


def _assert_ends_with_a_reason(client, sent, action_type) -> None:
    if not sent.handle.accepted:
        return
    outcome = result(client, sent, timeout=300.0)
    assert outcome.status in (GoalStatus.STATUS_SUCCEEDED, GoalStatus.STATUS_ABORTED, GoalStatus.STATUS_CANCELED)
    if outcome.result.error_code != action_type.Result.SUCCESS:
        assert outcome.result.error_msg, f"ended {outcome.result.error_code} without a reason"
        assert outcome.result.error_code != action_type.Result.SIM_FAULT, outcome.result.error_msg


@pytest.fixture(scope="module")
def panda(client):
    with running(["bringup", "--robot", "panda", "--rtf", "0"]) as process:
        yield process


def test_random_arm_goals_through_ros_end_with_a_code_and_the_next_valid_goal_succeeds(client, panda):
    move = ready_client(client, MoveArm, "/move_arm", timeout=READY_S)
    pick = ready_client(client, PickPlace, "/pick_place", timeout=READY_S)
    # Finite-but-wrong goals besides the random ones: unreachable, off the table, absurd timeouts.
    wrong = [MoveArm.Goal(position_tolerance=0.001, timeout=1e-6), PickPlace.Goal(object_id="box_0")]
    wrong[0].target.pose.position.x, wrong[0].target.pose.orientation.w = 2.5, 1.0
    wrong[1].place_pose.pose.position.x = 3.0

    @settings(max_examples=15 * SCALE, deadline=None, derandomize=True,
              suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
    @given(st.one_of(move_goals(), pick_goals(), st.sampled_from(wrong)))
    def served(goal: object) -> None:
        action_type, action = (MoveArm, move) if isinstance(goal, MoveArm.Goal) else (PickPlace, pick)
        sent = send(client, action, goal)
        _assert_ends_with_a_reason(client, sent, action_type)
        assert panda.alive()

    served()
    valid = MoveArm.Goal(position_tolerance=0.002, orientation_tolerance=0.0)
    valid.target.pose.position.x, valid.target.pose.position.z, valid.target.pose.orientation.w = 0.5, 0.3, 1.0
    outcome = result(client, send(client, move, valid))
    assert outcome.result.error_code == MoveArm.Result.SUCCESS, outcome.result.error_msg


PARAMETER_VALUES = st.one_of(
    st.builds(lambda v: ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=v), NUMBERS),
    st.builds(lambda v: ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=v),
              st.integers(min_value=-(2 ** 63), max_value=2 ** 63 - 1)),
    st.builds(lambda v: ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=v), st.text(max_size=20)),
    st.builds(lambda v: ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=v), st.booleans()),
    st.builds(lambda t: ParameterValue(type=t), st.integers(min_value=0, max_value=255)),  # unknown types
)


def test_random_parameter_messages_are_answered_and_leave_every_parameter_in_range(client, panda):
    nodes = ("/sim", "/arm")
    declared = {node: list(client.call(ListParameters, f"{node}/list_parameters", ListParameters.Request(),
                                       timeout=READY_S).result.names) for node in nodes}

    @settings(max_examples=40 * SCALE, deadline=None, derandomize=True,
              suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
    @given(st.sampled_from(nodes), st.data())
    def answered(node: str, data: st.DataObject) -> None:
        names = st.one_of(st.sampled_from(declared[node]), st.sampled_from(["", "no_such_parameter"]), st.text(max_size=20))
        parameters = data.draw(st.lists(st.builds(Parameter, name=names, value=PARAMETER_VALUES), min_size=1, max_size=4))
        answer = client.call(SetParameters, f"{node}/set_parameters", SetParameters.Request(parameters=parameters),
                             timeout=READY_S)
        assert len(answer.results) == len(parameters)
        for outcome in answer.results:
            assert outcome.successful or outcome.reason, "a refusal says why"
        assert panda.alive()

    answered()
    for node in nodes:  # every declared parameter still in its declared range
        names = declared[node]
        values = client.call(GetParameters, f"{node}/get_parameters", GetParameters.Request(names=names),
                             timeout=READY_S).values
        descriptors = client.call(DescribeParameters, f"{node}/describe_parameters",
                                  DescribeParameters.Request(names=names), timeout=READY_S).descriptors
        for name, value, descriptor in zip(names, values, descriptors, strict=True):
            for bound in descriptor.floating_point_range:
                assert math.isfinite(value.double_value) and \
                    bound.from_value - 1e-9 <= value.double_value <= bound.to_value + 1e-9, (node, name, value)
            for bound in descriptor.integer_range:
                assert bound.from_value <= value.integer_value <= bound.to_value, (node, name, value)
