"""A ROS session owned by a script: its own context, node and background executor."""

from __future__ import annotations

import faulthandler
import sys
import threading
import time
import traceback
from collections.abc import Callable
from typing import Any, Generic, TypeVar

import rclpy
from rcl_interfaces.msg import Parameter as ParameterMsg
from rclpy.context import Context
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import QoSProfile
from rclpy.serialization import deserialize_message
from rclpy.task import Future

MsgT = TypeVar("MsgT")

# A client's service readers keep this many responses (rclpy's default is 10). The responses of a
# server go to all of its clients, and each throws the others' away only as it reads them: with ten
# clients answered while this one was busy, a queue of 10 lost its own response (the soak benchmark).
RESPONSE_QOS = QoSProfile(depth=1000)
CLOSE_WAIT_S = 10.0  # [s of wall time] close() waits this long for the executor's callbacks and thread to end
RESEND_S = 5.0  # [s of wall time] a request that may be sent twice, unanswered this long, is sent again
# Services whose request may be sent twice (queries, and setting parameters to values): RosSession.call sends
# them again every RESEND_S until answered. A reset, a step or a state change is not (a lock-stepped scenario run
# sends its reset again, as /sim is paused then and a second reset restores the same state; a step carries an id).
SENT_AGAIN = frozenset({
    "GetParameters", "DescribeParameters", "ListParameters", "GetParameterTypes", "SetParameters",
    "SetParametersAtomically", "GetState", "GetAvailableStates", "GetAvailableTransitions", "GetEntityState",
    "GetEntities", "GetEntitiesStates", "GetEntityBounds", "GetEntityInfo", "GetSimulatorFeatures",
    "GetSimulationState", "GetSpawnables", "GetBatteryLevel", "ComputeIK",
})

T = TypeVar("T")


def quiet_events() -> SubscriptionEventCallbacks:
    """No QoS event handlers on a subscription: rclpy's defaults only log QoS mismatch warnings, and
    each is a Python waitable the executor rebuilds into its wait set on every wake-up (a recorder of
    ~20 topics had ~40 of them, and each lock-step chunk waits behind those wake-ups)."""
    return SubscriptionEventCallbacks(use_default_callbacks=False)

class WaitTimeout(TimeoutError):
    """A condition did not hold before its deadline; the message says which."""


class TopicRecorder(Generic[MsgT]):
    """Keeps the messages of one topic as they arrive (thread-safe), with their arrival count."""

    def __init__(self, keep: int = 100_000) -> None:
        self._lock = threading.Lock()
        self._messages: list[MsgT] = []
        self._keep = keep
        self.count = 0
        self._unsubscribe: Callable[[], Any] | None = None

    def _on_message(self, msg: MsgT) -> None:
        with self._lock:
            self._messages.append(msg)
            if len(self._messages) > self._keep:
                del self._messages[: len(self._messages) - self._keep]
            self.count += 1

    @property
    def latest(self) -> MsgT | None:
        with self._lock:
            return self._messages[-1] if self._messages else None

    def messages(self) -> list[MsgT]:
        with self._lock:
            return list(self._messages)

    def clear(self) -> None:
        with self._lock:
            self._messages.clear()

    def stop(self) -> None:
        """Unsubscribe (the messages kept so far stay readable)."""
        if self._unsubscribe is not None:
            self._unsubscribe()
            self._unsubscribe = None


class SerializedTopicRecorder(TopicRecorder[MsgT]):
    """A :class:`TopicRecorder` that keeps each message as its serialized bytes and deserializes it when read, once.

    Taking a message raw costs the executor a copy; deserializing a JointState of 43 joints costs more than the
    rest of its callback. A scenario run records /joint_states at 200 Hz of sim time and its measures may read
    none of them: those are never deserialized.
    """

    def __init__(self, msg_type: type[MsgT], keep: int = 100_000) -> None:
        super().__init__(keep)
        self._type = msg_type

    def _decoded(self, index: int) -> MsgT:  # under the lock
        entry: Any = self._messages[index]
        if isinstance(entry, bytes):
            entry = deserialize_message(entry, self._type)
            self._messages[index] = entry
        return entry

    @property
    def latest(self) -> MsgT | None:
        with self._lock:
            return self._decoded(-1) if self._messages else None

    def messages(self) -> list[MsgT]:
        with self._lock:
            return [self._decoded(i) for i in range(len(self._messages))]


