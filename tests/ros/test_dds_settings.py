"""The project's Fast DDS settings are read by every process that imports it (sim_ros/fastdds_profiles.xml)."""

from __future__ import annotations

import os
import subprocess
import sys

import sim_ros

PROBE = """
import sim_ros, os, rclpy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node("dds_settings_probe")
node.create_publisher(String, "/dds_settings_probe", 10)
node.destroy_node()
rclpy.shutdown()
print(os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"])
"""


def test_a_process_importing_the_project_loads_its_fast_dds_profile_without_errors():
    env = {k: v for k, v in os.environ.items() if k != "FASTRTPS_DEFAULT_PROFILES_FILE"}
    done = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == str(sim_ros.FASTDDS_PROFILES)
    assert "XMLPARSER" not in done.stderr and "Error" not in done.stderr, done.stderr[-2000:]
    assert "<intraprocess_delivery>OFF</intraprocess_delivery>" in sim_ros.FASTDDS_PROFILES.read_text()


def test_a_profile_the_user_names_is_kept():
    env = dict(os.environ, FASTRTPS_DEFAULT_PROFILES_FILE="/nonexistent/theirs.xml")
    done = subprocess.run([sys.executable, "-c", "import sim_ros, os; print(os.environ['FASTRTPS_DEFAULT_PROFILES_FILE'])"],
                          env=env, capture_output=True, text=True, timeout=60)
    assert done.stdout.strip() == "/nonexistent/theirs.xml"


def test_fast_dds_errors_go_to_stderr_and_leave_stdout_to_the_program(tmp_path):
    """A program's stdout is read (``sim watch``, the recorder's answers): Fast DDS's errors must not land there. The
    project's profile, with a consumer Fast DDS does not know added after its own, makes Fast DDS log an error."""
    text = sim_ros.FASTDDS_PROFILES.read_text()
    assert text.count("</consumer>") == 1, "the profile has one log consumer, followed here by a wrong one"
    broken = tmp_path / "profiles.xml"
    broken.write_text(text.replace("</consumer>", "</consumer><consumer><class>NoSuchConsumer</class></consumer>"))
    env = dict(os.environ, FASTRTPS_DEFAULT_PROFILES_FILE=str(broken))
    done = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "NoSuchConsumer" in done.stderr, "Fast DDS said nothing of the wrong consumer: the test tests nothing"
    assert done.stdout.strip() == str(broken), done.stdout[-2000:]
