"""The fetch benchmark's layouts through ROS: one ``bringup --robot g1 --scene tables`` (as fast as possible), and for
each layout a reset (``/sim/reset_simulation``), the objects put in place through ``/sim/set_entity_state`` and one
PickPlace goal from a plain client, as a user's program would send it. Used by ``fetch_bench.py --ros N``.
"""

from __future__ import annotations

import math
import os
import random
import time
from collections.abc import Iterable, Iterator

# A domain of this run's own, on this machine only: set before rclpy is imported.
os.environ.setdefault("ROS_DOMAIN_ID", str(1 + random.randrange(101)))  # 1..101: safe for Fast DDS ports
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"

from fetch_bench import OUT_OF_THE_WAY, Layout, Outcome

from robot_models import g1_tables
from sim_client import RosSession
from sim_client.actions import PickPlaceClient
from sim_ros.processes import running
from simulation_interfaces.msg import Result
from simulation_interfaces.srv import GetEntityState, ResetSimulation, SetEntityState

SERVICE_WALL_S = 60.0  # [s of wall time] for a service answer
FETCH_WALL_S = 900.0  # [s of wall time] for one fetch (about 60 s of sim time)
BRINGUP = ["bringup", "--robot", "g1", "--scene", "tables", "--rtf", "0"]


def _put(session: RosSession, name: str, x: float, y: float, z: float, yaw: float = 0.0) -> None:
    state = session.call(GetEntityState, "/sim/get_entity_state", GetEntityState.Request(entity=name),
                         timeout=SERVICE_WALL_S).state
    p, o = state.pose.position, state.pose.orientation
    p.x, p.y, p.z = x, y, z
    o.w, o.x, o.y, o.z = math.cos(yaw / 2.0), 0.0, 0.0, math.sin(yaw / 2.0)
    request = SetEntityState.Request(entity=name, state=state, set_pose=True)
    answer = session.call(SetEntityState, "/sim/set_entity_state", request, timeout=SERVICE_WALL_S).result
    if answer.result != Result.RESULT_OK:
        raise RuntimeError(f"/sim/set_entity_state {name}: {answer.error_message}")


def _xy(session: RosSession, name: str) -> tuple[float, float]:
    request = GetEntityState.Request(entity=name)
    p = session.call(GetEntityState, "/sim/get_entity_state", request, timeout=SERVICE_WALL_S).state.pose.position
    return p.x, p.y


def fetch_through_ros(layouts: Iterable[Layout]) -> Iterator[Outcome]:
    """Each layout's fetch through ROS, one after another on one bring-up (see the module)."""
    top = g1_tables.TABLE_TOP_Z_M
    with running(BRINGUP), RosSession("fetch_bench") as session:
        client = PickPlaceClient(session)
        client.wait_for_server(timeout=120.0)
        for layout in layouts:
            reset = session.call(ResetSimulation, "/sim/reset_simulation",
                                 ResetSimulation.Request(scope=ResetSimulation.Request.SCOPE_ALL), timeout=SERVICE_WALL_S)
            if reset.result.result != Result.RESULT_OK:
                raise RuntimeError(f"/sim/reset_simulation: {reset.result.error_message}")
            # The others out of the way first: the physics runs between the calls, and the object put where another
            # still stood at its reset spot (the box on the cube's or the can's) threw both off the table.
            for item in sorted(g1_tables.OBJECTS, key=lambda o: o.name == layout.object_name):
                if item.name == layout.object_name:
                    _put(session, item.name, *layout.object_xy, top + item.half_size[2] + 0.001, layout.object_yaw)
                else:
                    _put(session, item.name, *OUT_OF_THE_WAY[item.name], top + item.half_size[2] + 0.001)
            wall0, sim0 = time.perf_counter(), client.sim_now()
            handle = client.send(PickPlaceClient.goal(layout.object_name, (*layout.place_xy, top)))
            outcome = handle.wait(FETCH_WALL_S)
            wall, sim = time.perf_counter() - wall0, client.sim_now() - sim0
            code = "SUCCESS" if outcome.succeeded else (outcome.error_name or outcome.status)
            error = math.dist(_xy(session, layout.object_name), layout.place_xy)
            yield Outcome(layout, code, outcome.error_msg, error, code == "FELL", sim, wall)
