"""A multi-threaded executor that waits instead of spinning while its threads pick up work.

rclpy's ``MultiThreadedExecutor`` in the Jazzy wheels pinned here has a busy loop: a callback
handed to the thread pool stays "not executing" until a pool thread actually starts it, and in that
window the executor's own thread yields it again, resubmits it and rebuilds its wait set, over and
over. With the GIL, the pool thread it waits for is slow to get the interpreter, so every incoming
message costs spinning, and every thread busy in a long execute callback makes it spin without pause.

:class:`ServerExecutor` marks a handler as queued when it is submitted, so the executor goes back to
its wait set until the handler has run. Everything else is rclpy's own executor.
:func:`drop_qos_event_handlers` takes the other large cost of an idle node's wake-ups away. A callback
that raises is logged with its traceback and the node keeps serving (rclpy re-raises it out of
``spin()``, which would end the node: one malformed request would kill it).
"""

from __future__ import annotations

import threading
import traceback
from typing import Any, cast

import rclpy.logging
from rclpy.context import Context
from rclpy.event_handler import EventHandler
from rclpy.executors import (
    ConditionReachedException,
    Executor,
    ExternalShutdownException,
    MultiThreadedExecutor,
    ShutdownException,
    TimeoutException,
)
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.subscription import Subscription
from rclpy.task import Future, Task
from rosgraph_msgs.msg import Clock

_LOGGER = rclpy.logging.get_logger("executor")
_running = threading.local()  # the task a pool thread is running (for :func:`wait_parked`)


class _QueuedTask(Task):
    """A task that counts as executing from the moment it is handed to the thread pool.

    A coroutine task that awaits through :func:`wait_parked` is *parked* meanwhile: rclpy would
    hand it to a thread again on every turn of the executor (a busy loop for as long as it waits);
    parked, it is left alone until the future it waits for is done.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.queued = False
        self.parkable = False
        self._woken = False
        self._park_lock = threading.Lock()
        self._wake_executor: Any = kwargs.get("executor")

    def executing(self) -> bool:
        return self.queued or super().executing()

    def __call__(self) -> None:
        with self._park_lock:
            self.queued = False  # a coroutine that awaits is yielded again later, as rclpy intends
            self._woken = False
        _running.task = self
        try:
            super().__call__()
        finally:
            _running.task = None
        with self._park_lock:
            if self.parkable and not self._woken and not self.done():
                self.queued = True  # parked until wake()

    def wake(self) -> None:
        """The future a parked task waits for is done: let the executor run it again."""
        with self._park_lock:
            self._woken = True
            self.queued = False
        executor = self._wake_executor
        if executor is not None and executor._guard is not None:
            executor._guard.trigger()


async def wait_parked(future: Future) -> Any:
    """Await ``future`` from a coroutine callback without keeping the executor busy.

    Use it in ``async`` execute callbacks of :class:`ServerExecutor` nodes: the callback holds no
    thread while it waits (a server can have any number of goals waiting), and the executor sleeps
    until the future is done. Elsewhere it is a plain ``await``.
    """
    task = getattr(_running, "task", None)
    if isinstance(task, _QueuedTask) and not future.done():
        task.parkable = True
        future.add_done_callback(lambda _future: task.wake())
    try:
        return await future
    finally:
        if isinstance(task, _QueuedTask):
            task.parkable = False


class ServerExecutor(MultiThreadedExecutor):
    """``MultiThreadedExecutor`` without the busy loop: submitted handlers are not re-yielded."""

    def create_task(self, callback: Any, *args: Any, **kwargs: Any) -> Task:
        task = _QueuedTask(callback, args, kwargs, executor=self)
        with self._tasks_lock:
            self._tasks.append((task, None, None))
            self._guard.trigger()
        return task

    def _make_handler(self, entity: Any, node: Any, take_from_wait_list: Any) -> Task:
        """rclpy's handler coroutine for ``entity``, in a task that can be marked queued."""
        plain = super()._make_handler(entity, node, take_from_wait_list)
        task = _QueuedTask(plain._handler, executor=self)  # the coroutine rclpy made; ``plain`` is dropped
        plain._handler = None
        with self._tasks_lock:
            self._tasks = [(task if t is plain else t, e, n) for t, e, n in self._tasks]
        return task

    def _spin_once_impl(self, timeout_sec: Any = None, wait_condition: Any = lambda: False) -> None:
        """rclpy's own step (wait, submit one handler, collect finished ones), marking the handler queued.

        A ``/clock`` message is handled here, as the single-threaded executor does: rclpy's time source only sets
        the nodes' clocks, and handing that to a pool thread (a GIL hand-over at every message, 100 per second
        of sim time) made an idle server cost 1.4x a bare node on sim time.
        """
        try:
            handler: Any
            entity: Any
            handler, entity, _ = self.wait_for_ready_callbacks(timeout_sec, None, wait_condition)
        except (ExternalShutdownException, ShutdownException, TimeoutException, ConditionReachedException):
            return
        if isinstance(entity, Subscription) and entity.msg_type is Clock:
            handler()
            self._log_failure(handler)
            return
        if isinstance(handler, _QueuedTask):
            handler.queued = True
        self._executor.submit(handler)
        self._futures.append(handler)
        for future in self._futures[:]:
            if future.done():
                self._futures.remove(future)
                self._log_failure(future)

    @staticmethod
    def _log_failure(future: Future) -> None:
        """Log the exception of a finished handler (rclpy re-raises it out of spin(), and the node would end)."""
        error = future.exception()
        if error is not None:
            _LOGGER.error("a callback raised; the node keeps serving:\n" + "".join(traceback.format_exception(error)).rstrip())


