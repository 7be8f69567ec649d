"""Declaring ROS parameters from one typed table, with descriptors that state type and range.

A start-up value a parameter cannot take (out of range, of the wrong type) is a :class:`StartupError`
whose one line names the parameter, the value and what is allowed (:func:`allowed`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    Parameter as ParameterMsg,
    ParameterDescriptor,
    ParameterType,
    SetParametersResult,
)
from rcl_interfaces.srv import SetParameters, SetParametersAtomically
from rclpy.node import Node


class StartupError(Exception):
    """A node cannot start as asked; the message is the one line the user reads."""


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


def allowed(spec: ParameterSpec) -> str:
    """What a parameter accepts, in words: type, range, read-only."""
    kind = {bool: "true or false", int: "an integer", float: "a number with a decimal point", str: "a string"}[type(spec.default)]
    text = kind
    if spec.low is not None and spec.high is not None:
        text += f" from {spec.low:g} to {spec.high:g}"
    return text


def parameter_error(spec: ParameterSpec, value: Any, error: Exception) -> StartupError:
    """The one-line error for a start-up value rclpy refused while declaring ``spec``."""
    from rclpy.exceptions import InvalidParameterTypeException

    shown = repr(value) if value is not None else "the value given"
    if isinstance(error, InvalidParameterTypeException):
        return StartupError(f"parameter {spec.name}: {shown} has the wrong type; allowed: {allowed(spec)}")
    return StartupError(f"parameter {spec.name}: {shown} is refused; allowed: {allowed(spec)}")


def declare(node: Node, specs: tuple[ParameterSpec, ...]) -> None:
    """Declare every parameter of ``specs`` on ``node`` with a full descriptor (one declared already is left as it is).

    Raises:
        StartupError: a start-up value (``-p`` or a params file) is out of range or of the
            wrong type; the message names the parameter, the value and what is allowed.
    """
    from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException

    for spec in specs:
        if node.has_parameter(spec.name):  # declared by an earlier configure (a world loaded since): keeps its value
            continue
        descriptor = ParameterDescriptor(description=spec.description, read_only=spec.read_only)
        if spec.low is not None and spec.high is not None:
            if isinstance(spec.default, float):
                descriptor.floating_point_range = [FloatingPointRange(from_value=float(spec.low), to_value=float(spec.high))]
                descriptor.additional_constraints = f"{spec.low} <= value <= {spec.high}"
            elif isinstance(spec.default, int) and not isinstance(spec.default, bool):
                descriptor.integer_range = [IntegerRange(from_value=int(spec.low), to_value=int(spec.high), step=1)]
                descriptor.additional_constraints = f"{int(spec.low)} <= value <= {int(spec.high)}"
        try:
            node.declare_parameter(spec.name, spec.default, descriptor)
        except (InvalidParameterValueException, InvalidParameterTypeException) as error:
            # rclpy keeps the start-up values in this (private) table; the exception does not carry them.
            given = getattr(node, "_parameter_overrides", {}).get(spec.name)
            raise parameter_error(spec, getattr(given, "value", None), error) from None


PARAMETER_TYPES = {value: name for name, value in vars(ParameterType).items() if name.startswith("PARAMETER_")}


def report_read_only(node: Node, name: str, value: Any) -> None:
    """Give a read-only parameter the value the node now has (e.g. the scene loaded since start-up): users cannot set
    it, and rclpy's ``set_parameters`` refuses a read-only one, so its table entry is replaced."""
    from rclpy.parameter import Parameter

    node._parameters[name] = Parameter(name, value=value)


def parameter_problem(parameter: ParameterMsg) -> str:
    """Why a parameter message cannot be judged at all ("" when it can); rclpy's services raise on these."""
    if not parameter.name:
        return "a parameter name must not be empty"
    if parameter.value.type not in PARAMETER_TYPES:
        known = ", ".join(f"{value} {name.removeprefix('PARAMETER_')}" for value, name in sorted(PARAMETER_TYPES.items()))
        return f"parameter {parameter.name!r}: value type {parameter.value.type} is not a parameter type ({known})"
    return ""


def guard_parameter_services(node: Node) -> None:
    """Refuse malformed parameter messages with a reason before rclpy's own services see them.

    rclpy's ``~/set_parameters`` and ``~/set_parameters_atomically`` raise on a value type outside
    ParameterType (and let an empty name through): the exception would leave the executor and end
    the node. Here such parameters are refused with a reason that says what is allowed; the others of
    a ``set_parameters`` request are set as usual (each independently, as that service promises),
    an atomic request is refused whole.
    """
    for service in node.services:
        if service.srv_type is SetParameters:
            service.callback = _guarded_set(service.callback)
        elif service.srv_type is SetParametersAtomically:
            service.callback = _guarded_set_atomically(service.callback)


def _guarded_set(inner: Callable[[Any, Any], Any]) -> Callable[[Any, Any], Any]:
    def set_parameters(request: SetParameters.Request, response: SetParameters.Response) -> SetParameters.Response:
        problems = [parameter_problem(p) for p in request.parameters]
        if not any(problems):
            return inner(request, response)
        kept = [p for p, problem in zip(request.parameters, problems, strict=True) if not problem]
        valid = SetParameters.Request(parameters=kept)
        applied = iter(inner(valid, SetParameters.Response()).results if valid.parameters else [])
        response.results = [SetParametersResult(successful=False, reason=problem) if problem else next(applied)
                            for problem in problems]
        return response

    return set_parameters


def _guarded_set_atomically(inner: Callable[[Any, Any], Any]) -> Callable[[Any, Any], Any]:
    def set_parameters_atomically(request: SetParametersAtomically.Request,
                                  response: SetParametersAtomically.Response) -> SetParametersAtomically.Response:
        problems = [problem for problem in map(parameter_problem, request.parameters) if problem]
        if not problems:
            return inner(request, response)
        response.result = SetParametersResult(successful=False, reason="; ".join(problems) + "; nothing was set")
        return response

    return set_parameters_atomically
