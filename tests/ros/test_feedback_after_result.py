"""A goal's feedback that reaches the client after the goal's result is kept, as the server sent it.

rclpy's ActionClient forgets a goal's feedback callback once the result is in, and takes one feedback message
per pass of its executor: a burst of feedback queued behind a result was dropped. A lock-stepped walk on a
loaded machine lost its last two feedback messages so (CI, stop 32). Here a server in another context
publishes a burst of feedback and ends the goal at once; the client's history has every message, in order.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator

import pytest
import rclpy
from rclpy.action import ActionServer
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from sim_client import RosSession
from sim_client.actions import WalkClient
from sim_interfaces.action import Walk
from sim_ros.names import FEEDBACK_QOS

BURST = 60  # feedback messages published just before the result (below FEEDBACK_QOS's depth of 100)
WAIT_S = 30.0  # [s] wall: a deadline for what must happen (never reached when it works)
ACTION = "/burst_walk"


@pytest.fixture
def burst_server() -> Iterator[None]:
    """A Walk server, in a context and executor of its own, whose goal publishes BURST feedbacks and succeeds."""
    context = rclpy.Context()
    rclpy.init(context=context)
    node = Node("burst_server", context=context)

    def execute(goal_handle):
        for k in range(BURST):
            feedback = Walk.Feedback()
            feedback.distance_walked = float(k)
            goal_handle.publish_feedback(feedback)
        goal_handle.succeed()
        return Walk.Result()

    server = ActionServer(node, Walk, ACTION, execute, feedback_pub_qos_profile=FEEDBACK_QOS)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    thread = threading.Thread(target=executor.spin, daemon=True)
    thread.start()
    yield
    executor.shutdown()
    thread.join(WAIT_S)
    server.destroy()
    node.destroy_node()
    rclpy.try_shutdown(context=context)


def test_every_feedback_of_a_goal_reaches_its_handle_even_after_the_result(burst_server):
    with RosSession("burst_client", use_sim_time=False) as session:
        walk = WalkClient(session, ACTION)
        for _ in range(3):
            handle = walk.send(WalkClient.goal(distance=1.0), timeout=WAIT_S)
            assert handle.wait(WAIT_S).status == "SUCCEEDED"
            session.wait_for(lambda h=handle: len(h.feedback_history) >= BURST, WAIT_S,
                             f"{BURST} feedback messages (have {len(handle.feedback_history)})")
            assert [s.feedback.distance_walked for s in handle.feedback_history] == [float(k) for k in range(BURST)]
        walk.destroy()
