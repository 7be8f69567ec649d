"""The ROS simulation standard (simulation_interfaces) on /sim, driven through its own types from another process."""

from __future__ import annotations

import math

import pytest
from action_msgs.msg import GoalStatus
from geometry_msgs.msg import Point, Vector3

from robot_models import panda_constants
from sim_interfaces.msg import ObjectStates
from simulation_interfaces.action import SimulateSteps
from simulation_interfaces.msg import (
    Bounds,
    EntityCategory,
    EntityFilters,
    Result,
    SimulationState,
    SimulatorFeatures,
    TagsFilter,
)
from simulation_interfaces.srv import (
    DeleteEntity,
    GetEntities,
    GetEntitiesStates,
    GetEntityBounds,
    GetEntityInfo,
    GetEntityState,
    GetSimulationState,
    GetSimulatorFeatures,
    GetSpawnables,
    ResetSimulation,
    SetEntityState,
    SetSimulationState,
    SpawnEntity,
    StepSimulation,
)
from tests.ros.actions import ready_client, result, send
from tests.ros.processes import running

STARTUP_S = 60.0
PHYSICS_STEP_S = 0.002  # the Panda scene's MuJoCo timestep
OK = Result.RESULT_OK


@pytest.fixture(scope="class")
def panda(client):
    with running(["sim_node", "--ros-args", "-p", "robot:=panda"]) as process:
        client.call(GetSimulatorFeatures, "/sim/get_simulator_features", GetSimulatorFeatures.Request(), timeout=STARTUP_S)
        assert process.alive(), process.output()
        yield process
        assert process.alive(), "every refusal left /sim serving"


def call(client, srv_type, name: str, **fields):
    return client.call(srv_type, f"/sim/{name}", srv_type.Request(**fields), timeout=30.0)


def sim_time(client) -> float:
    """Sim time [s], from the stamp of an entity state (the standard has no clock query of its own)."""
    stamp = call(client, GetEntityState, "get_entity_state", entity="box_0").state.header.stamp
    return stamp.sec + stamp.nanosec * 1e-9


def set_state(client, state: int) -> Result:
    return call(client, SetSimulationState, "set_simulation_state", state=SimulationState(state=state)).result


def get_state(client) -> int:
    return call(client, GetSimulationState, "get_simulation_state").state.state


