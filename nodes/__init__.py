"""ROS 2 nodes of the sim package: thin adapters between ROS interfaces and the simulation core."""

import os

# The nodes run headless: MuJoCo's renderer (the cameras of /sim) picks its GL back-end when mujoco is first
# imported, so the default must be set before any module imports it. EGL renders on the CPU (Mesa) or a GPU.
os.environ.setdefault("MUJOCO_GL", "egl")
