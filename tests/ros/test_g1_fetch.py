"""PickPlace on the G1 through ROS (issue 21), from a plain rclpy client in another process: one goal for the cube
takes it in one hand (the fingers close until they press on it) to the second table; one goal walks the
robot to the box, squeezes it between both palms, lifts it, carries it to the second table and puts it down
within 2 cm of the place, with feedback at every stage, after the box was moved on the first table through
/sim/set_entity_state; a MoveArm goal for an arm the fetch moves is refused with the reason; a cancel while
it carries stops the robot, which stands holding the box, and a new goal for the box it holds goes straight to
the place.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from action_msgs.msg import GoalStatus

from robot_models import g1_tables
from sim_interfaces.action import MoveArm, PickPlace
from simulation_interfaces.msg import Result
from simulation_interfaces.srv import GetEntityState, SetEntityState
from tests.ros.actions import ready_client, result, send, wait_feedback
from tests.ros.processes import running

pytestmark = pytest.mark.slow

PLACE = (1.02, -2.75)  # on the second table, 12 cm inside its edge toward the robot's side [m]
MOVED_TO = (1.06, 0.03, -0.20)  # the box, moved (4 cm deeper, turned 11 deg) on the first table: x, y [m], yaw [rad]
PLACEMENT_TOLERANCE_M = 0.02
FETCH_WAIT_S = 900.0  # wall seconds for the whole task (about 60 s of sim time)
CARRY_WAIT_S = 600.0  # wall seconds until it carries the box (about 25 s of sim time)
MIN_GRIP_N = 5.0


def _box(client):
    request = GetEntityState.Request(entity=g1_tables.BOX.name)
    return client.call(GetEntityState, "/sim/get_entity_state", request, timeout=30.0).state


def _box_z(client) -> float:
    return _box(client).pose.position.z


def _tilt(q) -> float:
    """Angle between the body's z axis and the world's [rad]."""
    return math.acos(max(-1.0, min(1.0, 1.0 - 2.0 * (q.x * q.x + q.y * q.y))))


def _place_goal() -> PickPlace.Goal:
    goal = PickPlace.Goal(object_id=g1_tables.BOX.name)
    goal.place_pose.header.frame_id = "world"
    goal.place_pose.pose.position.x, goal.place_pose.pose.position.y = PLACE
    goal.place_pose.pose.position.z = g1_tables.TABLE_TOP_Z_M
    return goal


def test_one_pick_place_goal_fetches_the_moved_box_to_the_second_table(client):
    rest_z = g1_tables.TABLE_TOP_Z_M + g1_tables.BOX.half_size[2]
    with running(["bringup", "--robot", "g1", "--scene", "tables", "--rtf", "0"]) as process:
        pick_place = ready_client(client, PickPlace, "/pick_place", timeout=90.0)
        state = _box(client)
        x, y, yaw = MOVED_TO
        state.pose.position.x, state.pose.position.y, state.pose.position.z = x, y, rest_z + 0.002
        o = state.pose.orientation
        o.w, o.x, o.y, o.z = math.cos(yaw / 2.0), 0.0, 0.0, math.sin(yaw / 2.0)
        request = SetEntityState.Request(entity=g1_tables.BOX.name, state=state, set_pose=True)
        moved = client.call(SetEntityState, "/sim/set_entity_state", request, timeout=30.0).result
        assert moved.result == Result.RESULT_OK, moved.error_message

        sent = send(client, pick_place, _place_goal())
        assert sent.handle.accepted
        outcome = result(client, sent, timeout=FETCH_WAIT_S)
        assert outcome.status == GoalStatus.STATUS_SUCCEEDED, (outcome.result.error_code, outcome.result.error_msg)
        assert outcome.result.placement_error <= PLACEMENT_TOLERANCE_M
        stages = [f.stage for f in sent.feedback]
        assert stages == sorted(stages) and set(stages) == set(range(8)), f"every stage, in order: {sorted(set(stages))}"

        final = _box(client)
        p = final.pose.position
        assert math.dist((p.x, p.y), PLACE) <= PLACEMENT_TOLERANCE_M, (p.x, p.y)
        assert abs(p.z - rest_z) < 0.01 and _tilt(final.pose.orientation) < math.radians(5.0), "resting level on the table"
        v = final.twist.linear
        assert np.linalg.norm([v.x, v.y, v.z]) < 0.02, "let go of, at rest"
        assert process.alive(), process.output()


def test_one_pick_place_goal_fetches_the_cube_in_one_hand(client):
    cube = g1_tables.CUBE
    rest_z = g1_tables.TABLE_TOP_Z_M + cube.half_size[2]
    goal = PickPlace.Goal(object_id=cube.name)
    goal.place_pose.header.frame_id = "world"
    goal.place_pose.pose.position.x, goal.place_pose.pose.position.y = PLACE
    goal.place_pose.pose.position.z = g1_tables.TABLE_TOP_Z_M
    with running(["bringup", "--robot", "g1", "--scene", "tables", "--rtf", "0"]) as process:
        pick_place = ready_client(client, PickPlace, "/pick_place", timeout=90.0)
        sent = send(client, pick_place, goal)
        assert sent.handle.accepted
        outcome = result(client, sent, timeout=FETCH_WAIT_S)
        assert outcome.status == GoalStatus.STATUS_SUCCEEDED, (outcome.result.error_code, outcome.result.error_msg)
        stages = [f.stage for f in sent.feedback]
        assert stages == sorted(stages) and set(stages) == set(range(8)), f"every stage, in order: {sorted(set(stages))}"
        carried = [f for f in sent.feedback if f.stage == PickPlace.Feedback.TRANSPORT]
        assert carried and min(f.object_pose.pose.position.z for f in carried) > rest_z + 0.02, "held up while carried"
        state = client.call(GetEntityState, "/sim/get_entity_state", GetEntityState.Request(entity=cube.name),
                            timeout=30.0).state
        p = state.pose.position
        assert math.dist((p.x, p.y), PLACE) <= PLACEMENT_TOLERANCE_M, (p.x, p.y)
        assert abs(p.z - rest_z) < 0.01 and _tilt(state.pose.orientation) < math.radians(5.0), "resting level on the table"
        assert process.alive(), process.output()


def test_a_pick_place_goal_walks_grasps_lifts_and_carries_the_box_a_cancel_keeps_it_held_and_a_new_goal_places_it(client):
    rest_z = g1_tables.TABLE_TOP_Z_M + g1_tables.BOX.half_size[2]
    with running(["bringup", "--robot", "g1", "--scene", "tables", "--rtf", "0"]) as process:
        pick_place = ready_client(client, PickPlace, "/pick_place", timeout=90.0)
        move_arm = ready_client(client, MoveArm, "/move_arm", timeout=90.0)
        refused = PickPlace.Goal(object_id="box", end_effector="left_arm")
        refused.place_pose.pose.position.x, refused.place_pose.pose.position.y = PLACE
        assert not send(client, pick_place, refused).handle.accepted, "both palms: end_effector must be empty"

        sent = send(client, pick_place, _place_goal())
        assert sent.handle.accepted
        wait_feedback(client, sent, lambda f: f.phase == "navigate_place" and f.distance_remaining > 1.0,
                      CARRY_WAIT_S, "the robot carrying the box toward the second table")
        carrying = sent.feedback[-1]
        assert carrying.stage == PickPlace.Feedback.TRANSPORT and carrying.stage_name == "TRANSPORT"
        assert min(carrying.grip_force_left, carrying.grip_force_right) > MIN_GRIP_N, carrying
        assert carrying.object_pose.pose.position.z > rest_z + 0.03, "lifted off the table (5 cm)"
        assert carrying.object_pose.header.frame_id == "world"

        stages = [f.stage for f in sent.feedback]
        assert stages == sorted(stages), "stages only move forward"
        seen = set(stages)
        assert seen == set(range(PickPlace.Feedback.TRANSPORT + 1)), f"every stage up to TRANSPORT: {sorted(seen)}"
        approach = [f for f in sent.feedback if f.stage == PickPlace.Feedback.APPROACH]
        assert max(f.distance_remaining for f in approach) > 0.3, "walked to the box"
        squeeze = [f for f in sent.feedback if f.stage == PickPlace.Feedback.GRASP]
        assert squeeze[-1].grip_force > MIN_GRIP_N, "squeezed to a measured force before lifting"

        # Canceled while it carries the box (at once: the sim runs as fast as it can, and a slower client's cancel
        # once came as the box was being lowered onto the second table, 1.6 cm above its rest).
        answer = sent.cancel()
        assert answer.return_code == 0, answer  # ERROR_NONE: the cancel is taken
        outcome = result(client, sent, timeout=120.0)
        assert outcome.status == GoalStatus.STATUS_CANCELED, (outcome.result.error_code, outcome.result.error_msg)
        assert "in stage TRANSPORT" in outcome.result.error_msg, outcome.result.error_msg
        assert "holding the object" in outcome.result.error_msg, outcome.result.error_msg
        assert _box_z(client) > rest_z + 0.03, "still held up after the cancel"

        # A new PickPlace for the box it holds goes straight to the place, and puts it down there.
        again = send(client, pick_place, _place_goal())
        assert again.handle.accepted
        wait_feedback(client, again, lambda f: f.stage == PickPlace.Feedback.TRANSPORT, CARRY_WAIT_S, "the new goal carrying")

        # An arm the fetch moves takes no other goal meanwhile: refused with the reason, the fetch untouched.
        reach = MoveArm.Goal(end_effector="left_arm", position_tolerance=0.01, orientation_tolerance=0.1)
        reach.target.header.frame_id = "pelvis"
        reach.target.pose.position.x, reach.target.pose.position.y, reach.target.pose.position.z = 0.3, 0.25, 0.1
        reach.target.pose.orientation.w = 1.0
        refused_arm = send(client, move_arm, reach)
        assert refused_arm.handle.accepted, "a valid goal: /sim is the one that knows the arm is taken"
        arm_outcome = result(client, refused_arm, timeout=60.0)
        assert arm_outcome.status == GoalStatus.STATUS_ABORTED, arm_outcome.result.error_msg
        assert "moved by the running pick_place goal" in arm_outcome.result.error_msg, arm_outcome.result.error_msg

        finished = result(client, again, timeout=FETCH_WAIT_S)
        assert finished.status == GoalStatus.STATUS_SUCCEEDED, (finished.result.error_code, finished.result.error_msg)
        stages = [f.stage for f in again.feedback]
        assert stages and min(stages) == PickPlace.Feedback.TRANSPORT and stages == sorted(stages), stages
        p = _box(client).pose.position
        assert math.dist((p.x, p.y), PLACE) <= PLACEMENT_TOLERANCE_M, (p.x, p.y)
        assert process.alive(), process.output()
