"""Test access to the project's process launcher (one implementation, in sim_client)."""

from sim_ros.processes import ChildProcess as NodeProcess, running

__all__ = ["NodeProcess", "running"]
