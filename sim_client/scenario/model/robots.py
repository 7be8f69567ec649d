"""What a scenario may ask of a robot, read from its spec in ``robot_models`` (not copied here).

Building a spec compiles its MuJoCo model, so the facts of each robot in each scene are computed once
per process (they are immutable); whether a robot has a scene is known without building it.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import robot_models
from robot_models.registry import entry_of


@dataclass(frozen=True)
class RobotFacts:
    """The names a scenario file may use for one robot.

    Attributes:
        name: its name in ``robot_models.ROBOT_NAMES``.
        keyframes: keyframes of the model; the first is the default.
        default_scene: the scene the robot loads when none is named.
        objects: free bodies a scenario may measure and pick (boxes), in the scene the facts were read from.
        arms: arm names a move_arm goal may name.
        walks: whether it has feet (a floating base that walks: /cmd_vel, walk, navigate).
        grips: whether it can pick objects: grippers (a fixed arm) or palms on a walking robot (a fetch).
    """

    name: str
    keyframes: tuple[str, ...]
    default_scene: str
    objects: tuple[str, ...]
    arms: tuple[str, ...]
    walks: bool
    grips: bool


def robot_facts(name: str, scene: str | None = None) -> RobotFacts:
    """The facts of a registered robot (``name`` in ``robot_models.ROBOT_NAMES``) in one of its scenes
    (``None`` or ``""`` = its default scene, which ``default_scene`` names either way)."""
    return _facts(name, scene or entry_of(name).default_scene)


@functools.cache
def _facts(name: str, scene: str) -> RobotFacts:
    spec = robot_models.load(name, scene)
    return RobotFacts(name=spec.name, keyframes=tuple(spec.keyframes), default_scene=entry_of(name).default_scene,
                      objects=tuple(spec.objects), arms=tuple(spec.end_effector_sites), walks=bool(spec.feet_sites),
                      grips=spec.grasp is not None or (bool(spec.palms) and spec.walking is not None))


def scene_problem(robot: str, scene: str) -> str | None:
    """None when ``robot`` has ``scene``; otherwise robot_models' reason, which lists the scenes (no model is built)."""
    try:
        robot_models.check_scene(robot, scene)
    except robot_models.UnknownSceneError as error:
        return str(error)
    return None
