"""``device_nodes``: the robot's device nodes in one process (as the bring-up runs them), each with its own name,
parameters and services; ``bringup`` starts it instead of one process per device."""

from __future__ import annotations

import pytest
from builtin_interfaces.msg import Time
from rcl_interfaces.msg import ParameterEvent
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock

from nodes.devices import devices_of
from nodes.launch.bringup import commands_for, parse_args
from sim_ros.processes import BIN
from sim_ros.session import WaitTimeout
from tests.ros.processes import running


def test_each_robot_has_the_devices_of_its_model():
    assert devices_of("g1") == ["power", "hand_sensors", "camera", "head"]
    assert devices_of("panda") == ["hand_sensors", "camera"]  # the wrist sensor and the scene camera


@pytest.mark.parametrize("robot", ["g1", "panda"])
def test_a_bringup_runs_its_devices_in_one_process(robot):
    executables = [command[0] for command in commands_for(parse_args(["--robot", robot]), [])]
    assert executables.count("device_nodes") == 1
    assert not {"power_node", "hand_sensors", "camera_node", "head_node"} & set(executables), executables


def test_a_bringup_passes_its_stream_rates_to_sim_and_refuses_a_rate_out_of_range(capsys):
    sim = commands_for(parse_args(["--robot", "g1", "--clock-rate", "50", "--joint-state-rate", "100"]), [])[0]
    assert sim[0] == "sim_node" and "clock_rate:=50.0" in sim and "joint_state_rate:=100.0" in sim, sim
    assert not any("joint_state_rate" in arg for arg in commands_for(parse_args(["--robot", "g1"]), [])[0])
    with pytest.raises(SystemExit):
        parse_args(["--joint-state-rate", "0.5"])
    assert "--joint-state-rate must be in [1, 500] Hz of sim time" in capsys.readouterr().err


def test_the_g1_devices_serve_their_own_parameters_from_one_process(client):
    with running([str(BIN / "device_nodes"), "--ros-args", "-p", "robot:=g1",
                  "-p", "power:battery_low_threshold:=25.0"]) as process:
        names = devices_of("g1")
        client.wait_for(lambda: all(client.parameters(name).services_are_ready() for name in names) or not process.alive(),
                        60.0, f"the parameter services of {names}")
        assert process.alive(), process.output()[-2000:]
        values = {}
        for node, parameter in (("power", "battery_low_threshold"), ("head", "head_tilt_angle"),
                                ("camera", "camera_exposure"), ("hand_sensors", "calibration_window")):
            answer = client.until_answered(lambda n=node, p=parameter: client.parameters(n).get_parameters([p]), 30.0,
                                           f"get {node} {parameter}")
            values[node] = answer.values[0].double_value  # each of these is a double
        assert values["power"] == pytest.approx(25.0), "a node-prefixed -p reaches that node only"
        assert values["head"] == pytest.approx(0.0) and values["camera"] > 0 and values["hand_sensors"] > 0, values
        ok, reason = client.set_parameter("head", "head_tilt_angle", 2.0)
        assert not ok and "out of range" in reason, reason  # each node keeps its ranges and reasons
        assert process.alive()


def test_the_devices_of_one_process_keep_sim_time_from_one_clock_subscription(client):
    """/sim writes each /clock message once to the process, not once per device node; every node's clock follows it."""
    with running([str(BIN / "device_nodes"), "--ros-args", "-p", "robot:=g1"]) as process:
        names = devices_of("g1")
        client.wait_for(lambda: all(client.parameters(name).services_are_ready() for name in names) or not process.alive(),
                        60.0, f"the parameter services of {names}")
        assert process.alive(), process.output()[-2000:]

        def clock_readers() -> list[str]:
            return [info.node_name for info in client.node.get_subscriptions_info_by_topic("/clock")]

        # Discovery gives a reader's node name a moment after the reader. Each node subscribed on its own when it
        # was made and let go once all were made, so the others' readers leave a moment after they came (on a
        # loaded machine the client once saw all four here): the wait is for the readers the process keeps.
        def one_reader() -> bool:
            readers = clock_readers()
            return "_NODE_NAME_UNKNOWN_" not in readers and sorted(name for name in readers if name in names) == [names[0]]

        try:
            client.wait_for(one_reader, 30.0, f"one /clock reader in the process, {names[0]}'s")
        except WaitTimeout as timeout:
            raise AssertionError(f"{timeout}: the /clock readers are {clock_readers()}") from timeout
        clock = client.node.create_publisher(Clock, "/clock", 10)
        events = client.record(ParameterEvent, "/parameter_events", qos=QoSProfile(depth=1000))
        sim_s = 1234.5
        for node, parameter in (("power", "battery_low_threshold"), ("head", "head_tilt_angle"),
                                ("camera", "camera_exposure"), ("hand_sensors", "calibration_window")):
            value = client.get_parameter(node, parameter)

            def stamped_at_sim_time(node: str = node, parameter: str = parameter, value: float = value) -> bool:
                # /clock keeps coming (a best-effort subscription may miss one); each set publishes a parameter
                # event stamped by the node's own clock.
                clock.publish(Clock(clock=Time(sec=1234, nanosec=500_000_000)))
                ok, reason = client.set_parameter(node, parameter, value)
                assert ok, reason
                return any(event.node == f"/{node}" and abs(event.stamp.sec + event.stamp.nanosec * 1e-9 - sim_s) < 1e-6
                           for event in events.messages())

            client.wait_for(stamped_at_sim_time, 30.0, f"/{node}'s parameter events stamped with sim time {sim_s} s",
                            poll=0.2)
        assert process.alive()
