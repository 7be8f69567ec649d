"""Test-wide set-up: a ROS domain of this run's own, localhost discovery, headless rendering.

The environment is fixed before anything imports rclpy, so every process started by a test
(and the test's own clients) share this run's ``ROS_DOMAIN_ID`` and hear no other run.
"""

from __future__ import annotations

import os

# Domain ids 1..101 are safe for Fast DDS ports; 0 is everyone's default, so it is avoided.
os.environ["ROS_DOMAIN_ID"] = str(os.environ.get("SIM_TEST_DOMAIN_ID") or 1 + os.getpid() % 100)
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("MUJOCO_GL", "egl")