class TestPanda:
    """The Panda at its table with three boxes (one /sim for the class; the G1 test below starts its own)."""

    def test_features_say_what_is_served_and_spawning_is_refused(self, client, panda):
        features = call(client, GetSimulatorFeatures, "get_simulator_features").features
        served = set(features.features)
        for feature in (SimulatorFeatures.SIMULATION_RESET, SimulatorFeatures.SIMULATION_STATE_SETTING,
                        SimulatorFeatures.SIMULATION_STATE_PAUSE, SimulatorFeatures.STEP_SIMULATION_MULTIPLE,
                        SimulatorFeatures.STEP_SIMULATION_ACTION, SimulatorFeatures.ENTITY_STATE_GETTING,
                        SimulatorFeatures.ENTITY_STATE_SETTING, SimulatorFeatures.ENTITY_INFO_GETTING,
                        SimulatorFeatures.WORLD_LOADING, SimulatorFeatures.AVAILABLE_WORLDS,
                        SimulatorFeatures.WORLD_INFO_GETTING):
            assert feature in served
        for feature in (SimulatorFeatures.SPAWNING, SimulatorFeatures.DELETING, SimulatorFeatures.SPAWNABLES,
                        SimulatorFeatures.WORLD_RESOURCE_STRING, SimulatorFeatures.WORLD_UNLOADING,
                        SimulatorFeatures.SIMULATION_RESET_SPAWNED):
            assert feature not in served
        assert list(features.spawn_formats) == [] and "physics step" in features.custom_info
        for srv_type, name in ((SpawnEntity, "spawn_entity"), (DeleteEntity, "delete_entity"), (GetSpawnables, "get_spawnables")):
            answer = call(client, srv_type, name).result
            assert answer.result == Result.RESULT_FEATURE_UNSUPPORTED and "set_entity_state" in answer.error_message


    def test_state_round_trip_and_refused_transitions(self, client, panda):
        assert get_state(client) == SimulationState.STATE_PLAYING
        assert set_state(client, SimulationState.STATE_PAUSED).result == OK
        assert get_state(client) == SimulationState.STATE_PAUSED
        assert set_state(client, SimulationState.STATE_PAUSED).result == SetSimulationState.Response.ALREADY_IN_TARGET_STATE
        quitting = set_state(client, SimulationState.STATE_QUITTING)
        assert quitting.result == Result.RESULT_FEATURE_UNSUPPORTED and "PLAYING" in quitting.error_message
        no_world = set_state(client, SimulationState.STATE_NO_WORLD)
        assert no_world.result == SetSimulationState.Response.INCORRECT_TRANSITION and "STOPPED" in no_world.error_message
        assert set_state(client, SimulationState.STATE_PLAYING).result == OK
        assert get_state(client) == SimulationState.STATE_PLAYING
        start = sim_time(client)
        client.wait_for(lambda: sim_time(client) > start + 0.05, 30.0, "sim time to run while playing")

        assert set_state(client, SimulationState.STATE_STOPPED).result == OK
        assert get_state(client) == SimulationState.STATE_STOPPED
        assert sim_time(client) == 0.0, "stopped = paused and reset with SCOPE_ALL: the clock restarts"
        assert set_state(client, SimulationState.STATE_STOPPED).result == SetSimulationState.Response.ALREADY_IN_TARGET_STATE
        assert set_state(client, SimulationState.STATE_PAUSED).result == OK
        assert get_state(client) == SimulationState.STATE_PAUSED and sim_time(client) == 0.0
        assert set_state(client, SimulationState.STATE_PLAYING).result == OK


    def test_step_simulation_advances_sim_time_by_whole_physics_steps(self, client, panda):
        refused = call(client, StepSimulation, "step_simulation", steps=5).result
        assert refused.result == Result.RESULT_OPERATION_FAILED and "paused" in refused.error_message
        assert set_state(client, SimulationState.STATE_PAUSED).result == OK
        try:
            before = sim_time(client)
            assert call(client, StepSimulation, "step_simulation", steps=1).result.result == OK
            assert call(client, StepSimulation, "step_simulation", steps=149).result.result == OK
            assert sim_time(client) - before == pytest.approx(150 * PHYSICS_STEP_S, abs=1e-9)
            assert sim_time(client) - before == pytest.approx(150 * PHYSICS_STEP_S, abs=1e-9), "paused: it stays"
            zero = call(client, StepSimulation, "step_simulation", steps=0).result
            assert zero.result == Result.RESULT_OPERATION_FAILED and "steps must be in" in zero.error_message
        finally:
            set_state(client, SimulationState.STATE_PLAYING)


    def test_simulate_steps_reports_progress_and_can_be_canceled(self, client, panda):
        action = ready_client(client, SimulateSteps, "/sim/simulate_steps")
        assert set_state(client, SimulationState.STATE_PAUSED).result == OK
        try:
            before = sim_time(client)
            # The last feedback is published before the result, on another topic: it may arrive after it, and
            # rclpy's action client drops feedback of a goal whose result it has. So the feedback topic itself is
            # read, as `ros2 topic echo` would, for every message of this goal.
            stream = client.record(SimulateSteps.Impl.FeedbackMessage, "/sim/simulate_steps/_action/feedback")
            sent = send(client, action, SimulateSteps.Goal(steps=500))
            outcome = result(client, sent, timeout=60.0)
            assert outcome.status == GoalStatus.STATUS_SUCCEEDED and outcome.result.result.result == OK
            assert sim_time(client) - before == pytest.approx(500 * PHYSICS_STEP_S, abs=1e-9)

            def of_this_goal() -> list:
                return [m.feedback for m in stream.messages() if bytes(m.goal_id.uuid) == bytes(sent.handle.goal_id.uuid)]

            client.wait_for(lambda: of_this_goal() and of_this_goal()[-1].completed_steps == 500, 30.0,
                            "the feedback of the last step")
            progress = [(f.completed_steps, f.remaining_steps) for f in of_this_goal()]
            assert len(progress) >= 2 and progress[-1] == (500, 0)
            assert all(done + left == 500 for done, left in progress)
            assert [done for done, _ in progress] == sorted(done for done, _ in progress)

            long = send(client, action, SimulateSteps.Goal(steps=50_000_000))  # ~28 h of sim time
            client.wait_for(lambda: long.feedback, 30.0, "the first feedback of a long SimulateSteps goal")
            assert long.cancel().return_code == 0
            canceled = result(client, long, timeout=30.0)
            assert canceled.status == GoalStatus.STATUS_CANCELED and "canceled after" in canceled.result.result.error_message
        finally:
            set_state(client, SimulationState.STATE_PLAYING)
        refused = result(client, send(client, action, SimulateSteps.Goal(steps=10)), timeout=30.0)
        assert refused.status == GoalStatus.STATUS_ABORTED and refused.result.result.result == Result.RESULT_OPERATION_FAILED


    def test_entities_are_listed_and_filtered(self, client, panda):
        def names(**filters) -> list[str]:
            answer = call(client, GetEntities, "get_entities", filters=EntityFilters(**filters))
            assert answer.result.result == OK, answer.result.error_message
            return list(answer.entities)

        assert names() == ["panda", *panda_constants.BOX_NAMES, "table"]
        assert names(filter="box_[12]") == ["box_1", "box_2"]
        assert names(categories=[EntityCategory(category=EntityCategory.CATEGORY_ROBOT)]) == ["panda"]
        assert names(categories=[EntityCategory(category=EntityCategory.CATEGORY_STATIC_OBJECT)]) == ["table"]
        assert names(tags=TagsFilter(tags=["object", "graspable"], filter_mode=TagsFilter.FILTER_MODE_ALL)) == list(
            panda_constants.BOX_NAMES)
        x, y, z = panda_constants.BOX_HOME_POSITIONS[1]
        sphere = Bounds(type=Bounds.TYPE_SPHERE, points=[Vector3(x=x, y=y, z=z + 0.1), Vector3(x=0.09)])
        assert names(bounds=sphere) == ["box_1"]
        hull = Bounds(type=Bounds.TYPE_CONVEX_HULL, points=[Vector3(), Vector3(x=1.0), Vector3(y=1.0)])
        answer = call(client, GetEntities, "get_entities", filters=EntityFilters(bounds=hull)).result
        assert answer.result == Result.RESULT_FEATURE_UNSUPPORTED and "TYPE_SPHERE" in answer.error_message

        info = call(client, GetEntityInfo, "get_entity_info", entity="box_2")
        assert info.result.result == OK and info.info.category.category == EntityCategory.CATEGORY_OBJECT
        bounds = call(client, GetEntityBounds, "get_entity_bounds", entity="box_2")
        assert bounds.bounds.type == Bounds.TYPE_BOX and bounds.bounds.points[1].x == pytest.approx(0.02, abs=1e-6)
        states = call(client, GetEntitiesStates, "get_entities_states", filters=EntityFilters(filter="^box"))
        assert list(states.entities) == list(panda_constants.BOX_NAMES) and len(states.states) == 3
        assert states.states[0].header.frame_id == "world"


    def test_set_entity_state_moves_a_box_and_reset_restores_it(self, client, panda):
        objects = client.record(ObjectStates, "/objects", keep=100)

        def box_1_x() -> float | None:
            latest = objects.latest
            return None if latest is None else latest.poses[list(latest.names).index("box_1")].position.x

        home = panda_constants.BOX_HOME_POSITIONS[1]
        client.wait_for(lambda: box_1_x() is not None, 30.0, "/objects")
        state = call(client, GetEntityState, "get_entity_state", entity="box_1").state
        assert state.pose.position.x == pytest.approx(home[0], abs=0.005)
        state.pose.position = Point(x=home[0] - 0.1, y=home[1] + 0.05, z=home[2] + 0.001)
        moved = call(client, SetEntityState, "set_entity_state", entity="box_1", state=state, set_pose=True).result
        assert moved.result == OK, moved.error_message
        client.wait_for(lambda: abs(box_1_x() - (home[0] - 0.1)) < 0.005, 30.0, "box_1 moved on /objects")
        after = call(client, GetEntityState, "get_entity_state", entity="box_1").state
        assert after.pose.position.y == pytest.approx(home[1] + 0.05, abs=0.005)

        spun = GetEntityState.Response().state
        spun.pose = after.pose
        spun.twist.angular.z = 2.0
        assert call(client, SetEntityState, "set_entity_state", entity="box_2", state=spun, set_twist=True).result.result == OK

        for kwargs, code, words in (
            ({"entity": "box_9", "set_pose": True}, Result.RESULT_NOT_FOUND, "box_0"),
            ({"entity": "panda", "set_pose": True}, Result.RESULT_OPERATION_FAILED, "fixed to the world"),
            ({"entity": "table", "set_pose": True}, Result.RESULT_OPERATION_FAILED, "box_0, box_1, box_2"),
        ):
            answer = call(client, SetEntityState, "set_entity_state", state=after, **kwargs).result
            assert answer.result == code and words in answer.error_message, answer.error_message
        bad = GetEntityState.Response().state
        bad.pose.orientation.w = 0.5  # not a unit quaternion
        answer = call(client, SetEntityState, "set_entity_state", entity="box_1", state=bad, set_pose=True).result
        assert answer.result == SetEntityState.Response.INVALID_POSE and "unit quaternion" in answer.error_message
        in_a_link = GetEntityState.Response().state
        in_a_link.header.frame_id = "panda_hand"
        answer = call(client, SetEntityState, "set_entity_state", entity="box_1", state=in_a_link, set_pose=True).result
        assert answer.result == Result.RESULT_FEATURE_UNSUPPORTED and "world" in answer.error_message
        unknown = call(client, GetEntityState, "get_entity_state", entity="nothing")
        assert unknown.result.result == Result.RESULT_NOT_FOUND and "box_1" in unknown.result.error_message

        scope = ResetSimulation.Request.SCOPE_TIME
        alone = call(client, ResetSimulation, "reset_simulation", scope=scope).result
        assert alone.result == Result.RESULT_FEATURE_UNSUPPORTED and "SCOPE_ALL" in alone.error_message
        assert abs(box_1_x() - (home[0] - 0.1)) < 0.005, "a refused reset changes nothing"
        assert call(client, ResetSimulation, "reset_simulation", scope=ResetSimulation.Request.SCOPE_ALL).result.result == OK
        client.wait_for(lambda: abs(box_1_x() - home[0]) < 0.005, 30.0, "box_1 back home on /objects")
        restored = call(client, GetEntityState, "get_entity_state", entity="box_2").state
        assert math.hypot(restored.twist.angular.z, restored.pose.position.x - home[0]) < 0.01
        assert sim_time(client) < 5.0, "SCOPE_ALL restarts the clock"
        objects.stop()


