"""Builds /tf messages from the simulation: odom -> base, parent link -> child link, world -> objects."""

from __future__ import annotations

import mujoco
import numpy as np
from geometry_msgs.msg import TransformStamped
from tf2_msgs.msg import TFMessage

from sim_bridge import Simulation
from sim_ros.stamps import set_time


def _relative_transforms(data: mujoco.MjData, parents: np.ndarray, children: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions (n, 3) and quaternions wxyz (n, 4) of children in their parents' frames."""
    parent_rot = data.xmat[parents].reshape(-1, 3, 3)
    delta = data.xpos[children] - data.xpos[parents]
    positions = np.einsum("nji,nj->ni", parent_rot, delta)
    quats = np.empty((len(children), 4))
    inv = np.empty(4)
    for i, (p, c) in enumerate(zip(parents.tolist(), children.tolist(), strict=False)):
        mujoco.mju_negQuat(inv, data.xquat[p])
        mujoco.mju_mulQuat(quats[i], inv, data.xquat[c])
    return positions, quats


class TransformSet:
    """A reusable TFMessage for a fixed list of (parent frame, child frame) body pairs.

    The message objects are built once; each publish only writes numbers into them.
    """

    def __init__(self, sim: Simulation, pairs: list[tuple[str, str]], parent_frame_names: dict[str, str] | None = None) -> None:
        model = sim.model
        rename = parent_frame_names or {}
        self._parents = np.array([model.body(p).id for p, _ in pairs], dtype=int)
        self._children = np.array([model.body(c).id for _, c in pairs], dtype=int)
        self.message = TFMessage()
        transforms = []
        for parent, child in pairs:
            transform = TransformStamped()
            transform.header.frame_id = rename.get(parent, parent)
            transform.child_frame_id = child
            transforms.append(transform)
        self.message.transforms = transforms

    def __len__(self) -> int:
        return len(self._children)

    def update(self, data: mujoco.MjData, sim_time: float) -> TFMessage:
        positions, quats = _relative_transforms(data, self._parents, self._children)
        for transform, p, q in zip(self.message.transforms, positions.tolist(), quats.tolist(), strict=False):
            set_time(transform.header.stamp, sim_time)
            t = transform.transform.translation
            t.x, t.y, t.z = p[0], p[1], p[2]
            r = transform.transform.rotation
            r.w, r.x, r.y, r.z = q[0], q[1], q[2], q[3]
        return self.message


def link_pairs(sim: Simulation) -> list[tuple[str, str]]:
    """(parent, child) body name pairs of the robot's kinematic tree below its base."""
    model = sim.model
    objects = set(sim.robot.objects)
    pairs = []
    for body_id in range(1, model.nbody):
        name = model.body(body_id).name
        parent_id = int(model.body_parentid[body_id])
        if name in objects or name == sim.robot.base_body or parent_id == 0:
            continue
        pairs.append((model.body(parent_id).name, name))
    return pairs
