"""What a scenario may ask of a robot, read from its spec in ``robot_models`` (not copied here).

Building a spec compiles its MuJoCo model, so the facts of each robot
and the answer for each scene are computed once per process; both are immutable.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import robot_models


@dataclass(frozen=True)
class RobotFacts:
    """The names a scenario file may use for one robot.

    Attributes:
        name: its name in ``robot_models.ROBOT_NAMES``.
        keyframes: keyframes of the model; the first is the default.
        default_scene: the scene the robot loads when none is named.
        objects: free bodies a scenario may measure and pick (boxes).
        arms: arm names a move_arm goal may name.
        walks: whether it has feet (a floating base that walks: /cmd_vel, walk, navigate).
    """

    name: str
    keyframes: tuple[str, ...]
    default_scene: str
    objects: tuple[str, ...]
    arms: tuple[str, ...]
    walks: bool


@functools.cache
def robot_facts(name: str) -> RobotFacts:
    """The facts of a registered robot (``name`` in ``robot_models.ROBOT_NAMES``)."""
    spec = robot_models.load(name)
    return RobotFacts(name=spec.name, keyframes=tuple(spec.keyframes), default_scene=spec.scene, objects=tuple(spec.objects),
                      arms=tuple(spec.end_effector_sites), walks=bool(spec.feet_sites))


@functools.cache
def scene_problem(robot: str, scene: str) -> str | None:
    """None when ``robot`` has ``scene``; otherwise robot_models' reason, which lists the scenes."""
    try:
        robot_models.load(robot, scene)
    except robot_models.UnknownSceneError as error:
        return str(error)
    return None
