"""Walk, /cmd_vel and live walking_speed on the G1 under physics, from a client in another process."""

from __future__ import annotations

import itertools
import math
import time

import pytest
from action_msgs.msg import GoalStatus
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from std_srvs.srv import Trigger

import robot_models
from sim_interfaces.action import NavigateToPose, Walk
from sim_interfaces.srv import Push, Reset, Step
from sim_ros.conversions import yaw_of
from sim_ros.stamps import seconds_of
from tests.ros.actions import action_client, ready_client, result, send, sim_now as sim_at, wait_feedback
from tests.ros.processes import running

pytestmark = pytest.mark.slow


def xy(odom: Odometry) -> tuple[float, float]:
    return odom.pose.pose.position.x, odom.pose.pose.position.y


def yaw(odom: Odometry) -> float:
    o = odom.pose.pose.orientation
    return yaw_of((o.w, o.x, o.y, o.z))


@pytest.fixture(scope="module")
def g1(client):
    with running(["bringup", "--robot", "g1", "--rtf", "2.0"]) as process:
        yield process


@pytest.fixture(scope="module")
def walk(client, g1):
    return ready_client(client, Walk, "/walk", timeout=90.0)


@pytest.fixture(scope="module", autouse=True)
def navigate_made(client, g1):
    """The navigation's client, made at the start and not waited for: one made at the end of this long module once
    waited a minute, on a loaded machine, for the server to match it; made early, its discovery overlaps the walks."""
    return action_client(client, NavigateToPose, "/navigate_to_pose")


@pytest.fixture()
def odom(client, g1):
    recorder = client.record(Odometry, "/odom", qos=1000, keep=100_000)  # deep: a starved reader loses nothing
    client.wait_for(lambda: recorder.count > 0, 30.0, "/odom")
    return recorder


def sim_now(client) -> float:
    return sim_at(client, "g1")


def caught_up(client, odom) -> float:
    """The sim's time now, once this client's /odom has reached it."""
    now = sim_now(client)
    client.wait_for(lambda: seconds_of(odom.latest.header.stamp) >= now, 60.0, f"/odom at t={now:.3f} s")
    return now


def reset(client, odom) -> float:
    """Reset the sim and wait until the odometry this process holds is from after the reset (a loaded machine can
    leave pre-reset messages in flight for a while); returns the sim time of the reset."""
    response = client.call(Reset, "/sim/reset", Reset.Request())
    assert response.success, response.message
    client.wait_for(lambda: seconds_of(odom.latest.header.stamp) > response.sim_time, 30.0, "odometry after the reset")
    return float(response.sim_time)


def pace(odom_messages: list[Odometry], t0: float, t1: float) -> float:
    """Mean forward speed [m/s] between sim times t0 and t1, from positions."""
    window = [m for m in odom_messages if t0 <= seconds_of(m.header.stamp) <= t1]
    assert len(window) >= 2 and seconds_of(window[-1].header.stamp) - seconds_of(window[0].header.stamp) > 0.8 * (t1 - t0), \
        f"/odom covers [{t0:.3f}, {t1:.3f}] s"
    first, last = window[0], window[-1]
    return math.dist(xy(first), xy(last)) / (seconds_of(last.header.stamp) - seconds_of(first.header.stamp))


def test_walk_two_metres_forward_then_half_a_metre_back(client, walk, odom):
    reset(client, odom)
    start = xy(odom.latest)
    sent = send(client, walk, Walk.Goal(distance=2.0, speed=0.3))
    assert sent.handle.accepted
    outcome = result(client, sent, timeout=180.0)
    assert outcome.status == GoalStatus.STATUS_SUCCEEDED, outcome.result.error_msg
    assert outcome.result.final_distance == pytest.approx(2.0, rel=0.05)
    caught_up(client, odom)
    moved = math.dist(start, xy(odom.latest))
    assert moved == pytest.approx(2.0, rel=0.05), "odometry agrees: the base moved 2 m"
    walked = [f.distance_walked for f in sent.feedback]
    assert walked[-1] > walked[0] + 1.5 and sent.feedback[-1].steps_taken >= 6
    assert odom.latest.pose.pose.position.z > 0.6, "still standing"

    back = result(client, send(client, walk, Walk.Goal(distance=-0.5)), timeout=120.0)
    assert back.result.error_code == Walk.Result.SUCCESS, back.result.error_msg
    assert back.result.final_distance == pytest.approx(-0.5, rel=0.05)


