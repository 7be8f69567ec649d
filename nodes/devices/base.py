"""The shape of a device node: parameters from one table, relayed to ``/sim`` on a latched topic.

``/sim`` simulates the devices (the camera, the head's tilt mount, the battery) because it alone holds
the state; a device node plays the driver and owns the settings a driver exposes. Its parameters are
declared with type, range and description (rclpy refuses a value outside with a reason that states what
is allowed, and the node keeps its value); at start and after every accepted change, the settings
message is published latched, so a ``/sim`` that starts later, or again, takes the latest.
"""

from __future__ import annotations

from collections.abc import Callable, Collection
from typing import Any

from rclpy.node import Node
from rclpy.parameter import Parameter

from nodes.runtime.parameters import ParameterSpec, declare
from sim_ros.names import LATCHED


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
                publisher.publish(settings())

        self.add_post_set_parameters_callback(on_parameters)
        publisher.publish(settings())
