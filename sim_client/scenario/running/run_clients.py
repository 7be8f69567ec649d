"""The clients a run talks to the nodes with, made once per client session and shared by the runs on it.

Runs on one bring-up share its session (:class:`sim_client.scenario.running.bringups.Bringup`). A client
made anew for each run had to be discovered by the nodes again before its first answer could come back:
a warm run's start-up was 1-3.5 s of that (a fresh session per run, its ``/sim/reset_simulation`` and
action-server probes). A run's recordings are not shared: each run subscribes anew, so they start empty.
"""

from __future__ import annotations

from typing import Any

from sim_client.actions import ACTION_CLIENTS, SimActionClient
from sim_ros.session import RosSession


class RunClients:
    """Publishers and action clients of one session, each made on first use and kept (its service clients are
    kept by the session itself: :meth:`sim_ros.session.RosSession.service_client`).

    Args:
        session: the session they belong to (closed by its owner; :meth:`close` first).
    """

    def __init__(self, session: RosSession) -> None:
        self.session = session
        self._publishers: dict[tuple[Any, str], Any] = {}
        self._actions: dict[str, SimActionClient] = {}

    def publisher(self, msg_type: Any, topic: str, depth: int = 10) -> Any:
        """The publisher of ``topic`` (relative to the session's namespace)."""
        key = (msg_type, topic)
        if key not in self._publishers:
            self._publishers[key] = self.session.node.create_publisher(msg_type, topic, depth)
        return self._publishers[key]

    def action(self, action: str) -> SimActionClient:
        """The client of ``action`` (a scenario's action name: ``walk``, ``navigate`` ...); it probes its server
        once (``wait_for_server``), not again in the next runs."""
        if action not in self._actions:
            self._actions[action] = ACTION_CLIENTS[action](self.session)
        return self._actions[action]

    def close(self) -> None:
        """Destroy the action clients (their feedback subscriptions); the rest goes with the session's node."""
        for client in self._actions.values():
            self.session.in_executor(client.destroy, what="destroying an action client")
        self._actions.clear()
