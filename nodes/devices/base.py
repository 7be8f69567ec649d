"""The shape of a device node: parameters from one table, relayed to ``/sim`` on a latched topic.

``/sim`` simulates the devices (the camera, the head's tilt mount, the battery) because it alone holds
the state; a device node plays the driver and owns the settings a driver exposes. Its parameters are
declared with type, range and description (rclpy refuses a value outside with a reason that states what
is allowed, and the node keeps its value); at start and after every accepted change, the settings
message is published latched, so a ``/sim`` that starts later, or again, takes the latest.

A change made while ``/sim`` runs but has not yet matched the settings topic (the first seconds after a
bring-up, when discovery is slow on a loaded machine) is answered once ``/sim`` takes it, or after
:data:`SIM_MATCH_WALL_S`: an accepted value then reaches the simulation within a control step or two, not
whenever discovery ends (a lock-stepped scenario tilting the head right after start-up ran its 3 s of sim
time before ``/sim`` heard the tilt).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Collection
from typing import Any

from rclpy.node import Node
from rclpy.parameter import Parameter

from nodes.runtime.parameters import ParameterSpec, declare
from sim_ros.names import LATCHED, SIM_NODE

SIM_MATCH_WALL_S = 5.0  # [s] wall: longest a change waits for a running /sim to match its settings topic
MATCH_POLL_S = 0.01  # [s] wall between looks at the match (discovery runs in Fast DDS's threads meanwhile)


class DeviceNode(Node):
    """A node whose ``specs`` are declared at construction; :meth:`relay` sends settings made from them to /sim.

    Args:
        node_name: the node's name.
        specs: every parameter of the node.
        kwargs: for :class:`rclpy.node.Node` (``parameter_overrides``, ...).

    Raises:
        nodes.runtime.parameters.StartupError: a start-up value is refused.
    """

    def __init__(self, node_name: str, specs: tuple[ParameterSpec, ...], **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        declare(self, specs)

    def relay(self, msg_type: Any, topic: str, parameters: Collection[str], settings: Callable[[], Any]) -> None:
        """Publish ``settings()`` on ``topic`` (latched) now and whenever one of ``parameters`` changed."""
        publisher = self.create_publisher(msg_type, topic, LATCHED)
        names = frozenset(parameters)

        def on_parameters(changed: list[Parameter]) -> None:
            if any(p.name in names for p in changed):
                self._wait_for_sim_to_listen(publisher)
                publisher.publish(settings())

        self.add_post_set_parameters_callback(on_parameters)
        publisher.publish(settings())

    def _wait_for_sim_to_listen(self, publisher: Any) -> None:
        """Until ``publisher`` has a subscriber, while a ``sim`` node runs in this node's namespace (bounded by
        :data:`SIM_MATCH_WALL_S`); at once when it has one, or when no /sim runs (it takes the latched value when
        it starts)."""
        deadline = time.monotonic() + SIM_MATCH_WALL_S
        while publisher.get_subscription_count() == 0 and time.monotonic() < deadline:
            if (SIM_NODE, self.get_namespace()) not in self.get_node_names_and_namespaces():
                return
            time.sleep(MATCH_POLL_S)  # polling the match (no rclpy wait exists for it), bounded by the deadline
