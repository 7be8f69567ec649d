"""Palm pads on the G1's wrists: contact pads to squeeze a box between both hands.

The Dex3-1 hands' own palms cannot squeeze a flat side: the thumb's root sits on the palm face, so the
thumb stands at least 3 cm proud of it in any pose (11 cm open, straight into what the palm pushes;
4.8 cm tucked along the palm's upper edge, :data:`robot_models.g1_constants.HAND_PALM_POSE`), and a
side meets the thumb alone. So on the inner side of each wrist's yaw link (the hand's palm body), a
pad of four small spheres at the corners of a 10 x 6 cm face stands out past the tucked thumb (one
flat box would touch a flat box side at a single point, about which the held box pitches away; four
points resist that torque), colliding with the scene's objects (and the tables, floor) but not with
the robot itself, with the objects' contact settings (condim 4, friction 1, a stiff ``solref``) so a
squeeze holds by friction. Each pad carries a site at the centre of its contact face, its z axis
along the face's outward normal (from the palm into what it holds). The hands hold
``HAND_PALM_POSE`` while they squeeze (:attr:`robot_models.spec.RobotSpec.palm_hand_pose`).
"""

from __future__ import annotations

import math
from typing import Final

import mujoco

import robot_models.g1_constants as names

PAD_HALF_SIZE: Final = (0.04, 0.03)  # half extents of the face along the hand (x) and up (z) [m]
PAD_SPHERE_RADIUS_M: Final = 0.01
PAD_CENTER_X_M: Final = 0.09  # along the wrist link's x axis, around the hand site [m]
PAD_FACE_Y_M: Final = 0.062  # inward offset of the pad's face from the link's x axis [m] (the tucked thumb: 0.048)
PAD_FRICTION: Final = (1.0, 0.05, 0.001)  # torsional: a palm-sized patch resists twisting
PAD_SOLREF: Final = (0.004, 1.0)
PAD_CONDIM: Final = 4

# arm -> (wrist body, pad geom name prefix, palm site, sign of the inward direction along the link's y axis)
PALMS: Final = {
    "left_arm": (names.LEFT_HAND_BODY, "left_palm_pad", "left_palm", -1.0),
    "right_arm": (names.RIGHT_HAND_BODY, "right_palm_pad", "right_palm", 1.0),
}
PALM_SITES: Final = {arm: site for arm, (_, _, site, _) in PALMS.items()}


def add_palm_pads(spec: mujoco.MjSpec) -> dict[str, str]:
    """Add a pad and its face site to each wrist (before compiling). Returns arm -> palm site name."""
    half = math.sqrt(0.5)
    for body_name, geom, site, inward in PALMS.values():
        body = spec.body(body_name)
        sphere_y = inward * (PAD_FACE_Y_M - PAD_SPHERE_RADIUS_M)
        corners = [(sx, sz) for sx in (-1.0, 1.0) for sz in (-1.0, 1.0)]
        for index, (sx, sz) in enumerate(corners):
            body.add_geom(name=f"{geom}_{index}", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[PAD_SPHERE_RADIUS_M, 0, 0],
                          pos=[PAD_CENTER_X_M + sx * PAD_HALF_SIZE[0], sphere_y, sz * PAD_HALF_SIZE[1]], mass=0.0,
                          condim=PAD_CONDIM, friction=list(PAD_FRICTION), solref=list(PAD_SOLREF),
                          contype=names.SHELL_CONTYPE, conaffinity=0, group=0, rgba=[0.2, 0.2, 0.2, 1.0])
        # z axis along the inward normal: a quarter turn about x (+ turns z to -y, - to +y)
        body.add_site(name=site, pos=[PAD_CENTER_X_M, inward * PAD_FACE_Y_M, 0.0], quat=[half, -inward * half, 0.0, 0.0],
                      size=[0.01] * 3)
    return dict(PALM_SITES)
