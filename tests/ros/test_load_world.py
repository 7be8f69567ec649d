"""``/sim/load_world`` replaces the running scene by another of the robot's (simulation_interfaces' LoadWorld): bad
requests are refused with what is allowed and change nothing; a loaded scene runs from sim time 0 with its entities,
its map and the node's settings, and the action servers validate goals on it."""

from __future__ import annotations

import pathlib

import pytest
from action_msgs.msg import GoalStatus
from nav_msgs.msg import OccupancyGrid
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, SetParameters
from rosgraph_msgs.msg import Clock

from sim_interfaces.action import PickPlace
from sim_ros.names import LATCHED
from simulation_interfaces.msg import Result
from simulation_interfaces.srv import GetAvailableWorlds, GetCurrentWorld, GetEntities, LoadWorld
from tests.ros.actions import ready_client, result, send
from tests.ros.processes import running

pytestmark = pytest.mark.slow

WAIT_S = 60.0  # [s] wall: a deadline for what must happen (never reached when it works)


def _load(client, uri: str = "", resource_string: str = "") -> LoadWorld.Response:
    request = LoadWorld.Request()
    request.world_resource.uri, request.world_resource.resource_string = uri, resource_string
    return client.call(LoadWorld, "/sim/load_world", request, timeout=WAIT_S)


def _current(client) -> str:
    return client.call(GetCurrentWorld, "/sim/get_current_world", GetCurrentWorld.Request(), timeout=WAIT_S).world.name


def _scene_of(client, node: str) -> str:
    values = client.call(GetParameters, f"/{node}/get_parameters", GetParameters.Request(names=["scene"]),
                         timeout=WAIT_S).values
    return values[0].string_value


def _child_named(parent: int, name: str) -> int:
    """The pid of ``parent``'s child process whose program is ``name``."""
    for status in pathlib.Path("/proc").glob("[0-9]*/status"):
        try:
            fields = dict(line.split(":\t", 1) for line in status.read_text().splitlines() if ":\t" in line)
            cmdline = (status.parent / "cmdline").read_bytes().split(b"\0")
        except OSError:  # ended meanwhile
            continue
        if int(fields.get("PPid", "0")) == parent and any(arg.endswith(name.encode()) for arg in cmdline[:2]):
            return int(status.parent.name)
    raise AssertionError(f"no {name} under process {parent}")


def _resident_mb(pid: int) -> float:
    status = pathlib.Path(f"/proc/{pid}/status").read_text()
    return int(status.split("VmRSS:")[1].split()[0]) / 1024.0


def _box_goal() -> PickPlace.Goal:
    goal = PickPlace.Goal(object_id="box")
    goal.place_pose.header.frame_id = "world"
    goal.place_pose.pose.position.x, goal.place_pose.pose.position.y, goal.place_pose.pose.position.z = 1.02, -2.75, 0.75
    return goal


def test_load_world_replaces_the_scene_and_the_servers_follow_it(client):
    with running(["bringup", "--robot", "g1", "--rtf", "1.0"]) as process:
        pick_place = ready_client(client, PickPlace, "/pick_place", timeout=90.0)
        worlds = client.call(GetAvailableWorlds, "/sim/get_available_worlds", GetAvailableWorlds.Request(), timeout=WAIT_S)
        assert [w.name for w in worlds.worlds] == ["open", "course", "tables"]
        assert _current(client) == "open"
        refused = send(client, pick_place, _box_goal())
        assert not refused.handle.accepted, "the open floor has no box"

        # Refused, with what is allowed; nothing changes and /sim keeps serving.
        for request, code, words in ((("moon", ""), Result.RESULT_NOT_FOUND, "scenes: open, course, tables"),
                                     (("", "<mujoco/>"), LoadWorld.Response.UNSUPPORTED_FORMAT, "named by uri"),
                                     (("", ""), LoadWorld.Response.NO_RESOURCE, "open, course, tables")):
            answer = _load(client, *request)
            assert answer.result.result == code and words in answer.result.error_message, answer.result
        assert _current(client) == "open"

        # The scenes replaced are let go: /sim's memory stays where one scene keeps it (a G1 scene is ~180 MB).
        sim = _child_named(process.process.pid, "sim_node")
        before = _resident_mb(sim)
        for scene in ("course", "open", "course", "open"):
            assert _load(client, scene).result.result == Result.RESULT_OK
        assert _resident_mb(sim) < before + 90.0, f"/sim grew from {before:.0f} MB to {_resident_mb(sim):.0f} MB"

        # A setting of the node carries over to the new scene.
        step = Parameter(name="gait.step_duration", value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=0.45))
        assert client.call(SetParameters, "/sim/set_parameters", SetParameters.Request(parameters=[step]),
                           timeout=WAIT_S).results[0].successful
        clock = client.record(Clock, "/clock", keep=10_000)
        client.wait_for(lambda: clock.count > 0 and clock.latest.clock.sec >= 2, WAIT_S, "2 s of sim time")

        answer = _load(client, "g1/tables")
        assert answer.result.result == Result.RESULT_OK and answer.world.name == "tables", answer.result
        assert _current(client) == "tables"
        loaded_at = clock.count
        client.wait_for(lambda: clock.count > loaded_at + 5, WAIT_S, "/clock of the new scene")
        assert min(m.clock.sec + m.clock.nanosec * 1e-9 for m in clock.messages()[loaded_at:]) < 1.0, "sim time from 0"
        entities = client.call(GetEntities, "/sim/get_entities", GetEntities.Request(), timeout=WAIT_S).entities
        assert {"g1", "box", "cube", "can"} <= set(entities), entities
        grid = client.record(OccupancyGrid, "/map", qos=LATCHED, keep=1)
        client.wait_for(lambda: grid.count > 0 and any(v > 50 for v in grid.latest.data), WAIT_S, "the tables on /map")
        step_now = client.call(GetParameters, "/sim/get_parameters", GetParameters.Request(names=["gait.step_duration", "scene"]),
                               timeout=WAIT_S).values
        assert step_now[0].double_value == pytest.approx(0.45) and step_now[1].string_value == "tables"
        for server in ("arm", "locomotion"):
            client.wait_for(lambda server=server: _scene_of(client, server) == "tables", WAIT_S, f"/{server} in the tables")

        sent = send(client, pick_place, _box_goal())
        assert sent.handle.accepted, "the tables scene has the box: the server validates on the scene /sim runs"
        client.wait_for(lambda: len(sent.feedback) > 0, WAIT_S, "the fetch's feedback")
        assert sent.cancel().goals_canceling
        outcome = result(client, sent, timeout=WAIT_S)
        assert outcome.status == GoalStatus.STATUS_CANCELED, outcome.result.error_msg
        assert process.alive(), process.output()
