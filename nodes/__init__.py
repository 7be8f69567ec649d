"""ROS 2 nodes of the sim package: thin adapters between ROS interfaces and the simulation core."""

import os

# The nodes run headless: MuJoCo's renderer (the cameras of /sim) picks its GL back-end when mujoco is first
# imported, so the default must be set before any module imports it. EGL renders on the CPU (Mesa) or a GPU.
os.environ.setdefault("MUJOCO_GL", "egl")
# One OpenBLAS thread (numpy's and scipy's), set before numpy loads: see robot_models/__init__.py. Every entry point
# imports numpy (through rclpy's messages or mujoco) before robot_models, where this was set too late for numpy.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
