"""The robots by name: the only module that knows every robot module.

Each robot module (``robot_models.g1``, ``robot_models.panda``) builds its scenes from the building
blocks (:mod:`robot_models.spec`, :mod:`~robot_models.cameras`, :mod:`~robot_models.sensors`,
:mod:`~robot_models.physics`) and knows nothing of the others nor of this registry.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Final

import robot_models.g1 as g1
import robot_models.g1_constants as g1_names
import robot_models.panda as panda
import robot_models.panda_constants as panda_names
from robot_models.cameras import CameraLayout
from robot_models.sensors import SensorLayout
from robot_models.spec import RobotSpec, UnknownRobotError

G1: Final = g1_names.ROBOT_NAME
PANDA: Final = panda_names.ROBOT_NAME


@dataclass(frozen=True)
class RobotEntry:
    """What the registry holds of one robot: how to build it, and the facts known without building it.

    Attributes:
        name: registry name.
        build: builds and compiles the robot in the named scene.
        default_scene: the scene built when none is named.
        sensors: its sensor layout (and battery pack).
        cameras: its cameras (names, frames, tilt ranges).
    """

    name: str
    build: Callable[[str], RobotSpec]
    default_scene: str
    sensors: SensorLayout
    cameras: tuple[CameraLayout, ...]


_ROBOTS: Final = {
    entry.name: entry
    for entry in (
        RobotEntry(G1, g1.load, g1_names.DEFAULT_SCENE, g1.SENSORS, g1.CAMERAS),
        RobotEntry(PANDA, panda.load, panda_names.DEFAULT_SCENE, panda.SENSORS, panda.CAMERAS),
    )
}

ROBOT_NAMES: tuple[str, ...] = tuple(sorted(_ROBOTS))


def entry_of(name: str) -> RobotEntry:
    """The registered robot of that name.

    Raises:
        UnknownRobotError: the name is not registered; the message lists the names that are.
    """
    try:
        return _ROBOTS[name]
    except KeyError:
        raise UnknownRobotError(f"unknown robot {name!r}; known robots: {', '.join(ROBOT_NAMES)}") from None


def load(name: str, scene: str | None = None) -> RobotSpec:
    """Build the named robot in one of its scenes (``None`` or ``""`` = the robot's default scene).

    Raises:
        UnknownRobotError: the name is not registered; the message lists the names that are.
        UnknownSceneError: the robot has no such scene; the message lists its scenes.
    """
    entry = entry_of(name)
    return entry.build(scene or entry.default_scene)


def sensors_of(name: str) -> SensorLayout:
    """A robot's sensor layout (and battery pack) without building its model: cheap, for nodes that need only names.

    Raises:
        UnknownRobotError: the name is not registered; the message lists the names that are.
    """
    return entry_of(name).sensors


def cameras_of(name: str) -> tuple[CameraLayout, ...]:
    """A robot's cameras (names, frames, tilt ranges) without building its model.

    Raises:
        UnknownRobotError: the name is not registered; the message lists the names that are.
    """
    return entry_of(name).cameras
