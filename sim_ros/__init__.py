"""What the ROS side shares: the names and QoS of the topics between nodes, the camera settings' ranges,
message conversions, a client session over rclpy, the project's processes.

Below both ``nodes`` (the ROS nodes) and ``sim_client`` (scripts, scenarios, the CLI); above the
simulation core. It holds no node.
"""
