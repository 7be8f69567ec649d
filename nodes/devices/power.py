"""The ``/power`` node: the battery's settings, ``/battery_state`` from a timer, and ``/get_battery_level``.

The battery itself is simulated inside ``/sim``: its drain (idle draw + the actuators' mechanical
power |tau * qdot| over the drive efficiency) is integrated at every control step, so it is
deterministic and measured from the physics, and Walk and NavigateToPose check it there. This node
owns the model's parameters (sent to ``/sim`` on a latched topic whenever they change), republishes
the measured state as ``sensor_msgs/BatteryState`` on ``/battery_state`` at ``publish_rate`` Hz of
sim time (a timer on the measurements' sim time), and answers ``/get_battery_level`` at once from the
latest measurement.
"""

from __future__ import annotations

import sys
import threading
from typing import Any

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.qos import QoSProfile
from sensor_msgs.msg import BatteryState

import robot_models
from nodes.devices.base import DeviceNode
from nodes.runtime.parameters import ParameterSpec
from nodes.runtime.serve import spin_server
from robot_models.sensors import BatteryLayout
from sim_interfaces.msg import BatteryConfig
from sim_interfaces.srv import GetBatteryLevel
from sim_ros.names import BATTERY_CONFIG_TOPIC, BATTERY_TOPIC
from sim_ros.stamps import seconds_of

NODE_NAME = "power"
MODEL_PARAMETERS = ("capacity_wh", "idle_power_w", "drive_efficiency", "battery_low_threshold")


def parameters(pack: BatteryLayout) -> tuple[ParameterSpec, ...]:
    """The node's parameters; the defaults come from the robot's battery pack."""
    return (
        ParameterSpec("capacity_wh", pack.capacity_wh, "usable energy of a full battery [Wh]", 10.0, 10000.0),
        ParameterSpec("idle_power_w", pack.idle_power_w, "always-on draw of the computers and electronics [W]", 0.0, 2000.0),
        ParameterSpec("drive_efficiency", 0.6, "mechanical power out per electrical power in of the drives", 0.05, 1.0),
        ParameterSpec("battery_low_threshold", 20.0, "below this level [%] Walk and NavigateToPose refuse to start and "
                      "abort with BATTERY_LOW", 0.0, 100.0),
        ParameterSpec("publish_rate", 1.0, "/battery_state rate [Hz of sim time] (at most /sim's state_rate)", 0.1, 30.0),
    )


class PowerNode(DeviceNode):
    """Serves the battery of the robot of ``/sim`` (see the module's text)."""

    def __init__(self, robot: str, **kwargs: Any) -> None:
        pack = robot_models.sensors_of(robot).battery
        if pack is None:
            raise robot_models.RobotModelError(f"robot {robot!r} has no battery (it runs on mains power)")
        super().__init__(NODE_NAME, (ParameterSpec("robot", robot, "robot whose battery is served", read_only=True),
                                     *parameters(pack)), **kwargs)
        self._lock = threading.Lock()
        self._latest: BatteryState | None = None
        group = MutuallyExclusiveCallbackGroup()
        self._state_pub = self.create_publisher(BatteryState, "battery_state", 10)
        self.create_subscription(BatteryState, BATTERY_TOPIC, self._on_battery, QoSProfile(depth=10), callback_group=group)
        self.create_service(GetBatteryLevel, "get_battery_level", self._on_get_level, callback_group=group)
        self._next_publish = 0.0  # [s of sim time]
        # A steady 1 Hz wake-up of the executor, so that stopping this node (Ctrl-C) ends the process cleanly:
        # without any wall-clock timer it can abort ("terminate called without an active exception").
        self._wake = self.create_timer(1.0, lambda: None, callback_group=group, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.relay(BatteryConfig, BATTERY_CONFIG_TOPIC, MODEL_PARAMETERS, self._config)
        self.get_logger().info(f"serving /battery_state and /get_battery_level for {robot}")

    def _param(self, name: str) -> float:
        return float(self.get_parameter(name).value)

    def _config(self) -> BatteryConfig:
        return BatteryConfig(
            capacity_wh=self._param("capacity_wh"), idle_power_w=self._param("idle_power_w"),
            drive_efficiency=self._param("drive_efficiency"), low_threshold_percent=self._param("battery_low_threshold"))

    def _on_battery(self, msg: BatteryState) -> None:
        """Keep the latest measurement; publish /battery_state when the sim-time timer falls due.

        The timer runs on the measurements' sim time (the period on the grid of ``publish_rate``), so the
        rate is in sim time at any real-time factor and nothing is published while the sim is paused.
        """
        now = seconds_of(msg.header.stamp)
        with self._lock:
            self._latest = msg
            due = now + 1e-9 >= self._next_publish or now < self._next_publish - 1.0 / self._param("publish_rate")
            if due:  # (or sim time went back: a restarted /sim)
                self._next_publish = now + 1.0 / self._param("publish_rate")
        if due:
            self._state_pub.publish(msg)

    def _on_get_level(self, request: GetBatteryLevel.Request, response: GetBatteryLevel.Response) -> GetBatteryLevel.Response:
        with self._lock:
            latest = self._latest
        if latest is None:
            response.level_percent = -1.0
            response.message = f"no battery measurement from /sim on {BATTERY_TOPIC} yet; is /sim running?"
            return response
        threshold = self._param("battery_low_threshold")
        response.level_percent = 100.0 * float(latest.percentage)
        response.low = response.level_percent < threshold
        response.voltage = float(latest.voltage)
        response.message = (f"battery at {response.level_percent:.1f} %, drawing {-latest.current * latest.voltage:.0f} W"
                            + (f"; low (below {threshold:g} %): walking is refused" if response.low else ""))
        return response


def main(args: list[str] | None = None) -> int:
    """Console entry point: ``power_node`` (asks /sim for its robot)."""
    return spin_server(lambda robot, _scene, overrides: PowerNode(robot, parameter_overrides=overrides), NODE_NAME, args,
                       events=True)


if __name__ == "__main__":
    sys.exit(main())
