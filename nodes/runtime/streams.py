"""Topics a node reads now and then: the latest message, and a subscription held only while it is needed."""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Iterator
from typing import Any, Generic, TypeVar

from rclpy.clock import Clock, ClockType
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node

MsgT = TypeVar("MsgT")


class Latest(Generic[MsgT]):
    """The latest message of a topic, with a condition to wait for the next one."""

    def __init__(self) -> None:
        self._message: MsgT | None = None
        self._condition = threading.Condition()
        self._version = 0

    def put(self, msg: MsgT) -> None:
        with self._condition:
            self._message = msg
            self._version += 1
            self._condition.notify_all()

    def get(self) -> MsgT | None:
        with self._condition:
            return self._message

    def clear(self) -> None:
        with self._condition:
            self._message = None

    def wait_next(self, timeout_s: float) -> bool:
        """Block until a new message arrives or ``timeout_s`` wall seconds pass. True if one came."""
        with self._condition:
            version = self._version
            return self._condition.wait_for(lambda: self._version != version, timeout=timeout_s)


class OnDemandTopic(Generic[MsgT]):
    """A topic subscribed only while something needs it: idle servers receive nothing they do not use.

    Every message a Python node receives costs an executor wake-up, and ``/sim`` publishes
    ``/joint_states`` at 200 Hz and its state topics at 30 Hz. A server that needs a stream only for a
    goal or a query holds it for that time (:meth:`held`) or asks for a fresh message (:meth:`fresh`);
    the subscription then stays for ``linger_s`` wall seconds after the last use, so a burst of goals
    or queries subscribes once. Messages never outlive the subscription: after it ends, nothing stale
    is handed out.
    """

    def __init__(self, node: Node, msg_type: Any, topic: str, qos: Any, callback_group: Any,
                 linger_s: float = 5.0) -> None:
        self.latest: Latest[MsgT] = Latest()
        self._node = node
        self._args = (msg_type, topic, self.latest.put, qos)
        self._group = callback_group
        self._linger_s = linger_s
        self._lock = threading.Lock()
        self._holders = 0
        self._last_use = 0.0
        self._subscription: Any = None
        self._timer: Any = None

    def _acquire(self) -> None:
        with self._lock:
            self._holders += 1
            if self._subscription is None:
                self.latest.clear()
                self._subscription = self._node.create_subscription(
                    *self._args, callback_group=self._group,
                    event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False))
                self._timer = self._node.create_timer(1.0, self._expire, callback_group=self._group,
                                                      clock=Clock(clock_type=ClockType.STEADY_TIME))

    def _release(self) -> None:
        with self._lock:
            self._holders -= 1
            self._last_use = time.monotonic()

    def _expire(self) -> None:
        """Unsubscribe once nobody holds the topic and ``linger_s`` passed since the last use."""
        with self._lock:
            if self._subscription is None or self._holders > 0 or time.monotonic() - self._last_use < self._linger_s:
                return
            self._node.destroy_subscription(self._subscription)
            self._node.destroy_timer(self._timer)
            self._subscription = self._timer = None
            self.latest.clear()

    @contextlib.contextmanager
    def held(self) -> Iterator[Latest[MsgT]]:
        """Subscribed for the duration of a ``with`` block (and ``linger_s`` after); yields the box."""
        self._acquire()
        try:
            yield self.latest
        finally:
            self._release()

    def fresh(self, timeout_s: float) -> MsgT | None:
        """The latest message since subscribing, waiting up to ``timeout_s`` wall seconds for one."""
        with self.held() as latest:
            deadline = time.monotonic() + timeout_s
            while (msg := latest.get()) is None and time.monotonic() < deadline:
                latest.wait_next(min(0.1, max(0.0, deadline - time.monotonic())))
            return msg