def test_a_paused_step_stops_where_the_walk_ends(client, walk, odom):
    """/sim/step with stop_at_goal_end returns at the publication stop after the goal ended, not after all its steps."""
    reset(client, odom)
    assert client.call(Trigger, "/sim/pause", Trigger.Request()).success
    try:
        sent = send(client, walk, Walk.Goal(distance=0.3, speed=0.3))
        assert sent.handle.accepted
        wait_feedback(client, sent, lambda _feedback: True, 60.0, "the walk to start in the paused sim")
        start = client.call(Step, "/sim/step", Step.Request(steps=1)).sim_time
        stepped = client.call(Step, "/sim/step", Step.Request(steps=5000, stop_at_goal_end=True), timeout=120.0)
        assert stepped.success and stepped.goals_ended == 1, stepped.message
        assert start + 0.5 < stepped.sim_time < start + 15.0, "stopped where the 0.3 m walk ended, not 20 s later"
        outcome = result(client, sent, timeout=60.0)
        assert outcome.status == GoalStatus.STATUS_SUCCEEDED, outcome.result.error_msg
        again = client.call(Step, "/sim/step", Step.Request(steps=50, stop_at_goal_end=True))
        assert again.goals_ended == 0 and again.sim_time == pytest.approx(stepped.sim_time + 50 * 0.004, abs=1e-9)
    finally:
        assert client.call(Trigger, "/sim/resume", Trigger.Request()).success


def test_walking_speed_changes_the_pace_mid_walk(client, walk, odom):
    reset(client, odom)
    assert client.set_parameter("locomotion", "walking_speed", 0.2)[0]
    try:
        sent = send(client, walk, Walk.Goal(distance=5.0))
        wait_feedback(client, sent, lambda f: seconds_of(f.elapsed) > 5.0, 120.0, "5 s of walking")
        before = caught_up(client, odom)  # at least 5 s into the walk
        slow = pace(odom.messages(), before - 2.5, before)
        ok, reason = client.set_parameter("locomotion", "walking_speed", 0.4)
        assert ok, reason
        # The change is in force once the parameter service has answered: the fast window is timed from the sim's
        # time read after that answer, so a slow client (a loaded machine) cannot move the change into the window.
        changed_at = sim_now(client)
        client.wait_for(lambda: seconds_of(odom.latest.header.stamp) > changed_at + 4.0, 120.0, "4 s after the change")
        fast = pace(odom.messages(), changed_at + 2.0, changed_at + 4.0)
        assert slow == pytest.approx(0.2, abs=0.05)
        assert fast == pytest.approx(0.4, abs=0.07), "within 2 s the pace follows the new walking_speed"
        sent.cancel()
        assert result(client, sent).status == GoalStatus.STATUS_CANCELED
    finally:
        client.set_parameter("locomotion", "walking_speed", 0.3)


def test_walking_speed_out_of_range_is_refused_with_the_range(client, g1):
    high = robot_models.load("g1").walking.speed_range_mps[1]
    ok, reason = client.set_parameter("locomotion", "walking_speed", 2.5)
    assert not ok and f"Max: {high}" in reason, reason
    ok, reason = client.set_parameter("locomotion", "walking_speed", -0.3)
    assert not ok and "0.05" in reason


def test_cmd_vel_turns_the_robot_in_place_by_ninety_degrees(client, odom, g1):
    reset(client, odom)
    caught_up(client, odom)
    # The steering reads the newest odometry only (a queue of one, as a controller subscribes): a deep queue would
    # hand a client that falls behind old headings, and it would stop turning late.
    fresh = client.record(Odometry, "/odom", qos=1, keep=1)
    client.wait_for(lambda: fresh.count > 0, 30.0, "/odom")
    publisher = client.node.create_publisher(Twist, "/cmd_vel", 10)
    start_yaw, start_xy = yaw(odom.latest), xy(odom.latest)
    command = Twist()
    turned = lambda: abs(math.remainder(yaw(fresh.latest) - start_yaw, 2 * math.pi))  # noqa: E731
    polled_at: list[float] = []
    try:
        def turning() -> bool:
            # Slow down as the heading approaches 90 degrees, as a client steering by odometry does. The gentle
            # gain (0.6 /s) keeps the heading within the tolerance even if this client is descheduled for up to
            # about 1 s of wall time on a loaded machine (the sim runs at 2x), during which its last command holds.
            polled_at.append(time.monotonic())
            remaining = math.radians(90) - turned()
            command.angular.z = min(0.5, max(0.08, 0.6 * remaining))
            publisher.publish(command)
            return remaining <= math.radians(2)

        client.wait_for(turning, 120.0, "a 90 degree turn", poll=0.05)
    finally:
        publisher.publish(Twist())
    stop_time = sim_now(client)
    longest_gap = max(b - a for a, b in itertools.pairwise(polled_at))

    def still() -> bool:
        publisher.publish(Twist())
        return seconds_of(odom.latest.header.stamp) > stop_time + 3.0

    client.wait_for(still, 60.0, "the robot to stop", poll=0.05)
    fresh.stop()
    turned = lambda: abs(math.remainder(yaw(odom.latest) - start_yaw, 2 * math.pi))  # noqa: E731
    assert turned() == pytest.approx(math.radians(90), abs=math.radians(10)), (
        f"heading after stopping; the steering client's longest gap between commands was {longest_gap:.2f} s wall"
    )
    assert math.dist(start_xy, xy(odom.latest)) < 0.25, "turned in place"
    assert odom.latest.pose.pose.position.z > 0.6
    client.node.destroy_publisher(publisher)


