"""Responsiveness of the action servers at real_time_factor 1 (figures for the closing note; not a test).

For each robot, ``bringup --robot R --rtf 1``; then, round after round, a goal of each action (G1:
Walk 1 m at 0.3 m/s, NavigateToPose 2 m ahead; Panda: MoveArm between two poses at velocity scaling
0.2, PickPlace of box_1): wall time from the goal's acceptance to its first feedback, and, once it is
under way, from the cancel request to the goal's terminal state. Walk and NavigateToPose end CANCELED
once the robot stands (the gait's closing step and settle, about 1 s of sim time); MoveArm and
PickPlace as soon as the arm holds. Prints each round and the medians.

Usage: ``make bench-response`` or ``.venv/bin/python benchmarks/response_bench.py [--rounds 5]``.
"""

from __future__ import annotations

import argparse
import os
import random
import statistics
import time
from collections.abc import Callable
from typing import Any

# A domain of this run's own, on this machine only: set before rclpy is imported.
os.environ.setdefault("ROS_DOMAIN_ID", str(1 + random.randrange(101)))  # 1..101: safe for Fast DDS ports
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"

# Imported once the ROS environment above is fixed.
from sim_client.actions import MoveArmClient, NavigateClient, PickPlaceClient, WalkClient
from sim_interfaces.action import MoveArm, NavigateToPose, PickPlace, Walk
from sim_interfaces.srv import Reset
from sim_ros.processes import running
from sim_ros.session import RosSession


def _move_goal(round_: int) -> MoveArm.Goal:
    goal = MoveArm.Goal(position_tolerance=0.001, orientation_tolerance=0.01, max_velocity_scaling=0.2)
    goal.target.header.frame_id = "world"
    p, o = goal.target.pose.position, goal.target.pose.orientation
    p.x, p.y, p.z = 0.5, 0.3 if round_ % 2 == 0 else -0.3, 0.3
    o.x, o.w = 1.0, 0.0  # the tool pointing down
    return goal


def _navigate_goal(_round: int) -> NavigateToPose.Goal:
    goal = NavigateToPose.Goal()
    goal.pose.header.frame_id = "world"
    goal.pose.pose.position.x, goal.pose.pose.orientation.w = 2.0, 1.0
    return goal


def _pick_goal(_round: int) -> PickPlace.Goal:
    goal = PickPlace.Goal(object_id="box_1")
    goal.place_pose.pose.position.x, goal.place_pose.pose.position.y = 0.45, -0.25
    return goal


def _reset(session: RosSession, client: Any) -> None:
    """Back to the keyframe between rounds (a navigation or a pick starts from the same state)."""
    session.wait_for(client.service_is_ready, 30.0, "/sim/reset")
    session.wait_future(client.call_async(Reset.Request()), 30.0, "the reset")


def _rounds(session: RosSession, client: Any, goal: Callable[[int], Any], under_way: Callable[[Any], bool],
            rounds: int, label: str, before: Callable[[], None] | None = None) -> tuple[list[float], list[float]]:
    first_ms: list[float] = []
    cancel_ms: list[float] = []
    for round_ in range(rounds):
        if before is not None:
            before()
        handle = client.send(goal(round_), timeout=30.0)
        accepted = time.monotonic()

        def fed(h: Any = handle) -> bool:
            return h.feedback is not None

        def going(h: Any = handle) -> bool:
            return h.feedback is not None and under_way(h.feedback)

        def ended(h: Any = handle) -> bool:
            return bool(h.done)

        session.wait_for(fed, 10.0, "the first feedback", poll=0.001)
        first_ms.append((time.monotonic() - accepted) * 1e3)
        session.wait_for(going, 30.0, "the goal under way")
        asked = time.monotonic()
        handle.cancel()
        session.wait_for(ended, 30.0, "the canceled goal to end", poll=0.001)
        cancel_ms.append((time.monotonic() - asked) * 1e3)
        outcome = handle.outcome()
        print(f"  {label} round {round_ + 1}: goal -> first feedback {first_ms[-1]:6.1f} ms   "
              f"cancel -> {outcome.status if outcome else '?'} {cancel_ms[-1]:7.1f} ms", flush=True)
    return first_ms, cancel_ms


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    options = parser.parse_args()
    figures = {}
    with RosSession("response_bench") as session:
        reset = session.node.create_client(Reset, "/sim/reset")
        with running(["bringup", "--robot", "g1", "--rtf", "1"]):
            walk, navigate = WalkClient(session), NavigateClient(session)
            walk.wait_for_server(120.0)
            navigate.wait_for_server(120.0)
            figures["Walk"] = _rounds(session, walk, lambda _r: Walk.Goal(distance=1.0, speed=0.3),
                                      lambda f: f.distance_walked > 0.15, options.rounds, "Walk")
            _reset(session, reset)
            figures["NavigateToPose"] = _rounds(session, navigate, _navigate_goal, lambda f: f.distance_remaining < 1.85,
                                                options.rounds, "NavigateToPose", lambda: _reset(session, reset))
        with running(["bringup", "--robot", "panda", "--rtf", "1"]):
            move, pick = MoveArmClient(session), PickPlaceClient(session)
            move.wait_for_server(120.0)
            pick.wait_for_server(120.0)
            figures["MoveArm"] = _rounds(session, move, _move_goal, lambda f: f.percent_complete > 10.0,
                                         options.rounds, "MoveArm")
            figures["PickPlace"] = _rounds(session, pick, _pick_goal, lambda f: f.stage >= PickPlace.Feedback.DESCEND,
                                           options.rounds, "PickPlace", lambda: _reset(session, reset))
    for action, (first_ms, cancel_ms) in figures.items():
        print(f"median {action}: goal -> first feedback {statistics.median(first_ms):.1f} ms (goal <= 50 ms), "
              f"worst {max(first_ms):.1f} ms; cancel -> terminal {statistics.median(cancel_ms):.0f} ms")


if __name__ == "__main__":
    main()
