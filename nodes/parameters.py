"""Declaring ROS parameters from one typed table, with descriptors that state type and range."""

from __future__ import annotations

from dataclasses import dataclass

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node


@dataclass(frozen=True)
class ParameterSpec:
    """One parameter: name, default, description, optional range, read-only flag.

    The type follows the default (float -> double, int -> integer, str, bool). ``low``/``high``
    bound doubles and integers; rclpy refuses values outside with a reason naming the range.
    """

    name: str
    default: float | int | str | bool
    description: str
    low: float | None = None
    high: float | None = None
    read_only: bool = False


def declare(node: Node, specs: tuple[ParameterSpec, ...]) -> None:
    """Declare every parameter of ``specs`` on ``node`` with a full descriptor."""
    for spec in specs:
        descriptor = ParameterDescriptor(description=spec.description, read_only=spec.read_only)
        if spec.low is not None and spec.high is not None:
            if isinstance(spec.default, float):
                descriptor.floating_point_range = [FloatingPointRange(from_value=float(spec.low), to_value=float(spec.high))]
                descriptor.additional_constraints = f"{spec.low} <= value <= {spec.high}"
            elif isinstance(spec.default, int) and not isinstance(spec.default, bool):
                descriptor.integer_range = [IntegerRange(from_value=int(spec.low), to_value=int(spec.high), step=1)]
                descriptor.additional_constraints = f"{int(spec.low)} <= value <= {int(spec.high)}"
        node.declare_parameter(spec.name, spec.default, descriptor)
