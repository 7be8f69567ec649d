"""The robots by name: the only module that knows every robot module.

Each robot module (``robot_models.g1``, ``robot_models.panda``) builds its scenes from the building
blocks (:mod:`robot_models.spec`, :mod:`~robot_models.cameras`, :mod:`~robot_models.sensors`,
:mod:`~robot_models.physics`) and knows nothing of the others nor of this registry. A robot module
(and with it mujoco and the meshes) is imported only to build a model: the facts known without
building it (sensors, cameras) come from the robot's ``*_layout`` module.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Final

import robot_models.g1_constants as g1_names
import robot_models.g1_layout as g1_layout
import robot_models.panda_constants as panda_names
import robot_models.panda_layout as panda_layout
from robot_models.cameras import CameraLayout
from robot_models.sensors import SensorLayout
from robot_models.spec import RobotModelError, RobotSpec, UnknownRobotError, UnknownSceneError

G1: Final = g1_names.ROBOT_NAME
PANDA: Final = panda_names.ROBOT_NAME


@dataclass(frozen=True)
class RobotEntry:
    """What the registry holds of one robot: how to build it, and the facts known without building it.

    Attributes:
        name: registry name.
        build: builds and compiles the robot in the named scene, with or without its visual meshes.
        default_scene: the scene built when none is named.
        sensors: its sensor layout (and battery pack).
        cameras: its cameras (names, frames, tilt ranges).
        scenes: the scenes it can be built in.
        walks: whether it has feet to walk on (its spec has ``feet_sites`` and ``walking``).
    """

    name: str
    build: Callable[[str, bool], RobotSpec]
    default_scene: str
    sensors: SensorLayout
    cameras: tuple[CameraLayout, ...]
    scenes: tuple[str, ...]
    walks: bool


def _build_g1(scene: str, visuals: bool) -> RobotSpec:
    import robot_models.g1 as g1  # mujoco and the meshes only once a model is built

    return g1.load(scene, visuals)


def _build_panda(scene: str, visuals: bool) -> RobotSpec:
    import robot_models.panda as panda  # mujoco and the meshes only once a model is built

    return panda.load(scene, visuals)


_ROBOTS: Final = {
    entry.name: entry
    for entry in (
        RobotEntry(G1, _build_g1, g1_names.DEFAULT_SCENE, g1_layout.SENSORS, g1_layout.CAMERAS, g1_names.SCENES, walks=True),
        RobotEntry(PANDA, _build_panda, panda_names.DEFAULT_SCENE, panda_layout.SENSORS, panda_layout.CAMERAS, panda_names.SCENES,
                   walks=False),
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


def load(name: str, scene: str | None = None, visuals: bool = True) -> RobotSpec:
    """Build the named robot in one of its scenes (``None`` or ``""`` = the robot's default scene).

    ``visuals=False`` builds a light model (no visual-only geoms and meshes; the same bodies, joints,
    masses, sites and keyframes) for processes that validate goals and resolve frames, not render.

    Raises:
        UnknownRobotError: the name is not registered; the message lists the names that are.
        UnknownSceneError: the robot has no such scene; the message lists its scenes.
    """
    entry = entry_of(name)
    robot = entry.build(scene or entry.default_scene, visuals)
    if (robot.walking is not None and bool(robot.feet_sites)) != entry.walks:  # the registry's fact, checked once built
        raise RobotModelError(f"robot {name!r}: the registry says walks={entry.walks}, its spec says otherwise")
    return robot


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


def check_scene(name: str, scene: str | None = None) -> None:
    """Check that the named robot has that scene (``None`` or ``""`` = its default), without building it.

    Raises:
        UnknownRobotError: the name is not registered; the message lists the names that are.
        UnknownSceneError: the robot has no such scene; the message lists its scenes (as :func:`load` says).
    """
    entry = entry_of(name)
    if scene and scene not in entry.scenes:
        raise UnknownSceneError(f"unknown scene {scene!r} for {entry.name}; scenes: {', '.join(entry.scenes)}")


def scenes_of(name: str) -> tuple[str, ...]:
    """The named robot's scenes, without building its model.

    Raises:
        UnknownRobotError: the name is not registered; the message lists the names that are.
    """
    return entry_of(name).scenes


def scenes_summary() -> str:
    """Every robot's scenes, for help texts: ``"g1: open, course, tables; panda: table"``."""
    return "; ".join(f"{name}: {', '.join(_ROBOTS[name].scenes)}" for name in ROBOT_NAMES)


def walks(name: str) -> bool:
    """Whether the named robot walks (has feet sites and walking limits), without building its model.

    Raises:
        UnknownRobotError: the name is not registered; the message lists the names that are.
    """
    return entry_of(name).walks
