"""A node's standard parameter services (what ``ros2 param`` calls), built on :class:`sim_ros.session.RosSession`.

    with RosSession("my_script") as session:
        ok, reason = Parameters(session, "/locomotion").set("walking_speed", 0.5)

Every call blocks the calling thread: never use these from inside an executor callback.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from rcl_interfaces.msg import ParameterDescriptor, ParameterType
from rclpy.parameter import Parameter, parameter_value_to_python

from sim_ros.session import RosSession, WaitTimeout

_TYPE_NAMES = {
    ParameterType.PARAMETER_NOT_SET: "not set",
    ParameterType.PARAMETER_BOOL: "bool",
    ParameterType.PARAMETER_INTEGER: "integer",
    ParameterType.PARAMETER_DOUBLE: "double",
    ParameterType.PARAMETER_STRING: "string",
    ParameterType.PARAMETER_BYTE_ARRAY: "byte array",
    ParameterType.PARAMETER_BOOL_ARRAY: "bool array",
    ParameterType.PARAMETER_INTEGER_ARRAY: "integer array",
    ParameterType.PARAMETER_DOUBLE_ARRAY: "double array",
    ParameterType.PARAMETER_STRING_ARRAY: "string array",
}


@dataclass(frozen=True)
class ParameterInfo:
    """What ``ros2 param describe`` shows about one parameter."""

    name: str
    type: str
    description: str
    read_only: bool
    constraints: str
    range: tuple[float, float] | None = field(default=None)

    def __str__(self) -> str:
        lines = [f"Parameter name: {self.name}", f"  Type: {self.type}"]
        if self.description:
            lines.append(f"  Description: {self.description}")
        if self.range is not None:
            lines.append(f"  Range: {self.range[0]} .. {self.range[1]}")
        if self.constraints:
            lines.append(f"  Constraints: {self.constraints}")
        if self.read_only:
            lines.append("  Read only: true")
        return "\n".join(lines)


class ParameterError(RuntimeError):
    """A parameter does not exist or its node does not answer."""


class Parameters:
    """The standard parameter services of one node (what ``ros2 param`` calls).

    Args:
        session: the client session.
        node: node name: relative (``"sim"``: under the session's namespace) or absolute (``"/locomotion"``).
        timeout: wall seconds to wait for the node's services and each answer.
    """

    def __init__(self, session: RosSession, node: str, timeout: float = 10.0) -> None:
        self.session = session
        self.node = node if node.startswith("/") else f"{session.namespace}/{node}"  # relative: under the namespace
        self.timeout = timeout
        self._client = session.parameters(self.node)

    def _ready(self) -> None:
        try:
            self.session.wait_for(self._client.services_are_ready, self.timeout, f"parameter services of {self.node}")
        except WaitTimeout as error:
            raise ParameterError(f"{error}; is {self.node} running?") from None

    def list(self) -> list[str]:
        self._ready()
        response = self.session.wait_future(self._client.list_parameters([], 0), self.timeout, f"list of {self.node}")
        return sorted(response.result.names)

    def get(self, name: str) -> Any:
        self._ready()
        response = self.session.wait_future(self._client.get_parameters([name]), self.timeout, f"get {self.node} {name}")
        if not response.values or response.values[0].type == ParameterType.PARAMETER_NOT_SET:
            raise ParameterError(f"{self.node} has no parameter {name!r}")
        return parameter_value_to_python(response.values[0])

    def describe(self, name: str) -> ParameterInfo:
        self._ready()
        response = self.session.wait_future(
            self._client.describe_parameters([name]), self.timeout, f"describe {self.node} {name}"
        )
        if not response.descriptors:
            raise ParameterError(f"{self.node} has no parameter {name!r}")
        d: ParameterDescriptor = response.descriptors[0]
        if d.type == ParameterType.PARAMETER_NOT_SET:
            raise ParameterError(f"{self.node} has no parameter {name!r}")
        span: tuple[float, float] | None = None
        if d.floating_point_range:
            span = (d.floating_point_range[0].from_value, d.floating_point_range[0].to_value)
        elif d.integer_range:
            span = (float(d.integer_range[0].from_value), float(d.integer_range[0].to_value))
        return ParameterInfo(d.name or name, _TYPE_NAMES.get(d.type, str(d.type)), d.description, bool(d.read_only),
                             d.additional_constraints, span)

    def set(self, name: str, value: Any, coerce: bool = True) -> tuple[bool, str]:
        """Set a parameter; returns (successful, reason). The node's reason is passed on verbatim.

        With ``coerce``, an integer given for a double parameter is sent as a double (``ros2
        param set`` would refuse it as the wrong type).
        """
        if coerce and isinstance(value, int) and not isinstance(value, bool):
            try:
                if self.describe(name).type == "double":
                    value = float(value)
            except ParameterError:
                pass
        self._ready()
        response = self.session.wait_future(
            self._client.set_parameters([Parameter(name, value=value)]), self.timeout, f"set {self.node} {name}"
        )
        result = response.results[0]
        return bool(result.successful), str(result.reason)
