"""Robot scenes by name: ``load("g1")`` or ``load("panda")`` returns a :class:`RobotSpec`."""

from __future__ import annotations

from collections.abc import Callable

from robot_models.spec import JointLimits, RobotModelError, RobotSpec, UnknownRobotError

_REGISTRY: dict[str, Callable[[], RobotSpec]] = {}


def _g1() -> RobotSpec:
    from robot_models import g1

    return g1.load()


def _panda() -> RobotSpec:
    from robot_models import panda

    return panda.load()


_REGISTRY["g1"] = _g1
_REGISTRY["panda"] = _panda

ROBOT_NAMES: tuple[str, ...] = tuple(sorted(_REGISTRY))


def load(name: str) -> RobotSpec:
    """Build the named robot scene.

    Raises:
        UnknownRobotError: the name is not registered; the message lists the names that are.
    """
    try:
        factory = _REGISTRY[name]
    except KeyError:
        raise UnknownRobotError(f"unknown robot {name!r}; known robots: {', '.join(ROBOT_NAMES)}") from None
    return factory()


__all__ = ["JointLimits", "ROBOT_NAMES", "RobotModelError", "RobotSpec", "UnknownRobotError", "load"]
