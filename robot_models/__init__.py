"""Robot scenes by name: ``load("g1")`` or ``load("panda")`` returns a :class:`RobotSpec`."""

from __future__ import annotations

import importlib
from collections.abc import Callable

from robot_models.cameras import CameraLayout
from robot_models.sensors import SensorLayout
from robot_models.spec import (
    ArmScene,
    GraspLimits,
    JointLimits,
    Obstacle,
    RobotModelError,
    RobotSpec,
    UnknownRobotError,
    UnknownSceneError,
    WalkingLimits,
)

_REGISTRY: dict[str, Callable[..., RobotSpec]] = {}


def _g1(scene: str | None) -> RobotSpec:
    from robot_models import g1

    return g1.load(scene) if scene else g1.load()


def _panda(scene: str | None) -> RobotSpec:
    from robot_models import panda

    return panda.load(scene) if scene else panda.load()


_REGISTRY["g1"] = _g1
_REGISTRY["panda"] = _panda

ROBOT_NAMES: tuple[str, ...] = tuple(sorted(_REGISTRY))


def load(name: str, scene: str | None = None) -> RobotSpec:
    """Build the named robot in one of its scenes (``None`` = the robot's default scene).

    Raises:
        UnknownRobotError: the name is not registered; the message lists the names that are.
        UnknownSceneError: the robot has no such scene; the message lists its scenes.
    """
    try:
        factory = _REGISTRY[name]
    except KeyError:
        raise UnknownRobotError(f"unknown robot {name!r}; known robots: {', '.join(ROBOT_NAMES)}") from None
    return factory(scene)


def sensors_of(name: str) -> SensorLayout:
    """A robot's sensor layout (and battery pack) without building its model: cheap, for nodes that need only names.

    Each robot module ``robot_models.<name>`` defines it as ``SENSORS``.

    Raises:
        UnknownRobotError: the name is not registered; the message lists the names that are.
    """
    if name not in _REGISTRY:
        raise UnknownRobotError(f"unknown robot {name!r}; known robots: {', '.join(ROBOT_NAMES)}")
    layout = getattr(importlib.import_module(f"robot_models.{name}"), "SENSORS", SensorLayout())
    if not isinstance(layout, SensorLayout):
        raise RobotModelError(f"robot_models.{name}.SENSORS is not a SensorLayout")
    return layout


def cameras_of(name: str) -> tuple[CameraLayout, ...]:
    """A robot's cameras (names, frames, tilt ranges), from its module's ``CAMERAS`` (else from its model).

    Raises:
        UnknownRobotError: the name is not registered; the message lists the names that are.
    """
    if name not in _REGISTRY:
        raise UnknownRobotError(f"unknown robot {name!r}; known robots: {', '.join(ROBOT_NAMES)}")
    cameras = getattr(importlib.import_module(f"robot_models.{name}"), "CAMERAS", None)
    return tuple(cameras) if cameras is not None else load(name).cameras


__all__ = [
    "ROBOT_NAMES", "ArmScene", "GraspLimits", "JointLimits", "Obstacle", "RobotModelError", "RobotSpec", "UnknownRobotError",
    "UnknownSceneError", "WalkingLimits", "cameras_of", "load", "sensors_of",
]