def test_set_entity_state_moves_the_g1_base_and_it_stands_there(client):
    with running(["sim_node", "--ros-args", "-p", "robot:=g1", "-p", "scene:=course"]) as process:
        robot = EntityCategory(category=EntityCategory.CATEGORY_ROBOT)
        static = EntityCategory(category=EntityCategory.CATEGORY_STATIC_OBJECT)
        assert call(client, GetEntities, "get_entities", filters=EntityFilters(categories=[robot])).entities == ["g1"]
        obstacles = call(client, GetEntities, "get_entities", filters=EntityFilters(categories=[static])).entities
        assert list(obstacles) == ["obstacle_wall", "obstacle_block", "obstacle_pillar"]
        assert set_state(client, SimulationState.STATE_PAUSED).result == OK
        state = call(client, GetEntityState, "get_entity_state", entity="g1").state
        assert 0.7 < state.pose.position.z < 0.8, "the pelvis of the standing G1"
        state.pose.position.x += 0.8
        state.pose.position.y -= 0.5
        moved = call(client, SetEntityState, "set_entity_state", entity="g1", state=state, set_pose=True, set_twist=True)
        assert moved.result.result == OK, moved.result.error_message
        assert call(client, StepSimulation, "step_simulation", steps=1000).result.result == OK  # 2 s of sim time
        after = call(client, GetEntityState, "get_entity_state", entity="g1").state
        assert after.pose.position.x == pytest.approx(state.pose.position.x, abs=0.03)
        assert after.pose.position.y == pytest.approx(state.pose.position.y, abs=0.03)
        assert after.pose.position.z > 0.7, "it stands where it was put"
        wall = call(client, SetEntityState, "set_entity_state", entity="obstacle_wall", state=state, set_pose=True).result
        assert wall.result == Result.RESULT_OPERATION_FAILED and "navigation map" in wall.error_message
        assert process.alive(), process.output()


