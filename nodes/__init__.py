"""ROS 2 nodes of the sim package: thin adapters between ROS interfaces and the simulation core."""
