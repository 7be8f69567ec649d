"""A ROS tool outside the venv's interpreter set-up loads the project's types, as ros2cli does.

ros2cli installed in a venv of its own runs with that venv's start-up hook, which puts only its own
``lib/`` (the standard interface libraries) on the library path. The project's generated libraries
must then be found: the type support libraries are opened by searching ``LD_LIBRARY_PATH`` (a
RUNPATH does not help there), so ``<venv>/setup.sh`` exports it, as a workspace's setup.bash does.
These tests start a Python process in exactly that situation: a clean environment, the venv's
start-up hook marked done, a library path holding the ROS wheels' libraries and the standard
interface libraries but none of the project's, and nothing else from the venv's set-up.
"""

from __future__ import annotations

import os
import pathlib
import subprocess
import sys
import sysconfig
import textwrap

from tests.ros.processes import running

PREFIX = pathlib.Path(sys.prefix)
PROJECT_LIBRARIES = ("libsim_interfaces", "libsimulation_interfaces", "libtf2_msgs")

# Loads types by name (rosidl's "pkg/kind/Name" form) the way ros2cli's get_message/get_service/
# get_action do, then uses them against the running /sim: a service call, a subscription that
# receives, a publisher, an action client that finds its server.
CLIENT = textwrap.dedent("""
    import importlib, sys, time
    import rclpy
    from rclpy.action import ActionClient

    def get_type(name):
        package, kind, type_name = name.split("/")
        return getattr(importlib.import_module(f"{package}.{kind}"), type_name)

    rclpy.init()
    node = rclpy.create_node("ros_tool_probe")
    Reset = get_type("sim_interfaces/srv/Reset")
    TFMessage = get_type("tf2_msgs/msg/TFMessage")
    ObjectStates = get_type("sim_interfaces/msg/ObjectStates")
    MoveArm = get_type("sim_interfaces/action/MoveArm")
    received = []
    node.create_subscription(TFMessage, "/tf", lambda msg: received.append(len(msg.transforms)), 10)
    node.create_publisher(ObjectStates, "/ros_tool_probe/objects", 10)
    reset = node.create_client(Reset, "/sim/reset")
    arm = ActionClient(node, MoveArm, "/move_arm")
    deadline = time.monotonic() + 60.0

    def spin_until(condition, what):
        while not condition():
            if time.monotonic() > deadline:
                sys.exit(f"timed out waiting for {what}")
            rclpy.spin_once(node, timeout_sec=0.1)

    spin_until(reset.service_is_ready, "/sim/reset")
    # Sent again every 2 s until answered: the first request to a server that has just started can lose its
    # response (the server's reply writer may not have matched this client yet); a reset twice is a reset.
    future = reset.call_async(Reset.Request())
    sent_at = time.monotonic()

    def answered():
        global future, sent_at
        if not future.done() and time.monotonic() - sent_at > 2.0:
            future, sent_at = reset.call_async(Reset.Request()), time.monotonic()
        return future.done()

    spin_until(answered, "the reset response")
    spin_until(lambda: received, "a /tf message")
    spin_until(arm.server_is_ready, "the /move_arm action server")
    print(f"OK reset={future.result().success} tf_transforms={received[0]}")
""")


def tool_environment(tmp_path: pathlib.Path) -> dict[str, str]:
    """The environment of a ROS tool in a venv of its own: only the standard libraries on its path."""
    standard = tmp_path / "other_venv_lib"
    standard.mkdir()
    for library in (PREFIX / "lib").glob("*.so*"):
        if not library.name.startswith(PROJECT_LIBRARIES):
            (standard / library.name).symlink_to(library)
    site = pathlib.Path(sysconfig.get_paths()["purelib"])
    wheel_libraries = sorted(str(path) for path in site.glob("ros_*.libs"))
    return {
        "PATH": "/usr/bin:/bin",
        "HOME": os.environ.get("HOME", "/tmp"),
        "_ROS_WHEELS_BOOTSTRAP_COMPLETE": "1",  # the tool's own start-up hook has run
        "LD_LIBRARY_PATH": os.pathsep.join([str(standard), *wheel_libraries]),
        "ROS_DOMAIN_ID": os.environ["ROS_DOMAIN_ID"],
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
    }


def run_tool(command: str, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["/bin/sh", "-c", command], env=env, capture_output=True, text=True, timeout=120)


def test_setup_script_exports_the_ament_python_and_library_paths(tmp_path):
    script = PREFIX / "setup.sh"
    assert script.is_file(), "the set-up writes <venv>/setup.sh"
    env = tool_environment(tmp_path) | {"AMENT_PREFIX_PATH": "/opt/ros/jazzy"}
    shown = run_tool(f'. "{script}" && echo "$AMENT_PREFIX_PATH" && echo "$PYTHONPATH" && echo "$LD_LIBRARY_PATH"', env)
    assert shown.returncode == 0, shown.stderr
    ament, python_path, library_path = shown.stdout.splitlines()
    assert ament.split(os.pathsep) == [str(PREFIX), "/opt/ros/jazzy"]
    python_dir = pathlib.Path(python_path.split(os.pathsep)[0])
    # the interface packages and nothing else of the venv
    assert sorted(p.name for p in python_dir.iterdir()) == ["sim_interfaces", "simulation_interfaces", "tf2_msgs"]
    assert library_path.split(os.pathsep)[0] == env["LD_LIBRARY_PATH"].split(os.pathsep)[0]  # the tool's own first
    assert library_path.split(os.pathsep)[-1] == str(PREFIX / "lib")


def test_a_tool_on_its_own_library_path_uses_the_projects_types_after_sourcing_setup_sh(tmp_path):
    env = tool_environment(tmp_path)
    python = PREFIX / "bin" / "python"
    probe = tmp_path / "probe.py"
    probe.write_text(CLIENT)
    with running(["sim_node", "--ros-args", "-p", "robot:=panda", "-p", "real_time_factor:=1.0"]), \
         running(["arm_server"]):
        # As ros2cli found it: without the script the project's type support is not found.
        bare = run_tool(f'"{python}" "{probe}"', env)
        assert bare.returncode != 0 and "OK" not in bare.stdout, bare.stdout
        sourced = run_tool(f'. "{PREFIX / "setup.sh"}" && "{python}" "{probe}"', env)
        assert sourced.returncode == 0 and "OK reset=True" in sourced.stdout, sourced.stdout + sourced.stderr[-3000:]


def test_every_generated_library_and_extension_carries_the_runpath():
    site = pathlib.Path(sysconfig.get_paths()["purelib"])
    packages = ("sim_interfaces", "simulation_interfaces", "tf2_msgs")
    objects = [path for package in packages
               for path in (*(PREFIX / "lib").glob(f"lib{package}_*.so"), *(site / package).glob("*.so"))]
    assert len(objects) >= 10
    for path in objects:
        dynamic = subprocess.run(["readelf", "-d", str(path)], capture_output=True, text=True, check=True).stdout
        assert "RUNPATH" in dynamic and str(PREFIX / "lib") in dynamic, f"{path.name} has no RUNPATH to {PREFIX / 'lib'}"
