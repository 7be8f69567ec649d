"""Client side of sim: a small typed facade over rclpy for scripts, the scenario runner and the CLI.

Never use it from inside an executor callback: its waits block the calling thread.
"""

from sim_ros.session import RosSession, TopicRecorder, WaitTimeout

__all__ = ["RosSession", "TopicRecorder", "WaitTimeout"]
