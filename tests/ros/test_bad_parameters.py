"""Malformed parameter messages are refused with a reason and the node keeps serving (sim and a server)."""

from __future__ import annotations

import pytest
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, SetParameters, SetParametersAtomically

from tests.ros.processes import running

STARTUP_S = 60.0
VALID = {"sim": ("state_rate", 20.0), "arm": ("feedback_rate", 5.0)}


@pytest.fixture(scope="module")
def panda(client):
    with running(["bringup", "--robot", "panda"]) as process:
        for node in VALID:
            client.wait_for(lambda node=node: _service_up(client, f"/{node}/set_parameters"), STARTUP_S,
                            f"/{node}/set_parameters")
        yield process


def _service_up(client, name: str) -> bool:
    return any(service == name for service, _ in client.node.get_service_names_and_types())


def _double(name: str, value: float) -> Parameter:
    return Parameter(name=name, value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value))


@pytest.mark.parametrize("node", sorted(VALID))
def test_unknown_types_and_empty_names_are_refused_and_the_rest_is_set(client, panda, node):
    name, value = VALID[node]
    request = SetParameters.Request(parameters=[
        Parameter(name=name, value=ParameterValue(type=42)),
        Parameter(name="", value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=1.0)),
        _double(name, value),
    ])
    results = client.call(SetParameters, f"/{node}/set_parameters", request, timeout=10.0).results
    assert len(results) == 3
    assert not results[0].successful and "42 is not a parameter type" in results[0].reason and "DOUBLE" in results[0].reason
    assert not results[1].successful and "must not be empty" in results[1].reason
    assert results[2].successful, results[2].reason

    bad = Parameter(name=name, value=ParameterValue(type=99))
    atomic = SetParametersAtomically.Request(parameters=[_double(name, value + 1.0), bad])
    result = client.call(SetParametersAtomically, f"/{node}/set_parameters_atomically", atomic, timeout=10.0).result
    assert not result.successful and "99 is not a parameter type" in result.reason and "nothing was set" in result.reason

    answer = client.call(GetParameters, f"/{node}/get_parameters", GetParameters.Request(names=[name]), timeout=10.0)
    assert answer.values[0].double_value == value, "the valid value was set, the atomic request changed nothing"
    assert panda.alive(), "every node keeps running"
