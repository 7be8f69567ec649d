"""Ending a node so that the others see it leave at once."""

from __future__ import annotations

from rclpy.node import Node


def destroy_node_fully(node: Node) -> None:
    """Destroy the node's waitables that hold it (action servers and clients), then the node.

    rclpy's ``destroy_node`` leaves waitables alone, and an action server keeps its node's handle (and with it
    the process's DDS participant) alive. A process that then ends without finalization (``nodes.runtime.startup.end_process``)
    never tells the others it left: they drop it only when its lease runs out, 20 s later (measured: ``/arm``
    stopped with Ctrl-C stayed in every other node's graph for 20.0 s, ``/sim`` too with its lifecycle state
    machine; ``/power`` left at once), and a participant removed for a lease that ran out is what can
    deadlock another process's Fast DDS (eProsima/Fast-DDS#6502, see sim_ros/fastdds_profiles.xml).
    """
    for waitable in list(node.waitables):
        destroy = getattr(waitable, "destroy", None)
        if callable(destroy):
            destroy()
    node.destroy_node()
    machine = getattr(node, "_state_machine", None)  # a lifecycle node's (rclpy's own attribute): it holds the node too
    if machine is not None:
        machine.destroy_when_not_in_use()
