"""Nodes that bridge the ROS topics to other tools (the Foxglove app)."""