class RosSession:
    """rclpy context + node + executor thread, closed with ``with`` or :meth:`close`.

    Args:
        name: node name of the client.
        use_sim_time: run the client's clock on /clock (the project default).
        namespace: the bring-up's namespace ("" = the root): relative names resolve under it, and sim time
            comes from its clock.
    """

    def __init__(self, name: str = "sim_client", use_sim_time: bool = True, namespace: str = "") -> None:
        self.context = Context()
        namespace = namespace.strip("/")
        # a namespaced bring-up has its own clock under the namespace; rclpy's time source reads /clock
        rclpy.init(context=self.context, args=["--ros-args", "-r", f"/clock:=/{namespace}/clock"] if namespace else None)
        self.namespace = f"/{namespace}" if namespace else ""
        self.node = Node(
            name,
            namespace=self.namespace or None,
            context=self.context,
            parameter_overrides=[Parameter("use_sim_time", value=use_sim_time)],
        )
        self._closing = False
        self.callback_faults = 0  # exceptions raised by callbacks on the spin thread (printed, then spun past)
        self._executor = SingleThreadedExecutor(context=self.context)
        self._executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, name=f"{name}-executor", daemon=True)
        self._thread.start()
        self._parameter_clients: dict[str, AsyncParameterClient] = {}
        self.recorders: list[TopicRecorder[Any]] = []  # every recorder made by :meth:`record`, in order
        self._service_clients: dict[tuple[Any, str], Any] = {}

    def _spin(self) -> None:
        """Run callbacks until the session closes; a callback that raises is reported and the spin goes on.

        ``executor.spin()`` ends at the first exception a callback raises, and every later request of
        the session then waits for a thread that is gone (a test module's later tests all timed out
        that way). rclpy also raises ``InvalidHandle`` on the spin thread when another thread destroys
        an entity the wait set holds. The exception is printed with its stack and counted in
        :attr:`callback_faults`.
        """
        while self.context.ok() and not self._closing:
            try:
                self._executor.spin()  # (spin_once with a timeout makes an rcl timer per wait: slower)
                return
            except ExternalShutdownException:
                return
            except Exception:  # noqa: BLE001 - any callback's exception: reported, and the spin goes on
                # A close whose executor shutdown outlived its timeout (a loaded machine) destroys the node
                # under a spin still running: the handles it then meets are gone, which is no error.
                if not self.context.ok() or self._closing:
                    return
                self.callback_faults += 1
                print(f"{self.node.get_name()}: a callback raised; the executor goes on:", file=sys.stderr)
                traceback.print_exc()

    def __enter__(self) -> RosSession:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Stop the executor, wait for its thread to end, then destroy the node and the context.

        The node is destroyed only once the spin thread has ended: destroyed under a spin still running
        (an executor shutdown outlives its timeout on a loaded machine), rclpy finishes destroying a
        handle the wait set still held on the spin thread, and that once hung the whole process.
        """
        self._closing = True
        self._executor.shutdown(timeout_sec=CLOSE_WAIT_S)
        self._thread.join(timeout=CLOSE_WAIT_S)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
        self._thread.join(timeout=CLOSE_WAIT_S)

    # ----- waiting -----------------------------------------------------------------------
    @staticmethod
    def wait_for(predicate: Callable[[], Any], timeout: float, what: str, poll: float = 0.01) -> Any:
        """Wait until ``predicate()`` is truthy and return its value.

        Raises:
            WaitTimeout: not true within ``timeout`` wall seconds; the message names ``what``.
        """
        deadline = time.monotonic() + timeout
        event = threading.Event()
        while True:
            value = predicate()
            if value:
                return value
            if time.monotonic() > deadline:
                raise WaitTimeout(f"timed out after {timeout:.1f} s waiting for {what}")
            event.wait(poll)

    @staticmethod
    def wait_future(future: Future, timeout: float, what: str) -> Any:
        """The result of ``future``, woken the moment it completes (no polling: a lock-stepped run
        waits for one /sim/step response per chunk of sim time, and a 10 ms poll cost more wall time
        than the physics of the chunk).

        Raises:
            WaitTimeout: not done within ``timeout`` wall seconds; the message names ``what``.
        """
        done = threading.Event()
        future.add_done_callback(lambda _future: done.set())
        if not done.wait(timeout) and not future.done():
            raise WaitTimeout(f"timed out after {timeout:.1f} s waiting for {what}")
        return future.result()

    def in_executor(self, function: Callable[[], T], timeout: float = 10.0, what: str = "the executor") -> T:
        """Run ``function`` on the executor's thread and return what it returns.

        rclpy's ActionClient (Jazzy) sends a goal, result or cancel request and only then records
        the request's sequence number, without a lock; when its response is handled on the
        executor thread in between, it is dropped as "unexpected" and the future never completes.
        Sending from the executor's own (single) thread closes that window. Never call this from
        inside an executor callback.
        """
        task = self._executor.create_task(function)
        try:
            return self.wait_future(task, timeout, f"{what} to run the request")
        except WaitTimeout:
            # the spin thread is stuck somewhere: say where (pytest shows stderr with the failure)
            print(f"{self.node.get_name()}: the executor did not run a request in {timeout:.1f} s; every thread:",
                  file=sys.stderr, flush=True)
            faulthandler.dump_traceback(file=sys.stderr, all_threads=True)
            raise

    # ----- topics and services -----------------------------------------------------------
    def record(self, msg_type: type[MsgT], topic: str, qos: QoSProfile | int = 10, keep: int = 100_000,
               serialized: bool = False) -> TopicRecorder[MsgT]:
        """Keep the messages of ``topic`` as they arrive; ``serialized``: as bytes, deserialized when read
        (:class:`SerializedTopicRecorder`, for streams that may never be read)."""
        recorder: TopicRecorder[MsgT] = SerializedTopicRecorder(msg_type, keep) if serialized else TopicRecorder(keep)
        subscription = self.node.create_subscription(msg_type, topic, recorder._on_message, qos,
                                                     event_callbacks=quiet_events(), raw=serialized)
        recorder._unsubscribe = lambda: self.destroy_subscription(subscription)
        self.recorders.append(recorder)
        return recorder

    def destroy_subscription(self, subscription: Any) -> None:
        """Destroy a subscription on the spin thread (destroyed from another thread while the executor
        waits on it, rclpy raises ``InvalidHandle`` there); directly once the spin has ended."""
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self.in_executor(lambda: self.node.destroy_subscription(subscription), what="unsubscribing")
        else:
            self.node.destroy_subscription(subscription)

    def service_client(self, srv_type: Any, name: str) -> Any:
        """This session's client of service ``name``, made on first use and kept: a client made anew must be
        found by the server again before its first answer can come back."""
        key = (srv_type, name)
        if key not in self._service_clients:
            self._service_clients[key] = self.node.create_client(srv_type, name, qos_profile=RESPONSE_QOS)
        return self._service_clients[key]

    def call(self, srv_type: Any, name: str, request: Any, timeout: float = 10.0,
             resend_every_s: float | None = None) -> Any:
        """Call a service and return its response (waits for the service first).

        Clients are kept per service: a client created just before its call can lose the
        response (the server's reply side may not have matched it yet), and discovery per call
        costs time. For the same reason the first call to a server that has just started can lose
        its response; a request without side effects (a query) can be sent again every
        ``resend_every_s`` wall seconds until one is answered. The types of :data:`SENT_AGAIN` are by default.

        Raises:
            WaitTimeout: the service did not appear, or no response came, within ``timeout`` wall seconds.
        """
        if resend_every_s is None and getattr(srv_type, "__name__", "") in SENT_AGAIN:
            resend_every_s = RESEND_S
        client = self.service_client(srv_type, name)
        self.wait_for(client.service_is_ready, timeout, f"service {name}")
        if resend_every_s is None:
            return self.wait_future(client.call_async(request), timeout, f"response of {name}")
        return self.until_answered(lambda: client.call_async(request), timeout, f"response of {name}",
                                    every_s=resend_every_s, forget=client.remove_pending_request)

    def parameters(self, node_name: str) -> AsyncParameterClient:
        """Client of a node's standard parameter services (what ``ros2 param`` calls)."""
        if node_name not in self._parameter_clients:
            self._parameter_clients[node_name] = AsyncParameterClient(self.node, node_name, qos_profile=RESPONSE_QOS)
        return self._parameter_clients[node_name]

    def set_parameter(self, node_name: str, name: str, value: Any, timeout: float = 10.0) -> tuple[bool, str]:
        """Set one parameter through ``/<node>/set_parameters``. Returns (successful, reason)."""
        client = self.parameters(node_name)
        self.wait_for(lambda: client.services_are_ready(), timeout, f"parameter services of {node_name}")
        response = self.until_answered(lambda: client.set_parameters([Parameter(name, value=value)]), timeout,
                                        f"set {node_name} {name}")
        result = response.results[0]
        return bool(result.successful), str(result.reason)

    def get_parameter(self, node_name: str, name: str, timeout: float = 10.0) -> Any:
        client = self.parameters(node_name)
        self.wait_for(lambda: client.services_are_ready(), timeout, f"parameter services of {node_name}")
        response = self.until_answered(lambda: client.get_parameters([name]), timeout, f"get {node_name} {name}")
        if not response.values:
            raise KeyError(f"{node_name} has no parameter {name!r}")
        return Parameter.from_parameter_msg(ParameterMsg(name=name, value=response.values[0])).value

    def until_answered(self, send: Callable[[], Future], timeout: float, what: str, every_s: float = RESEND_S,
                        forget: Callable[[Future], Any] | None = None) -> Any:
        """Send a request that may be sent twice (a query, setting a value, or one whose id the server answers
        once: /sim/step's) every ``every_s`` wall seconds
        until one is answered: a node that has just started can lose the response to a first request while
        its side of discovery catches up (seen: 90 s without an answer). ``forget`` drops an unanswered one.

        Raises:
            WaitTimeout: no answer within ``timeout`` wall seconds.
        """
        deadline = time.monotonic() + timeout
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                raise WaitTimeout(f"timed out after {timeout:.1f} s waiting for {what}")
            future = send()
            try:
                return self.wait_future(future, min(every_s, remaining), what)
            except WaitTimeout:
                if forget is not None:
                    forget(future)
