"""The G1's tables scene through ``bringup``: NavigateToPose walks around a table, the objects stay on it;
PickPlace goals the palms cannot serve are refused with their reason."""

from __future__ import annotations

import math

import pytest
from action_msgs.msg import GoalStatus
from rcl_interfaces.srv import GetParameters

from robot_models import g1_tables
from sim_interfaces.action import NavigateToPose, PickPlace
from sim_interfaces.srv import ComputeIK
from simulation_interfaces.srv import GetEntityState
from tests.ros.actions import nav_goal, ready_client, result, send
from tests.ros.processes import running

pytestmark = pytest.mark.slow


def test_bringup_tables_navigates_around_a_table_and_its_servers_know_the_scene(client):
    table = g1_tables.PICK_TABLE
    with running(["bringup", "--robot", "g1", "--scene", "tables", "--rtf", "2.0"]) as process:
        navigate = ready_client(client, NavigateToPose, "/navigate_to_pose", timeout=90.0)
        on_the_table = result(client, send(client, navigate, nav_goal(*table.center_xy)))
        assert on_the_table.status == GoalStatus.STATUS_ABORTED
        assert on_the_table.result.error_code == NavigateToPose.Result.GOAL_IN_OBSTACLE

        behind = (table.xy_bounds[1] + 0.7, table.center_xy[1])
        sent = send(client, navigate, nav_goal(*behind))
        outcome = result(client, sent, timeout=400.0)
        assert outcome.status == GoalStatus.STATUS_SUCCEEDED, outcome.result.error_msg
        final = outcome.result.final_pose.pose.position
        assert math.dist((final.x, final.y), behind) <= 0.2 and final.z > 0.6
        sideways = max(abs(f.current_pose.pose.position.y) for f in sent.feedback)
        assert sideways > table.half_size_xy[1], "the robot walked around the table, not through it"
        for item in g1_tables.OBJECTS:
            state = client.call(GetEntityState, "/sim/get_entity_state", GetEntityState.Request(entity=item.name),
                                timeout=30.0).state
            p = state.pose.position
            assert math.dist((p.x, p.y, p.z), g1_tables.object_rest_position(item)) < 0.005, f"{item.name} moved"
        for server in ("arm", "locomotion"):  # they judge goals with the scene's facts
            values = client.call(GetParameters, f"/{server}/get_parameters", GetParameters.Request(names=["scene"]),
                                 timeout=30.0).values
            assert [v.string_value for v in values] == ["tables"], server
        query = ComputeIK.Request(end_effector="right_arm", position_only=True)
        query.target.header.frame_id = "box"
        answer = client.call(ComputeIK, "/arm/compute_ik", query, timeout=30.0)
        assert not answer.success and "is an object's" in answer.message, answer.message  # a frame /arm knows
        pick_place = ready_client(client, PickPlace, "/pick_place", timeout=60.0)
        assert not send(client, pick_place, PickPlace.Goal(object_id="cube")).handle.accepted, "on the floor"
        off_the_tables = PickPlace.Goal(object_id="box")  # place (0, 0): on the floor
        assert not send(client, pick_place, off_the_tables).handle.accepted, "a place on no table top"
        assert process.alive(), process.output()
