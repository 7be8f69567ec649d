"""Small helpers for action tests: send a goal, collect feedback, wait for the result."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from rclpy.action import ActionClient

from sim_client import RosSession


@dataclass
class Sent:
    """A goal in flight: its handle, the feedback received so far."""

    handle: Any
    feedback: list = field(default_factory=list)


def send(session: RosSession, client: ActionClient, goal: Any, timeout: float = 30.0) -> Sent:
    sent = Sent(handle=None)
    future = client.send_goal_async(goal, feedback_callback=lambda msg: sent.feedback.append(msg.feedback))
    sent.handle = session.wait_future(future, timeout, "goal acceptance")
    return sent


def result(session: RosSession, sent: Sent, timeout: float = 120.0) -> Any:
    """The wrapped result (``.status``, ``.result``)."""
    return session.wait_future(sent.handle.get_result_async(), timeout, "the action result")


def ready_client(session: RosSession, action_type: Any, name: str, timeout: float = 60.0) -> ActionClient:
    client = ActionClient(session.node, action_type, name)
    session.wait_for(client.server_is_ready, timeout, f"action server {name}")
    return client
