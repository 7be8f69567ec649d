"""Camera images of the simulation: rendering, pinhole intrinsics that match it, and exposure.

MuJoCo renders a fixed camera as an ideal pinhole: ``fovy`` is the vertical field of view, the
horizontal one follows from the image's aspect ratio (square pixels), and the optical axis passes
through the image centre. In ROS's pixel convention (a pixel's centre at integer coordinates, as in
OpenCV and ``sensor_msgs/CameraInfo``) that is

    fy = (height / 2) / tan(fovy / 2),  fx = fy,  cx = (width - 1) / 2,  cy = (height - 1) / 2,

a point (x, y, z) in the camera's optical frame (z forward, x right, y down) landing at
(u, v) = (fx x / z + cx, fy y / z + cy). ``tests/core/test_camera.py`` checks it on rendered images.

Rendering runs on the CPU here (EGL on Mesa's llvmpipe), without shadows and without multisampling,
both costly on the CPU; see ``benchmarks/camera_bench.py`` for what a frame costs.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import mujoco
import numpy as np

from robot_models.cameras import CameraLayout

DISPLAY_GAMMA = 2.2  # rendered values are taken as gamma-encoded with this exponent


@dataclass(frozen=True)
class CameraIntrinsics:
    """Pinhole intrinsics of an image, in ROS's pixel convention (see the module's text).

    Attributes:
        width, height: image size [px].
        fx, fy: focal lengths [px].
        cx, cy: principal point [px].
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    def k(self) -> tuple[float, ...]:
        """The 3x3 camera matrix, row-major (``sensor_msgs/CameraInfo.k``)."""
        return (self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0)

    def p(self) -> tuple[float, ...]:
        """The 3x4 projection matrix of a monocular camera, row-major (``sensor_msgs/CameraInfo.p``)."""
        return (self.fx, 0.0, self.cx, 0.0, 0.0, self.fy, self.cy, 0.0, 0.0, 0.0, 1.0, 0.0)


def intrinsics(layout: CameraLayout, width: int, height: int) -> CameraIntrinsics:
    """The intrinsics of ``layout``'s camera rendered at ``width`` x ``height`` [px].

    Raises:
        ValueError: a size is not a positive whole number.
    """
    if width < 1 or height < 1:
        raise ValueError(f"image size must be positive, got {width} x {height}")
    focal = (height / 2.0) / math.tan(math.radians(layout.fovy_deg) / 2.0)
    return CameraIntrinsics(width=width, height=height, fx=focal, fy=focal, cx=(width - 1) / 2.0, cy=(height - 1) / 2.0)


@functools.lru_cache(maxsize=64)
def exposure_table(exposure_gain: float) -> np.ndarray:
    """The 256-entry lookup table of :func:`apply_exposure` for one gain (read-only, memoised).

    Raises:
        ValueError: the gain is not a positive finite number.
    """
    if not (math.isfinite(exposure_gain) and exposure_gain > 0.0):
        raise ValueError(f"exposure gain must be a positive finite number, got {exposure_gain}")
    linear = np.power(np.arange(256) / 255.0, DISPLAY_GAMMA) * exposure_gain
    table = np.rint(255.0 * np.power(np.minimum(linear, 1.0), 1.0 / DISPLAY_GAMMA)).astype(np.uint8)
    table.flags.writeable = False
    return table


def apply_exposure(image: np.ndarray, exposure_gain: float) -> np.ndarray:
    """Scale an image's light as a longer or shorter exposure would, saturating at white.

    Each value is taken as gamma-encoded (gamma :data:`DISPLAY_GAMMA`), made linear, multiplied by
    the gain, clipped at 1 and encoded again: a gain of 2 lets in twice the light; values that reach
    full scale stay there.

    Args:
        image: uint8 array of any shape (e.g. (height, width, 3) RGB).
        exposure_gain: relative exposure (1 = as rendered; > 1 brighter, < 1 darker).

    Returns:
        A new uint8 array of the same shape, or ``image`` itself when the gain is 1.

    Raises:
        ValueError: the gain is not a positive finite number, or the image is not uint8.
    """
    if image.dtype != np.uint8:
        raise ValueError(f"exposure applies to uint8 images, got {image.dtype}")
    table = exposure_table(float(exposure_gain))
    if exposure_gain == 1.0:
        return image
    return table[image]


