"""What every server node of the project shares: sim time by default, the robot name from /sim,
and a small latest-message box that execute callbacks can wait on with a deadline."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Generic, TypeVar

import rclpy
from rcl_interfaces.srv import GetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter

MsgT = TypeVar("MsgT")
SIM_NODE = "sim"


def sim_time_overrides(args: list[str] | None) -> list[Parameter]:
    """``use_sim_time`` true unless the command line sets it (project convention: sim time everywhere)."""
    given = any("use_sim_time:=" in arg for arg in (args or []))
    return [] if given else [Parameter("use_sim_time", value=True)]


def robot_of_sim(node: Node, timeout_s: float = 30.0) -> str:
    """Ask ``/sim`` which robot it simulates (its read-only ``robot`` parameter).

    Call from ``main`` before spinning, never from a callback.

    Raises:
        RuntimeError: /sim did not answer within ``timeout_s``.
    """
    client = node.create_client(GetParameters, f"/{SIM_NODE}/get_parameters")
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    try:
        if not client.wait_for_service(timeout_sec=timeout_s):
            raise RuntimeError(f"/{SIM_NODE} is not running (no /{SIM_NODE}/get_parameters within {timeout_s:.0f} s); "
                               "start the sim node first or pass -p robot:=NAME")
        future = client.call_async(GetParameters.Request(names=["robot"]))
        executor.spin_until_future_complete(future, timeout_sec=timeout_s)
        if not future.done() or not future.result().values:
            raise RuntimeError(f"/{SIM_NODE} did not report its robot parameter")
        return str(future.result().values[0].string_value)
    finally:
        executor.remove_node(node)
        node.destroy_client(client)


class Latest(Generic[MsgT]):
    """The latest message of a topic (or per key), with a condition to wait for the next one."""

    def __init__(self, key: Callable[[MsgT], str] | None = None) -> None:
        self._key = key
        self._messages: dict[str, MsgT] = {}
        self._condition = threading.Condition()
        self._version = 0

    def put(self, msg: MsgT) -> None:
        with self._condition:
            self._messages[self._key(msg) if self._key else ""] = msg
            self._version += 1
            self._condition.notify_all()

    def get(self, key: str = "") -> MsgT | None:
        with self._condition:
            return self._messages.get(key)

    def clear(self) -> None:
        with self._condition:
            self._messages.clear()

    def wait_next(self, timeout_s: float) -> bool:
        """Block until a new message arrives or ``timeout_s`` wall seconds pass. True if one came."""
        with self._condition:
            version = self._version
            return self._condition.wait_for(lambda: self._version != version, timeout=timeout_s)
