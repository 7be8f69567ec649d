"""Responsiveness of the action servers at real_time_factor 1 (figures for the closing note; not a test).

``bringup --robot g1 --rtf 1``; then, round after round, a Walk goal (1 m at 0.3 m/s): wall time from
the goal's acceptance to its first feedback, and, once it walks, from the cancel request to the goal's
terminal state (CANCELED once the robot stands: the gait's stop and settle, about 1 s of sim time).
Prints each round and the medians.

Usage: ``make bench-response`` or ``.venv/bin/python benchmarks/response_bench.py [--rounds 5]``.
"""

from __future__ import annotations

import argparse
import os
import random
import statistics
import time
from typing import Any

# A domain of this run's own, on this machine only: set before rclpy is imported.
os.environ.setdefault("ROS_DOMAIN_ID", str(1 + random.randrange(101)))  # 1..101: safe for Fast DDS ports
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"

# Imported once the ROS environment above is fixed.
from sim_client.actions import WalkClient
from sim_client.processes import running
from sim_client.session import RosSession
from sim_interfaces.action import Walk


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    options = parser.parse_args()
    first_ms: list[float] = []
    cancel_ms: list[float] = []
    with running(["bringup", "--robot", "g1", "--rtf", "1"]), RosSession("response_bench") as session:
        client = WalkClient(session)
        client.wait_for_server(120.0)
        for round_ in range(options.rounds):
            handle = client.send(Walk.Goal(distance=1.0, speed=0.3), timeout=30.0)
            accepted = time.monotonic()

            def walking(h: Any = handle) -> bool:
                return h.feedback is not None and h.feedback.distance_walked > 0.15

            def fed(h: Any = handle) -> bool:
                return h.feedback is not None

            def ended(h: Any = handle) -> bool:
                return bool(h.done)

            session.wait_for(fed, 10.0, "the first feedback", poll=0.001)
            first_ms.append((time.monotonic() - accepted) * 1e3)
            session.wait_for(walking, 30.0, "the walk under way")
            asked = time.monotonic()
            handle.cancel()
            session.wait_for(ended, 30.0, "the canceled goal to end", poll=0.001)
            cancel_ms.append((time.monotonic() - asked) * 1e3)
            outcome = handle.outcome()
            print(f"  round {round_ + 1}: goal -> first feedback {first_ms[-1]:6.1f} ms   "
                  f"cancel -> {outcome.status if outcome else '?'} {cancel_ms[-1]:7.1f} ms", flush=True)
    print(f"median: Walk goal -> first feedback {statistics.median(first_ms):.1f} ms (goal <= 50 ms); "
          f"cancel -> terminal {statistics.median(cancel_ms):.0f} ms (waits until the robot stands)")


if __name__ == "__main__":
    main()
