"""Client side of sim: a small typed facade over rclpy for scripts, the scenario runner and the CLI.

Never use it from inside an executor callback: its waits block the calling thread.
"""

import os

# Videos and camera sheets render headless: MuJoCo picks its GL back-end when it is first imported, so
# the default is set here, before any module of the client imports it (a plain shell, not only `make`).
os.environ.setdefault("MUJOCO_GL", "egl")
# One OpenBLAS thread (numpy's and scipy's), set before numpy loads: see robot_models/__init__.py. Every entry point
# imports numpy (through rclpy's messages or mujoco) before robot_models, where this was set too late for numpy.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from sim_ros.session import RosSession, TopicRecorder, WaitTimeout

__all__ = ["RosSession", "TopicRecorder", "WaitTimeout"]
