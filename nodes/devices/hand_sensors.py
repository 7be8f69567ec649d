"""The ``/hand_sensors`` node: the wrist force/torque sensors' calibration, ``/calibrate_hand_sensors``.

``/sim`` reads each wrist sensor as a real F/T sensor reads (the true wrench plus a seeded offset, a slow
drift and noise) and publishes ``raw - offset`` as ``geometry_msgs/WrenchStamped`` in the sensor's frame on
``/<wrist>/wrench`` while anyone subscribes (the offset is zero until calibrated), as it publishes the
soles'. This node owns the offset, as a device driver owns its settings: ``/calibrate_hand_sensors``
averages every sensor's raw reading (``/sim/hand_sensors``, with how fast the hand moves and whether it
touches anything) at rest over a window of sim time, sends the average to ``/sim`` (latched, so a ``/sim``
that starts again takes it), and answers once ``/sim`` subtracts it: afterwards a hand at rest reads ~0,
and a load it holds reads as its weight. It is refused, with the reason, while a hand moves or touches
something. (Until 28 November this node republished every reading itself: a recorded G1 run spent
~1.2 CPU-s in its Python executor doing so.)
"""

from __future__ import annotations

import sys
import threading
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from geometry_msgs.msg import Wrench
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.task import Future

import robot_models
from nodes.runtime.executor import wait_parked
from nodes.runtime.parameters import ParameterSpec, declare
from nodes.runtime.serve import spin_server
from sim_interfaces.msg import HandSensors
from sim_interfaces.srv import CalibrateHandSensors
from sim_ros.names import HAND_OFFSETS_APPLIED_TOPIC, HAND_OFFSETS_TOPIC, HAND_SENSORS_TOPIC, LATCHED, wrench_topic
from sim_ros.stamps import seconds_of

NODE_NAME = "hand_sensors"
NO_DATA_TIMEOUT_S = 10.0  # wall seconds a calibration waits for /sim's readings to cover its window

PARAMETERS = (
    ParameterSpec("calibration_window", 0.5, "sim time each sensor is averaged over by /calibrate_hand_sensors [s]",
                  0.05, 5.0),
    ParameterSpec("rest_linear_speed", 0.02, "a hand faster than this [m/s] moves: calibration is refused", 0.001, 1.0),
    ParameterSpec("rest_angular_speed", 0.1, "a hand turning faster than this [rad/s] moves: calibration is refused",
                  0.001, 5.0),
)


def _vector(wrench: Wrench) -> np.ndarray:
    return np.array([wrench.force.x, wrench.force.y, wrench.force.z, wrench.torque.x, wrench.torque.y, wrench.torque.z])


def _set(msg: Wrench, values: np.ndarray) -> None:
    v = values.tolist()
    msg.force.x, msg.force.y, msg.force.z, msg.torque.x, msg.torque.y, msg.torque.z = v


@dataclass
class _Calibration:
    """A calibration in progress: samples over a window of sim time, or the reason it failed."""

    window_s: float
    start: float | None = None
    samples: list[np.ndarray] = field(default_factory=list)
    done: Future = field(default_factory=Future)


