"""One hand on a small object: where the hand goes, fingers that close until they touch, and the grip measured.

The hand is a :class:`~robot_models.hands.HandLayout` resolved against a model (:class:`Hand`). A grasp
puts the object's centre at the hand's grasp point, the fingers pointing along one of the object's
horizontal face normals (the one nearest the robot's heading), the palm facing the robot's midline and
tilted down by ``palm_tilt_rad`` (the fingers and the palm's lower edge stay above the table top).

The fingers close by position servos whose torque is bounded (:class:`FingerCloser`): each finger's target
moves from the open pose toward the closed one until that finger presses on the object with
``touch_force_n``, then stays ``squeeze_rad`` past where it touched, so the servo squeezes with about
``kp * squeeze_rad``. Nothing attaches the object: friction holds it. The grip is measured as the contact
normal forces between each finger (and the palm) and the object.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import mujoco
import numpy as np

from robot_models.hands import HandLayout
from sim_bridge.arm.poses import mat_to_quat
from sim_bridge.entities import descends
from sim_bridge.errors import UnknownNameError
from sim_bridge.fetch.contacts import contacts_on, normal_force, solve_contact_forces
from sim_bridge.state import Pose

PALM = "palm"  # the contacts of the hand's own body (not a finger's)


@dataclass(frozen=True)
class Hand:
    """A hand layout resolved against a model.

    Attributes:
        layout: the robot's facts.
        finger_of_body: body id -> finger name (``PALM`` for the hand body and bodies on no finger joint).
        actuators: joint -> actuator id of every joint of the open pose.
        qpos_adr: joint -> qpos address, same joints.
        closing: joint -> sign of the closing direction (closed - open), same joints.
    """

    layout: HandLayout
    finger_of_body: Mapping[int, str]
    actuators: Mapping[str, int]
    qpos_adr: Mapping[str, int]
    closing: Mapping[str, float]

    @property
    def arm(self) -> str:
        return self.layout.arm


def hand_of(model: mujoco.MjModel, layout: HandLayout) -> Hand:
    """Resolve ``layout``'s names in ``model``.

    Raises:
        UnknownNameError: a body, joint or actuator of the layout is not in the model.
    """
    try:
        root = int(model.body(layout.hand_body).id)
        actuators = {joint: int(model.actuator(joint).id) for joint in layout.open_pose}
        qpos_adr = {joint: int(model.joint(joint).qposadr[0]) for joint in layout.open_pose}
        finger_roots = {finger: [int(model.jnt_bodyid[model.joint(joints[0]).id])] for finger, joints in layout.fingers.items()}
    except KeyError as error:
        raise UnknownNameError(f"hand of {layout.arm!r}: {error}") from error
    finger_of_body: dict[int, str] = {}
    for body in range(model.nbody):
        if not descends(model, body, root):
            continue
        owners = [finger for finger, roots in finger_roots.items() if any(descends(model, body, r) for r in roots)]
        finger_of_body[body] = owners[0] if owners else PALM
    closing = {joint: math.copysign(1.0, layout.closed_pose.get(joint, angle) - angle) if joint in layout.closed_pose
               and layout.closed_pose[joint] != angle else 0.0 for joint, angle in layout.open_pose.items()}
    return Hand(layout, finger_of_body, actuators, qpos_adr, closing)


def grasp_rotation(hand: Hand, object_yaw: float, heading: float, palm_tilt_rad: float) -> np.ndarray:
    """The tool frame's orientation for a grasp, world frame, shape (3, 3).

    The fingers (tool x) point along the object's horizontal face normal nearest ``heading`` [rad] (its yaw
    ``object_yaw`` [rad] modulo a quarter turn); the palm normal faces the robot's midline, tilted down by
    ``palm_tilt_rad`` [rad].
    """
    quarter = math.pi / 2
    yaw = object_yaw + quarter * round(math.remainder(heading - object_yaw, 2 * math.pi) / quarter)
    along = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    left = np.array([-math.sin(yaw), math.cos(yaw), 0.0])
    normal_in_tool = np.asarray(hand.layout.palm_normal_in_tool, dtype=float)
    inward = left if normal_in_tool[1] > 0.0 else -left  # a right hand's palm faces left, and the other way
    normal = math.cos(palm_tilt_rad) * inward - math.sin(palm_tilt_rad) * np.array([0.0, 0.0, 1.0])
    # Tool axes in the world: x along the fingers, the palm normal where the layout has it.
    y_world = normal * normal_in_tool[1]
    return np.column_stack([along, y_world, np.cross(along, y_world)])


def grasp_tool_pose(hand: Hand, object_center: np.ndarray, rotation: np.ndarray,
                    offset_in_tool: np.ndarray | None = None) -> Pose:
    """The tool pose that puts ``object_center`` (world [m]) at the hand's grasp point (or at ``offset_in_tool``
    [m], tool frame), with the tool orientation ``rotation`` (3, 3)."""
    point = np.asarray(hand.layout.grasp_point_in_tool if offset_in_tool is None else offset_in_tool, dtype=float)
    return Pose(np.asarray(object_center, dtype=float) - rotation @ point, mat_to_quat(rotation))


def ready_tool_pose(hand: Hand, object_center: np.ndarray, rotation: np.ndarray, back_m: float, rise_m: float) -> Pose:
    """Where the hand waits before it reaches: its grasp pose for an object at ``object_center`` (world [m]),
    ``back_m`` [m] back against the fingers' direction and ``rise_m`` [m] up, clear above the table top. A hand
    that starts below the table's top reaches into it from underneath: raise it here before walking onto the
    stance (as the fetch raises its palms)."""
    grasp = grasp_tool_pose(hand, object_center, rotation)
    return Pose(grasp.position - back_m * rotation[:, 0] + np.array([0.0, 0.0, rise_m]), grasp.orientation_wxyz)


def finger_forces(model: mujoco.MjModel, data: mujoco.MjData, hand: Hand, body: int, solve: bool = False) -> dict[str, float]:
    """Normal contact force [N] of each finger (and ``PALM``) on the object ``body``; fingers that do not touch: 0.

    Args:
        solve: the contacts are those of the current positions but their forces are not solved yet (inside
            the control step, between ``mj_step1`` and ``mj_step2``): solve them first, when the hand touches
            the object (an object resting on the table alone needs no solve).
    """
    forces = dict.fromkeys([*hand.layout.fingers, PALM], 0.0)
    touching = contacts_on(model, data, body, hand.finger_of_body.get)
    if not touching:
        return forces
    if solve:
        solve_contact_forces(model, data)
    wrench = np.zeros(6)
    for index, finger in touching:
        forces[finger] += normal_force(model, data, index, wrench)
    return forces


def holds(forces: Mapping[str, float], hand: Hand, min_force_n: float) -> bool:
    """The opposing finger and another finger each press on the object with ``min_force_n`` [N] at least."""
    first, *others = hand.layout.fingers
    return forces[first] >= min_force_n and any(forces[f] >= min_force_n for f in others)


class FingerCloser:
    """Drives a hand's servo targets: open, or closing finger by finger until each touches the object.

    Args:
        hand: the hand.
        close_speed: fraction of the open-to-closed travel per second [1/s].
        touch_force_n: a finger pressing this hard on the object has touched it [N].
        squeeze_rad: a touching finger's targets stay this far past its measured angles [rad] (the servo's
            squeeze torque is about kp times this, at most its force limit).
    """

    def __init__(self, hand: Hand, close_speed: float, touch_force_n: float, squeeze_rad: float) -> None:
        self.hand = hand
        self.close_speed = close_speed
        self.touch_force_n = touch_force_n
        self.squeeze_rad = squeeze_rad
        self.closing = False
        self.fraction = dict.fromkeys(hand.layout.fingers, 0.0)  # each finger's travel toward closed, in [0, 1]
        self.touched: dict[str, bool] = dict.fromkeys(hand.layout.fingers, False)

    def open(self, data: mujoco.MjData) -> None:
        """Command the open pose now (the servos move there at their own pace)."""
        self.closing = False
        self.fraction = dict.fromkeys(self.hand.layout.fingers, 0.0)
        self.touched = dict.fromkeys(self.hand.layout.fingers, False)
        for joint, angle in self.hand.layout.open_pose.items():
            data.ctrl[self.hand.actuators[joint]] = angle

    def close(self) -> None:
        """Start closing from the current travel (each finger stops where it touches)."""
        self.closing = True

    @property
    def done(self) -> bool:
        """Every finger touches or has reached the closed pose."""
        return all(self.touched[f] or self.fraction[f] >= 1.0 for f in self.hand.layout.fingers)

    def update(self, data: mujoco.MjData, forces: Mapping[str, float], dt: float) -> None:
        """One control step [s]: advance the fingers that do not touch yet; hold the squeeze of those that do."""
        if not self.closing:
            return
        layout = self.hand.layout
        for finger, joints in layout.fingers.items():
            if not self.touched[finger] and forces[finger] >= self.touch_force_n:
                self.touched[finger] = True
                for joint in joints:  # squeeze from where it touched
                    measured = float(data.qpos[self.hand.qpos_adr[joint]])
                    data.ctrl[self.hand.actuators[joint]] = measured + self.hand.closing[joint] * self.squeeze_rad
            if self.touched[finger]:
                continue
            self.fraction[finger] = min(1.0, self.fraction[finger] + self.close_speed * dt)
            s = self.fraction[finger]
            for joint in joints:
                data.ctrl[self.hand.actuators[joint]] = (1.0 - s) * layout.open_pose[joint] + s * layout.closed_pose[joint]