def test_the_g1_tables_scene_serves_its_tables_and_objects(client):
    """``scene:=tables``: objects on /objects and /tf, movable through the standard; tables static, on /map."""
    from nav_msgs.msg import OccupancyGrid
    from rcl_interfaces.srv import GetParameters
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from tf2_msgs.msg import TFMessage

    from robot_models import g1_tables

    objects = ("box", "cube", "can")
    with running(["sim_node", "--ros-args", "-p", "robot:=g1", "-p", "scene:=tables"]) as process:
        grid = client.record(OccupancyGrid, "/map", QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
        published = client.record(ObjectStates, "/objects", keep=100)
        tf = client.record(TFMessage, "/tf", keep=2000)
        static = EntityCategory(category=EntityCategory.CATEGORY_STATIC_OBJECT)
        assert list(call(client, GetEntities, "get_entities", filters=EntityFilters()).entities) == [
            "g1", *objects, "table_0", "table_1"]
        assert list(call(client, GetEntities, "get_entities", filters=EntityFilters(categories=[static])).entities) == [
            "table_0", "table_1"]
        bounds = call(client, GetEntityBounds, "get_entity_bounds", entity="table_1").bounds
        assert bounds.type == Bounds.TYPE_BOX and bounds.points[1].z - bounds.points[0].z == pytest.approx(0.75, abs=1e-6)
        cube = call(client, GetEntityBounds, "get_entity_bounds", entity="cube").bounds
        assert cube.points[1].x - cube.points[0].x == pytest.approx(0.055, abs=1e-6)

        client.wait_for(lambda: published.latest is not None, 60.0, "/objects")
        assert tuple(published.latest.names) == objects
        client.wait_for(lambda: {t.child_frame_id for m in tf.messages() for t in m.transforms} >= set(objects), 30.0,
                        "world -> object transforms on /tf")
        client.wait_for(lambda: grid.count > 0, 90.0, "/map")  # latched: comes at discovery, slow on a loaded machine
        info = grid.latest.info
        for table in g1_tables.TABLES:
            x, y = table.center_xy
            column = int((x - info.origin.position.x) / info.resolution)
            row = int((y - info.origin.position.y) / info.resolution)
            assert grid.latest.data[row * info.width + column] > 50, f"{table.name} is an obstacle on /map"

        state = call(client, GetEntityState, "get_entity_state", entity="cube").state
        place = g1_tables.PLACE_TABLE
        state.pose.position = Point(x=place.center_xy[0], y=place.center_xy[1], z=place.top_z + 0.03)
        moved = call(client, SetEntityState, "set_entity_state", entity="cube", state=state, set_pose=True).result
        assert moved.result == OK, moved.error_message

        def cube_y() -> float:
            latest = published.latest
            return latest.poses[list(latest.names).index("cube")].position.y

        client.wait_for(lambda: abs(cube_y() - place.center_xy[1]) < 0.005, 30.0, "the cube on the second table on /objects")
        table = call(client, SetEntityState, "set_entity_state", entity="table_0", state=state, set_pose=True).result
        assert table.result == Result.RESULT_OPERATION_FAILED and "navigation map" in table.error_message
        with running(["arm_server"]) as arm:  # no parameters: it asks /sim for its robot and scene
            asked = GetParameters.Request(names=["robot", "scene"])
            values = client.call(GetParameters, "/arm/get_parameters", asked, timeout=120.0).values
            assert [v.string_value for v in values] == ["g1", "tables"], arm.output()
        assert process.alive(), process.output()
        for recording in (grid, published, tf):
            recording.stop()


def test_an_inactive_sim_is_paused_steps_and_refuses_to_play(client):
    from lifecycle_msgs.msg import Transition
    from lifecycle_msgs.srv import ChangeState, GetState

    args = ["sim_node", "--ros-args", "-p", "robot:=panda", "-p", "autostart:=false"]
    with running(args) as process:
        # A query first, sent again until answered: the first response of a node just started can be lost
        # while its side of discovery matches this client's reply reader; a transition is sent only once.
        assert client.call(GetState, "/sim/get_state", GetState.Request(), timeout=STARTUP_S,
                           resend_every_s=2.0).current_state.label == "unconfigured"
        configure = ChangeState.Request(transition=Transition(id=Transition.TRANSITION_CONFIGURE))
        assert client.call(ChangeState, "/sim/change_state", configure, timeout=STARTUP_S).success
        assert get_state(client) == SimulationState.STATE_PAUSED, "configured, not active: nothing steps the physics"
        refused = set_state(client, SimulationState.STATE_PLAYING)
        assert refused.result == SetSimulationState.Response.STATE_TRANSITION_ERROR and "activate" in refused.error_message
        before = sim_time(client)
        assert call(client, StepSimulation, "step_simulation", steps=10).result.result == OK
        assert sim_time(client) - before == pytest.approx(10 * PHYSICS_STEP_S, abs=1e-9)
        assert process.alive(), process.output()
