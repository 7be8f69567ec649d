"""Where a robot's cameras sit: name, MuJoCo camera, optical frame, field of view and tilt mount.

Each robot module describes its cameras with :class:`CameraLayout` values (names only, as
``CAMERAS``) and calls :func:`add_optical_camera` on its spec to put each one in the model: a body
with ROS optical axes (z forward out of the lens, x right, y down in the image), so the sim's /tf
carries it, and inside it the MuJoCo camera, which looks along its own -z with +y up (rotated
180 deg about x from the optical frame). Cameras change nothing of the physics.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from robot_models.validation import check_range, is_number

if TYPE_CHECKING:  # mujoco is imported where a spec is edited: the layouts are read without it
    import mujoco

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]

# (w, x, y, z) of the optical frame in a ROS body frame (x forward, y left, z up): optical z = body x,
# optical x = -body y, optical y = -body z (REP 103's ``*_optical_frame``).
OPTICAL_IN_BODY_QUAT: Quat = (0.5, -0.5, 0.5, -0.5)
# (w, x, y, z) of a MuJoCo camera (looks along -z, +y up) in an optical frame: 180 deg about x.
MJ_CAMERA_IN_OPTICAL_QUAT: Quat = (0.0, 1.0, 0.0, 0.0)

SKY_TEXTURE = "camera_sky"
FLOOR_MATERIAL = "camera_floor"
SUN_LIGHT = "camera_sun"
SKY_ZENITH_RGB: Vec3 = (0.35, 0.55, 0.85)
SKY_HORIZON_RGB: Vec3 = (0.7, 0.8, 0.95)
FLOOR_RGB: Vec3 = (0.45, 0.45, 0.45)
FLOOR_DARK_FACTOR = 0.7  # the checker's darker squares [fraction of FLOOR_RGB]
FLOOR_SQUARE_M = 1.0  # side of a checker square [m]


@dataclass(frozen=True)
class CameraLayout:
    """A camera of the robot's scene.

    Attributes:
        name: camera name; its ROS topics are ``/<name>/image_raw`` and ``/<name>/camera_info``.
        mj_camera: the MuJoCo camera's name in the model.
        optical_frame: a body in the model with ROS optical axes (z forward out of the lens, x right,
            y down in the image), so that /tf carries it.
        fovy_deg: vertical field of view [deg].
        tilt_joint: hinge of the tilt mount (pitch; + looks down), None for a fixed camera.
        tilt_range_rad: allowed tilt [rad].
        default_tilt_rad: tilt at start-up [rad].
    """

    name: str
    mj_camera: str
    optical_frame: str
    fovy_deg: float
    tilt_joint: str | None = None
    tilt_range_rad: tuple[float, float] = (0.0, 0.0)
    default_tilt_rad: float = 0.0

    def __post_init__(self) -> None:
        check_range(f"camera {self.name!r}: fovy", self.fovy_deg, 0, 180, low_open=True, high_open=True, unit="deg")
        low, high = self.tilt_range_rad
        if not (is_number(low) and is_number(high)):
            raise ValueError(f"camera {self.name!r}: the tilt range must be finite, got [{low}, {high}] rad")
        check_range(f"camera {self.name!r}: the default tilt", self.default_tilt_rad, low, high, unit="rad")
        if self.tilt_joint is None and (low, high) != (0.0, 0.0):
            raise ValueError(f"camera {self.name!r} has no tilt joint but a tilt range [{low}, {high}] rad")


def add_optical_camera(parent: mujoco.MjsBody, layout: CameraLayout, pos: Vec3, quat: Quat) -> mujoco.MjsBody:
    """Add a camera's optical-frame body (welded to ``parent``) holding its MuJoCo camera.

    The body is kept out of static-body fusion (``fuse = 0``) so it exists in the compiled model; it
    has no mass, no joint and no geom.

    Args:
        parent: the body the camera is fixed to.
        layout: names and field of view.
        pos: the optical frame's origin (the lens) in ``parent`` [m].
        quat: the optical frame's orientation in ``parent`` (w, x, y, z); for a parent with ROS body
            axes looking the camera along its x axis, :data:`OPTICAL_IN_BODY_QUAT`.

    Returns:
        The optical-frame body.
    """
    optical = parent.add_body(name=layout.optical_frame, pos=list(pos), quat=list(quat))
    optical.fuse = 0
    optical.add_camera(name=layout.mj_camera, quat=list(MJ_CAMERA_IN_OPTICAL_QUAT), fovy=layout.fovy_deg)
    return optical


def prepare_scene_for_cameras(spec: mujoco.MjSpec, offscreen_size: tuple[int, int] = (1280, 720)) -> str:
    """Make a scene fit for its cameras: an offscreen buffer, even light, a sky, a grey floor.

    - MuJoCo's offscreen buffer (640 x 480 by default) limits the images a renderer may make; it is
      raised to ``offscreen_size``.
    - A directional light from above (no shadows, so it costs one light in the shader) lights what
      any camera sees wherever it stands; the headlight adds a little ambient light.
    - A blue gradient sky (a skybox) and a plain neutral grey floor material (as Gazebo's ground
      plane; scenario videos dress the floor with a grid of their own), so that the floor is told
      from the sky by colour (the sky's blue exceeds its red by >= 0.15; the floor is grey).

    Args:
        spec: the scene.
        offscreen_size: (width, height) of the largest image [px].

    Returns:
        The name of the floor material (assign it to the floor geom).
    """
    import mujoco

    spec.visual.global_.offwidth, spec.visual.global_.offheight = offscreen_size
    spec.visual.headlight.ambient = [0.2, 0.2, 0.2]
    spec.visual.headlight.diffuse = [0.25, 0.25, 0.25]
    spec.add_texture(name=SKY_TEXTURE, type=mujoco.mjtTexture.mjTEXTURE_SKYBOX, builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
                     rgb1=list(SKY_ZENITH_RGB), rgb2=list(SKY_HORIZON_RGB), width=256, height=1536)
    spec.visual.rgba.haze = [*SKY_HORIZON_RGB, 1.0]  # where the floor plane meets the sky (white by default)
    # A checker of 1 m squares in two greys (as Gazebo's and Isaac's default grounds): the floor shows distance and
    # motion in the images (a plain floor gives an image nothing to track), and stays grey against the sky.
    spec.add_texture(name=FLOOR_MATERIAL, type=mujoco.mjtTexture.mjTEXTURE_2D, builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
                     rgb1=list(FLOOR_RGB), rgb2=[c * FLOOR_DARK_FACTOR for c in FLOOR_RGB], width=512, height=512)
    floor = spec.add_material(name=FLOOR_MATERIAL, reflectance=0.0, specular=0.0, shininess=0.0,  # no glare
                              texuniform=True, texrepeat=[0.5 / FLOOR_SQUARE_M] * 2)
    floor.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = FLOOR_MATERIAL
    spec.worldbody.add_light(name=SUN_LIGHT, type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL, pos=[0.0, 0.0, 5.0],
                             dir=[0.3, 0.2, -1.0], diffuse=[0.5, 0.5, 0.5], specular=[0.1, 0.1, 0.1], castshadow=False)
    return FLOOR_MATERIAL