def test_cancel_stops_the_walk_and_the_robot_stands(client, walk, odom):
    reset(client, odom)
    sent = send(client, walk, Walk.Goal(distance=3.0, speed=0.3))
    wait_feedback(client, sent, lambda f: f.distance_walked > 0.4, 120.0, "the walk to be under way")
    sent.cancel()
    outcome = result(client, sent)
    assert outcome.status == GoalStatus.STATUS_CANCELED
    assert outcome.result.error_code == Walk.Result.CANCELED
    assert 0.4 < outcome.result.final_distance < 2.0
    t0 = sim_now(client)
    client.wait_for(lambda: seconds_of(odom.latest.header.stamp) > t0 + 2.0, 60.0, "2 s after the cancel")
    assert pace(odom.messages(), t0 + 1.0, t0 + 2.0) < 0.03, "standing still"
    assert odom.latest.pose.pose.position.z > 0.6


def test_a_new_walk_preempts_the_running_one(client, walk, odom):
    reset(client, odom)
    first = send(client, walk, Walk.Goal(distance=3.0, speed=0.3))
    wait_feedback(client, first, lambda f: f.distance_walked > 0.2, 120.0, "the first walk to be under way")
    second = send(client, walk, Walk.Goal(distance=0.5, speed=0.3))
    first_outcome = result(client, first)
    assert first_outcome.status == GoalStatus.STATUS_ABORTED
    assert first_outcome.result.error_code == Walk.Result.PREEMPTED
    second_outcome = result(client, second, timeout=120.0)
    assert second_outcome.result.error_code == Walk.Result.SUCCESS, second_outcome.result.error_msg


def push(client, force_y: float, duration: float = 0.5, body: str = "") -> Push.Response:
    request = Push.Request(body=body, duration=duration)
    request.wrench.force.y = force_y
    return client.call(Push, "/sim/push", request)


def test_a_shove_knocks_the_walking_robot_over_and_after_a_reset_it_walks_again(client, walk, odom):
    reset(client, odom)
    refused = push(client, 100.0, body="no_such_body")
    assert not refused.success and "pelvis" in refused.message, refused.message
    refused = push(client, 1e5)
    # bounded by what the robot's mass makes sane: 10 g on the G1's 34.4 kg
    assert not refused.success and "up to 3374 N" in refused.message, refused.message

    sent = send(client, walk, Walk.Goal(distance=3.0, speed=0.3))
    wait_feedback(client, sent, lambda f: f.distance_walked > 0.3, 120.0, "the walk under way")
    shove = push(client, 400.0)  # sideways at the pelvis for 0.5 s: no gait absorbs this
    assert shove.success and shove.end_time == pytest.approx(shove.sim_time + 0.5), shove.message
    fell = result(client, sent, timeout=120.0)
    assert fell.result.error_code == Walk.Result.FELL, fell.result.error_msg
    assert "fell" in fell.result.error_msg
    client.wait_for(lambda: odom.latest.pose.pose.position.z < 0.3, 60.0, "the robot down")
    assert odom.latest.pose.pose.position.z > 0.05, "it lies on the floor, not in it"
    down = result(client, send(client, walk, Walk.Goal(distance=0.5)), timeout=60.0)
    assert down.result.error_code == Walk.Result.FELL and "reset" in down.result.error_msg, down.result.error_msg

    reset(client, odom)
    start = xy(odom.latest)
    again = result(client, send(client, walk, Walk.Goal(distance=0.5, speed=0.3)), timeout=120.0)
    assert again.result.error_code == Walk.Result.SUCCESS, again.result.error_msg
    caught_up(client, odom)
    assert math.dist(start, xy(odom.latest)) == pytest.approx(0.5, rel=0.1)
    assert odom.latest.pose.pose.position.z > 0.6, "standing after the walk"


@pytest.mark.parametrize(
    "goal",
    [Walk.Goal(distance=math.nan), Walk.Goal(distance=1e6), Walk.Goal(distance=0.0), Walk.Goal(distance=1.0, speed=-0.2),
     Walk.Goal(distance=1.0, speed=5.0), Walk.Goal(distance=1.0, timeout=-1.0)],
    ids=["nan", "absurd-distance", "zero-distance", "negative-speed", "too-fast", "negative-timeout"],
)
def test_bad_walk_goals_are_rejected_and_the_node_survives(client, walk, g1, goal):
    assert not send(client, walk, goal).handle.accepted
    assert g1.alive() and walk.server_is_ready()


def test_bad_navigation_goals_are_rejected(client, g1, navigate_made):
    navigate = ready_client(client, NavigateToPose, "/navigate_to_pose", made=navigate_made)
    goal = NavigateToPose.Goal()
    goal.pose.pose.position.x = math.nan
    assert not send(client, navigate, goal).handle.accepted
    goal = NavigateToPose.Goal()
    goal.pose.header.frame_id = "mars"
    assert not send(client, navigate, goal).handle.accepted
