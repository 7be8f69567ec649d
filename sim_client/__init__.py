"""Client side of sim: a small typed facade over rclpy for scripts, the scenario runner and the CLI.

Never use it from inside an executor callback: its waits block the calling thread.
"""

import os

# Videos and camera sheets render headless: MuJoCo picks its GL back-end when it is first imported, so
# the default is set here, before any module of the client imports it (a plain shell, not only `make`).
os.environ.setdefault("MUJOCO_GL", "egl")

from sim_ros.session import RosSession, TopicRecorder, WaitTimeout

__all__ = ["RosSession", "TopicRecorder", "WaitTimeout"]
