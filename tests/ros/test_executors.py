"""The device nodes' executor: rclpy's events executor, spun so that a callback that raises does not end the node."""

from __future__ import annotations

import time

import rclpy
from rclpy.context import Context
from rclpy.node import Node

from nodes.runtime.executor import events_executor, spin_once_logging


def test_a_callback_that_raises_is_logged_and_the_events_executor_spins_on():
    context = Context()
    rclpy.init(context=context)
    node = Node("raising", context=context)
    calls: list[float] = []

    def tick() -> None:
        calls.append(time.monotonic())
        if len(calls) == 1:
            raise ValueError("a malformed request")

    node.create_timer(0.01, tick)
    executor = events_executor(context)
    executor.add_node(node)
    try:
        deadline = time.monotonic() + 30.0
        while len(calls) < 3 and time.monotonic() < deadline:
            spin_once_logging(executor, node, timeout_sec=0.05)
        assert len(calls) >= 3, "the timer ran again after its callback raised"
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