class CameraRenderer:
    """Renders what one camera of a model sees, as RGB images.

    MuJoCo's renderer holds an OpenGL context that is current on one thread: construct this object
    on the thread that will call :meth:`render`, and call :meth:`close` there when done (or use it
    as a context manager).

    Args:
        model: the compiled model (its offscreen buffer must hold ``width`` x ``height``).
        layout: the camera.
        width, height: image size [px].

    Raises:
        ValueError: the camera is not in the model, or the image is larger than the model's offscreen
            buffer (``model.vis.global_.offwidth`` / ``offheight``).
    """

    def __init__(self, model: mujoco.MjModel, layout: CameraLayout, width: int, height: int) -> None:
        camera_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, layout.mj_camera)
        if camera_id < 0:
            cameras = [model.camera(i).name for i in range(model.ncam)]
            raise ValueError(f"no MuJoCo camera {layout.mj_camera!r} in the model; cameras: {', '.join(cameras)}")
        buffer = (int(model.vis.global_.offwidth), int(model.vis.global_.offheight))
        if width > buffer[0] or height > buffer[1]:
            raise ValueError(f"image {width} x {height} is larger than the model's offscreen buffer {buffer[0]} x {buffer[1]}")
        self.layout = layout
        self._model = model
        self._intrinsics = intrinsics(layout, width, height)
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self._camera.fixedcamid = camera_id
        self._scratch = mujoco.MjData(model)  # the pose is computed here: the caller's data is only read
        # No multisampling (each pixel one sample, as a sensor's pixels; costly on the CPU). The context reads
        # the sample count when it is made; the model's own setting (scenario videos) is kept.
        samples = int(model.vis.quality.offsamples)
        model.vis.quality.offsamples = 0
        try:
            self._renderer: mujoco.Renderer | None = mujoco.Renderer(model, height=height, width=width)
        finally:
            model.vis.quality.offsamples = samples
        # No shadows: a light's shadow map (4096^2 texels) is costly to render on the CPU.
        self._renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False

    @property
    def intrinsics(self) -> CameraIntrinsics:
        return self._intrinsics

    def render(self, data: mujoco.MjData, exposure_gain: float = 1.0) -> np.ndarray:
        """What the camera sees in ``data``'s current configuration.

        The bodies' poses are computed from ``data.qpos`` (and mocap poses) into a private MjData, so the
        image shows the configuration as it is now, and ``data`` is not written.

        Args:
            data: the simulation's state (read only).
            exposure_gain: see :func:`apply_exposure`.

        Returns:
            A C-contiguous (height, width, 3) uint8 RGB array, row 0 at the top of the image.

        Raises:
            RuntimeError: the renderer is closed.
            ValueError: the gain is not a positive finite number.
        """
        if self._renderer is None:
            raise RuntimeError(f"the renderer of camera {self.layout.name!r} is closed")
        exposure_table(float(exposure_gain))  # check the gain before the cost of a frame
        scratch, model = self._scratch, self._model
        scratch.qpos[:] = data.qpos
        scratch.mocap_pos[:] = data.mocap_pos
        scratch.mocap_quat[:] = data.mocap_quat
        mujoco.mj_kinematics(model, scratch)
        mujoco.mj_camlight(model, scratch)
        self._renderer.update_scene(scratch, camera=self._camera)
        return apply_exposure(self._renderer.render(), exposure_gain)

    def close(self) -> None:
        """Free the OpenGL resources (on the thread that rendered). Rendering afterwards raises."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def __enter__(self) -> CameraRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
