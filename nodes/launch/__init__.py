"""Launching and supervising a robot's nodes: bringup and the result keeper that answers for a dead server."""
