"""/sim/reset at random moments of every action: each goal gets a clean outcome, the servers keep serving.

A goal that was running when the sim was reset ends ABORTED with SIM_FAULT (the reset epoch in
/sim's state says so; nothing is guessed from motion); one that had already ended keeps its outcome;
one whose start reaches /sim after the reset runs from the reset state. None hangs, and a goal sent
afterwards succeeds.
"""

from __future__ import annotations

import random
from typing import Any

import pytest
from action_msgs.msg import GoalStatus

from sim_interfaces.action import MoveArm, NavigateToPose, PickPlace, Walk
from sim_interfaces.srv import Reset
from tests.ros.actions import ready_client, result, send
from tests.ros.processes import running

pytestmark = pytest.mark.slow
ROUNDS = 3


def _elapsed(feedback: Any) -> float:
    """Sim time [s] since the goal began, from whichever field the action's feedback names it."""
    duration = getattr(feedback, "elapsed", None) or feedback.navigation_time
    return duration.sec + duration.nanosec * 1e-9


def _reset_during(client: Any, action: Any, goal: Any, codes: Any, moments: list[float]) -> list[str]:
    """Send ``goal``, reset the sim ``moment`` s of sim time into it (0 = at once), check its end, per moment."""
    seen = []
    for moment in moments:
        assert client.call(Reset, "/sim/reset", Reset.Request()).success  # every round from the keyframe
        sent = send(client, action, goal)
        assert sent.handle.accepted
        if moment > 0.0:
            future = sent.result_future()

            def reached(m: float = moment, s: Any = sent, f: Any = future) -> bool:  # or the goal ended first
                return bool(f.done() or (s.feedback and _elapsed(s.feedback[-1]) >= m))

            client.wait_for(reached, 60.0, f"the goal {moment:.2f} s in")
        response = client.call(Reset, "/sim/reset", Reset.Request())
        assert response.success, response.message
        outcome = result(client, sent, timeout=90.0)
        status, code = outcome.status, outcome.result.error_code
        clean = (status == GoalStatus.STATUS_ABORTED and code == codes.SIM_FAULT) or \
            (status == GoalStatus.STATUS_SUCCEEDED and code == codes.SUCCESS)
        assert clean, f"reset {moment:.2f} s into the goal: status {status}, code {code}: {outcome.result.error_msg}"
        seen.append("reset" if code == codes.SIM_FAULT else "finished")
    return seen


def test_resets_during_walk_and_navigation_end_them_cleanly(client):
    moments = [0.0, *sorted(random.Random(11).uniform(0.2, 2.5) for _ in range(ROUNDS - 1))]
    with running(["bringup", "--robot", "g1", "--scene", "course", "--rtf", "2.0"]):
        walk = ready_client(client, Walk, "/walk", timeout=90.0)
        navigate = ready_client(client, NavigateToPose, "/navigate_to_pose", timeout=90.0)
        # Backward: the course's first obstacle stands 1.4 m ahead of the start.
        seen = _reset_during(client, walk, Walk.Goal(distance=-1.0, speed=0.3), Walk.Result, moments)
        assert "reset" in seen[1:], seen
        target = NavigateToPose.Goal()
        target.pose.header.frame_id = "world"
        target.pose.pose.position.x, target.pose.pose.orientation.w = 3.0, 1.0
        seen = _reset_during(client, navigate, target, NavigateToPose.Result, moments)
        assert "reset" in seen[1:], seen
        after = result(client, send(client, walk, Walk.Goal(distance=0.3, speed=0.3)))
        assert after.status == GoalStatus.STATUS_SUCCEEDED, after.result.error_msg


def test_resets_during_move_arm_and_pick_place_end_them_cleanly(client):
    moments = [0.0, *sorted(random.Random(12).uniform(0.1, 2.0) for _ in range(ROUNDS - 1))]
    with running(["bringup", "--robot", "panda", "--rtf", "2.0"]):
        move_arm = ready_client(client, MoveArm, "/move_arm")
        pick_place = ready_client(client, PickPlace, "/pick_place")
        move = MoveArm.Goal(position_tolerance=0.001, orientation_tolerance=0.01, max_velocity_scaling=0.2)
        move.target.header.frame_id = "world"
        move.target.pose.position.x, move.target.pose.position.y, move.target.pose.position.z = 0.5, 0.3, 0.3
        move.target.pose.orientation.x, move.target.pose.orientation.w = 1.0, 0.0  # the tool pointing down
        seen = _reset_during(client, move_arm, move, MoveArm.Result, moments)
        assert "reset" in seen[1:], seen
        pick = PickPlace.Goal(object_id="box_1")
        pick.place_pose.pose.position.x, pick.place_pose.pose.position.y = 0.45, -0.25
        seen = _reset_during(client, pick_place, pick, PickPlace.Result, moments)
        assert "reset" in seen[1:], seen
        after = result(client, send(client, move_arm, move))
        assert after.status == GoalStatus.STATUS_SUCCEEDED, after.result.error_msg