class HandSensorsNode(Node):
    """Calibrates the wrist force/torque sensors of the robot of ``/sim`` (which publishes them, less the offsets)."""

    def __init__(self, robot: str, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        wrists = robot_models.sensors_of(robot).wrists
        if not wrists:
            raise robot_models.RobotModelError(f"robot {robot!r} has no wrist force/torque sensors")
        declare(self, (ParameterSpec("robot", robot, "robot whose wrist sensors are served", read_only=True), *PARAMETERS))
        self._names = [wrist.name for wrist in wrists]
        self._offsets = np.zeros((len(wrists), 6))
        self._lock = threading.Lock()
        self._calibration: _Calibration | None = None
        self._frames = [wrist.frame for wrist in wrists]
        self._group = ReentrantCallbackGroup()
        self._readings: Any = None  # the subscription to /sim's raw readings, while a calibration runs
        # The offsets to /sim (latched), and /sim's word that it subtracts them.
        self._offsets_pub = self.create_publisher(HandSensors, HAND_OFFSETS_TOPIC, LATCHED)
        self._applied: tuple[np.ndarray, Future] | None = None  # offsets sent, done once /sim applies them
        self.create_subscription(HandSensors, HAND_OFFSETS_APPLIED_TOPIC, self._on_applied, LATCHED,
                                 callback_group=self._group)
        self._send_offsets(self._offsets)
        self.create_service(CalibrateHandSensors, "calibrate_hand_sensors", self._on_calibrate, callback_group=self._group)
        self.get_logger().info(f"calibrating {', '.join(wrench_topic(n) for n in self._names)} (/sim publishes them): "
                               "/calibrate_hand_sensors")

    def _param(self, name: str) -> float:
        return float(self.get_parameter(name).value)

    def _subscribe(self, wanted: bool) -> None:
        """/sim builds the raw readings only while someone subscribes: this node does only while it calibrates."""
        with self._lock:
            if wanted and self._readings is None:
                self._readings = self.create_subscription(HandSensors, HAND_SENSORS_TOPIC, self._on_readings,
                                                          QoSProfile(depth=10), callback_group=self._group)
            elif not wanted and self._readings is not None:
                self.destroy_subscription(self._readings)
                self._readings = None

    def _send_offsets(self, offsets: np.ndarray) -> Future:
        """Publish ``offsets`` (one row of 6 per sensor) to /sim; the future is done once /sim echoes them."""
        msg = HandSensors(names=list(self._names), frame_ids=list(self._frames), wrenches=[Wrench() for _ in self._names])
        for out, values in zip(msg.wrenches, offsets, strict=True):
            _set(out, values)
        done = Future()
        with self._lock:
            self._applied = (np.array(offsets, dtype=float), done)
        self._offsets_pub.publish(msg)
        return done

    def _on_applied(self, msg: HandSensors) -> None:
        if list(msg.names) != self._names:
            return  # another robot's sensors
        echoed = np.array([_vector(w) for w in msg.wrenches])
        with self._lock:
            if self._applied is not None and np.array_equal(echoed, self._applied[0]) and not self._applied[1].done():
                self._applied[1].set_result(True)

    def _on_readings(self, msg: HandSensors) -> None:
        if list(msg.names) != self._names:
            return  # another robot's sensors: not ours
        with self._lock:
            calibration = self._calibration
        if calibration is not None and not calibration.done.done():
            self._sample(calibration, msg, np.array([_vector(w) for w in msg.wrenches]))

    def _sample(self, calibration: _Calibration, msg: HandSensors, raw: np.ndarray) -> None:
        linear, angular = self._param("rest_linear_speed"), self._param("rest_angular_speed")
        for i, name in enumerate(self._names):
            if msg.in_contact[i]:
                self._finish(calibration, f"the {name} hand touches something; free it and calibrate again")
                return
            if msg.linear_speeds[i] > linear or msg.angular_speeds[i] > angular:
                self._finish(
                    calibration, f"the {name} hand moves ({msg.linear_speeds[i]:.3f} m/s, {msg.angular_speeds[i]:.3f} rad/s; "
                    f"at rest: below {linear:g} m/s and {angular:g} rad/s); hold it still and calibrate again")
                return
        now = seconds_of(msg.header.stamp)
        if calibration.start is None:
            calibration.start = now
        calibration.samples.append(raw)
        if now - calibration.start >= calibration.window_s - 1e-9:
            self._finish(calibration, "")

    def _finish(self, calibration: _Calibration, reason: str) -> None:
        """End a calibration once ("" = the window is full), whichever thread gets there first."""
        with self._lock:
            if calibration.done.done():
                return
            calibration.done.set_result(reason)

    async def _on_calibrate(self, request: CalibrateHandSensors.Request,
                            response: CalibrateHandSensors.Response) -> CalibrateHandSensors.Response:
        window = request.window or self._param("calibration_window")
        if not 0.05 <= window <= 5.0:
            response.message = f"window must be in [0.05, 5] s of sim time (0 = calibration_window), got {window}"
            return response
        calibration = _Calibration(window)
        with self._lock:
            if self._calibration is not None and not self._calibration.done.done():
                response.message = "a calibration is already running; try again when it has answered"
                return response
            self._calibration = calibration
        self._subscribe(True)

        def give_up() -> None:
            self._finish(calibration, f"no readings from /sim on {HAND_SENSORS_TOPIC} covering {window:g} s of sim "
                                            f"time within {NO_DATA_TIMEOUT_S:g} s; is /sim running (and not paused)?")

        timer = self.create_timer(NO_DATA_TIMEOUT_S, give_up, clock=Clock(clock_type=ClockType.STEADY_TIME))
        try:
            reason = await wait_parked(calibration.done)
        finally:
            self.destroy_timer(timer)
            self._subscribe(False)
        if reason:
            response.message = f"not calibrated: {reason}"
            return response
        offsets = np.mean(calibration.samples, axis=0)
        with self._lock:
            self._offsets = offsets
        # Answered once /sim subtracts the new offsets: no wrench published after the answer has the old ones.
        applied = self._send_offsets(offsets)
        timer = self.create_timer(NO_DATA_TIMEOUT_S, lambda: applied.done() or applied.set_result(False),
                                  clock=Clock(clock_type=ClockType.STEADY_TIME))
        try:
            taken = await wait_parked(applied)
        finally:
            self.destroy_timer(timer)
        if not taken:
            response.message = (f"not calibrated: /sim did not take the offsets within {NO_DATA_TIMEOUT_S:g} s (they are "
                                "sent latched: a /sim that starts takes them)")
            return response
        response.success = True
        response.names = list(self._names)
        response.offsets = [Wrench() for _ in self._names]
        for out, values in zip(response.offsets, offsets, strict=True):
            _set(out, values)
        described = (f"{name} offset force {np.round(v[:3], 3).tolist()} N, torque {np.round(v[3:], 4).tolist()} N m"
                     for name, v in zip(self._names, offsets, strict=True))
        response.message = f"calibrated over {len(calibration.samples)} readings in {window:g} s: " + "; ".join(described)
        self.get_logger().info(response.message)
        return response


def main(args: list[str] | None = None) -> int:
    """Console entry point: ``hand_sensors`` (asks /sim for its robot)."""
    # On ServerExecutor, not the events executor: /calibrate_hand_sensors awaits readings (an async callback
    # that subscribes while it runs), which rclpy 7.1.6's events executor never resumed (the call went unanswered).
    return spin_server(lambda robot, _scene, overrides: HandSensorsNode(robot, parameter_overrides=overrides), NODE_NAME, args)


if __name__ == "__main__":
    sys.exit(main())
