"""Every action a scenario may send goals to, each defined once.

An :class:`ActionKind` holds its generated action type (its error codes are read from the
``Result`` constants), what a robot needs to have it, how its goal fields are parsed and how the
goal message is built. To add one, add it to :data:`ACTIONS`; the schema, the runner and
``scenario kinds`` take it from there.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from sim_client.scenario.model.fields import Fields
from sim_client.scenario.model.robots import RobotFacts
from sim_interfaces.action import MoveArm, NavigateToPose, PickPlace, Walk


def error_code_names(action_type: Any) -> tuple[str, ...]:
    """The names of an action's result error codes, by value: the upper-case int constants of its ``Result``."""
    constants = {name: getattr(action_type.Result, name) for name in dir(action_type.Result) if name.isupper()}
    codes = {name: value for name, value in constants.items() if isinstance(value, int) and not isinstance(value, bool)}
    return tuple(sorted(codes, key=lambda name: (codes[name], name)))


@dataclass(frozen=True)
class ActionKind:
    """One action a scenario may send goals to.

    Attributes:
        name: the YAML name (``walk``).
        action_type: the generated ``sim_interfaces.action`` type; its result constants are the error codes.
        available: whether a robot has it (which servers bringup starts for it).
        parse_goal: ``(fields, robot) -> goal fields`` from the ``goal:`` mapping.
        make_goal: ``(client class, goal fields) -> goal message``, with the client's ``goal`` helper.
        fields: the goal's keys, for the README.
    """

    name: str
    action_type: Any
    available: Callable[[RobotFacts], bool]
    parse_goal: Callable[[Fields, RobotFacts], dict[str, Any]]
    make_goal: Callable[[Any, dict[str, Any]], Any]
    fields: str = ""
    error_names: tuple[str, ...] = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "error_names", error_code_names(self.action_type))


def _walk_goal(f: Fields, robot: RobotFacts) -> dict[str, Any]:
    return {"distance": f.required_number("distance", unit=" [m]"), "speed": f.number("speed", 0.0, unit=" [m/s]"),
            "timeout": f.number("timeout", 0.0, unit=" [s]")}


def _navigate_goal(f: Fields, robot: RobotFacts) -> dict[str, Any]:
    return {"x": f.required_number("x"), "y": f.required_number("y"), "yaw": f.number("yaw", 0.0),
            "frame": f.string("frame", "odom")}


def _move_arm_goal(f: Fields, robot: RobotFacts) -> dict[str, Any]:
    goal = {"position": f.required_vector3("position", unit=" [m]"), "rpy": f.optional_vector3("rpy", unit=" [rad]"),
            "arm": f.string("arm", ""), "position_tolerance": f.number("position_tolerance", 0.005),
            "orientation_tolerance": f.number("orientation_tolerance", 0.0),
            "max_velocity_scaling": f.number("max_velocity_scaling", 0.0), "timeout": f.number("timeout", 0.0),
            "frame": f.string("frame", "world")}
    # An unknown arm is allowed on purpose (bad-goal stories), but a typo is worth a clear note.
    goal["arm_known"] = goal["arm"] in ("", *robot.arms)
    return goal


def _pick_place_goal(f: Fields, robot: RobotFacts) -> dict[str, Any]:
    return {"object": f.required_string("object"), "place": f.required_vector3("place", unit=" [m]"), "arm": f.string("arm", ""),
            "timeout": f.number("timeout", 0.0)}


def _make_move_arm(client: Any, g: dict[str, Any]) -> Any:
    return client.goal(*g["position"], rpy=g["rpy"], arm=g["arm"], position_tolerance=g["position_tolerance"],
                       orientation_tolerance=g["orientation_tolerance"], max_velocity_scaling=g["max_velocity_scaling"],
                       timeout=g["timeout"], frame=g["frame"])


_ACTION_LIST = (
    ActionKind("walk", Walk, lambda robot: robot.walks, _walk_goal,
               lambda client, g: client.goal(g["distance"], g["speed"], g["timeout"]), "distance, speed, timeout"),
    ActionKind("navigate", NavigateToPose, lambda robot: robot.walks, _navigate_goal,
               lambda client, g: client.goal(g["x"], g["y"], g["yaw"], g["frame"]), "x, y, yaw, frame"),
    ActionKind("move_arm", MoveArm, lambda robot: bool(robot.arms), _move_arm_goal, _make_move_arm,
               "position [x,y,z], rpy [r,p,y] (omit = position only), arm, position_tolerance, orientation_tolerance, "
               "max_velocity_scaling, timeout, frame"),
    ActionKind("pick_place", PickPlace, lambda robot: bool(robot.objects) and robot.grips, _pick_place_goal,
               lambda client, g: client.goal(g["object"], g["place"], arm=g["arm"], timeout=g["timeout"]),
               "object, place [x,y,z], arm, timeout"),
)
ACTIONS: dict[str, ActionKind] = {kind.name: kind for kind in _ACTION_LIST}
STATUS_NAMES = ("SUCCEEDED", "ABORTED", "CANCELED", "REJECTED")
# Any action's error code, and REJECTED (the name of a goal that was refused).
ERROR_NAMES_ANY = tuple(sorted({name for kind in _ACTION_LIST for name in kind.error_names} | {"REJECTED"}))


def actions_of(robot: RobotFacts) -> tuple[str, ...]:
    """The actions ``robot`` has, in the order of :data:`ACTIONS`."""
    return tuple(name for name, kind in ACTIONS.items() if kind.available(robot))
