"""What the ROS side shares: the names and QoS of the topics between nodes, the camera settings' ranges,
message conversions, a client session over rclpy, the project's processes.

Below both ``nodes`` (the ROS nodes) and ``sim_client`` (scripts, scenarios, the CLI); above the
simulation core. It holds no node.
"""

import os as _os
import pathlib as _pathlib

FASTDDS_PROFILES = _pathlib.Path(__file__).with_name("fastdds_profiles.xml")
"""Fast DDS settings for every process that imports this package before it creates a node (see the file)."""
_os.environ.setdefault("FASTRTPS_DEFAULT_PROFILES_FILE", str(FASTDDS_PROFILES))