def drop_qos_event_handlers(node: Node) -> int:
    """Take the QoS event handlers of the node's publishers and subscriptions out of its executor's wait set.

    rclpy gives every publisher and subscription default handlers that only log "incompatible QoS"
    and "incompatible type" warnings. Each is a Python waitable that rclpy's executor adds to and
    checks in its wait set on every wake-up, which multiplies what an idle node's wake-ups cost. The
    project's own publishers and subscriptions use matching QoS on both ends, so the warnings are
    given up; a QoS mismatch still shows as no data (``ros2 topic info -v`` lists both ends' QoS).
    Each entity's handler list is emptied too, so destroying the node later does not look for them.
    Returns how many handlers were dropped.
    """
    dropped = 0
    entities: list[Publisher | Subscription] = [*node.publishers, *node.subscriptions]
    for entity in entities:
        handlers = cast("list[EventHandler]", entity.event_handlers)  # a list (rclpy 7.1 annotates one handler)
        for handler in handlers:
            node.remove_waitable(handler)
            handler.destroy()
            dropped += 1
        entity.event_handlers = cast(EventHandler, [])
    return dropped


def events_executor(context: Context | None = None) -> Executor:
    """rclpy's C++ events executor (``rclpy.experimental``), for nodes with short callbacks and no actions.

    It takes each ready message from the middleware's events instead of rebuilding a wait set in Python on
    every wake-up. Measured on this machine, a node on sim time doing nothing but follow a 100 Hz /clock
    took 2.4% of a core on it against 5.4% on rclpy's SingleThreadedExecutor (20 s, the same publisher).
    """
    from rclpy.experimental import EventsExecutor  # imported here: rclpy's experimental package

    return EventsExecutor(context=context)


def spin_once_logging(executor: Executor, node: Node, timeout_sec: float = 0.2) -> None:
    """One ``spin_once``; a callback that raised is logged with its traceback and the node keeps serving.

    :class:`ServerExecutor` logs its handlers' exceptions itself; the events executor raises them out of
    ``spin_once``, which would end the node's spin loop: one malformed request would stop the node.
    """
    try:
        executor.spin_once(timeout_sec=timeout_sec)
    except (ExternalShutdownException, ShutdownException, KeyboardInterrupt):
        raise
    except Exception as error:  # noqa: BLE001 - any callback's: logged, and the node serves on
        node.get_logger().error("a callback raised; the node keeps serving:\n"
                                + "".join(traceback.format_exception(error)).rstrip())
