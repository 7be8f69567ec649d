"""/goal_markers and /plan: published when a goal starts or ends, and for changes of what it shows at most every
``CHANGE_PERIOD_S`` of sim time (a walk re-plans its footsteps every step)."""

from __future__ import annotations

import time

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from visualization_msgs.msg import MarkerArray

from nodes.sim.goal_visuals import CHANGE_PERIOD_S, GoalVisualsPublisher
from sim_bridge.skills import GoalVisuals, SkillRun, SkillStatus
from sim_ros.names import GOAL_MARKERS_TOPIC, LATCHED

CONTROL_DT_S = 0.004
DEADLINE_S = 30.0


class Replanning:
    """A skill whose footsteps move on at every read (as a walk's do)."""

    name = "walk"
    resource = "legs"

    def __init__(self) -> None:
        self.reads = 0

    def visuals(self) -> GoalVisuals:
        self.reads += 1
        return GoalVisuals(goal_pose=(2.0, 0.0, 0.0), footsteps=((0.01 * self.reads, 0.1, 0.0),))


def test_changes_are_published_at_most_every_period_and_a_goal_end_at_once():
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = Node("goal_visuals_test", context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        latest: list[MarkerArray] = []
        node.create_subscription(MarkerArray, GOAL_MARKERS_TOPIC, latest.append, LATCHED)
        publisher = GoalVisualsPublisher(node)
        sent: list[MarkerArray] = []  # every publication, as it is made (a latched reader keeps only the last)
        markers_pub = publisher._markers_pub
        publish = markers_pub.publish
        markers_pub.publish = lambda msg: (sent.append(msg), publish(msg))[1]  # type: ignore[method-assign]
        skill = Replanning()
        run = SkillRun(1, skill, "walk", "legs", 0, 0.0)  # type: ignore[arg-type]

        steps = round(1.0 / CONTROL_DT_S)  # one second of sim time, a control step at a time
        for k in range(steps):
            publisher.update([run], k * CONTROL_DT_S)
        run.status = SkillStatus.SUCCEEDED
        publisher.update([run], steps * CONTROL_DT_S)  # the goal ended: cleared at once

        expected = round(1.0 / CHANGE_PERIOD_S)  # at the start, then once per period (each time changed); then the end
        assert skill.reads == expected, "the visuals are read at the start and once per period"
        assert [len(m.markers) for m in sent] == [3] * expected + [1]  # clear, the arrow, the footsteps; then clear
        assert sent[-1].markers[0].action == sent[-1].markers[0].DELETEALL
        deadline = time.monotonic() + DEADLINE_S
        while not (latest and len(latest[-1].markers) == 1) and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.1)
        assert latest and len(latest[-1].markers) == 1, "a viewer sees the markers cleared"
    finally:
        rclpy.shutdown(context=context)
