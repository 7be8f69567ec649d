"""``/sim``'s cameras: ``/<camera>/image_raw`` and ``/<camera>/camera_info``, rendered headless.

Each camera of the robot (:attr:`robot_models.RobotSpec.cameras`: the G1's head camera on its tilt
mount, the Panda's scene camera) is rendered from the simulation's own state at the publication stop
at or after each frame falls due (``rate_hz`` of sim time), and only while someone subscribes to its
image or its camera info: a camera nobody watches costs nothing. The state of that instant is copied
and drawn by a render thread (which owns the GL contexts), so the physics steps on while a frame is drawn. A frame is
stamped with the sim time it shows; its ``CameraInfo`` carries the same stamp and intrinsics that match
the rendering (fovy -> fx = fy, principal point at the centre, no distortion), in the camera's optical
frame (z out of the lens, x right, y down), which /tf carries with the robot's links.

The camera's settings come from ``/camera`` (its parameters) on ``/sim/<camera>/settings``; the
tilt of a mounted camera from ``/head`` on ``/sim/<camera>/tilt``: a servo in the simulation turns the
mount, so the image and /tf follow it under physics. Both topics are latched, so a restarted /sim
takes the latest. Exposure scales the scene's linear brightness (``exposure_ms`` / 10 ms), saturating
as a sensor does.
"""

from __future__ import annotations

import contextlib
import functools
import queue
import struct
import threading
from dataclasses import dataclass

import mujoco
import numpy as np
from geometry_msgs.msg import TransformStamped
from rclpy._rclpy_pybind11 import RCLError
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile
from rclpy.serialization import serialize_message
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import Float64
from tf2_msgs.msg import TFMessage

from nodes.sim.handoff import HandOffLock
from robot_models.cameras import CameraLayout
from sim_bridge import Simulation
from sim_bridge.camera import CameraIntrinsics, CameraRenderer, intrinsics
from sim_interfaces.msg import CameraSettings
from sim_ros.camera_settings import DEFAULT_SETTINGS, NOMINAL_EXPOSURE_MS, settings_problem
from sim_ros.names import LATCHED, TF_STATIC_TOPIC, camera_info_topic, camera_settings_topic, camera_tilt_topic, image_topic
from sim_ros.stamps import set_time

IMAGE_QOS = QoSProfile(depth=4)  # a frame is ~0.2-0.9 MB: a slow reader gets the latest few, not seconds of them
# camera_info is ~0.3 kB: 10 s of it at 10 Hz, so a reader that got a frame gets its info (a recorder on a loaded machine
# once had a frame whose info the writer had already dropped)
INFO_QOS = QoSProfile(depth=100)
NANOSECONDS_PER_SECOND = 1_000_000_000
SUBMIT_WAIT_S = 10.0  # longest wait [wall s] for the frame in flight; a CPU frame takes tens of ms
_STAMP_SENTINEL = struct.pack("<iI", 0x2BADF00D, 0x1CEB00DA)


class ImageTemplate:
    """An rgb8 ``sensor_msgs/Image`` of fixed size, serialized once; stamp and pixels are written into the bytes.

    Serializing a 640x480 image through rclpy's message conversion costs milliseconds; copying the pixels into
    a prepared CDR buffer costs tens of microseconds. The template checks its layout when it is built.
    """

    def __init__(self, frame_id: str, width: int, height: int) -> None:
        msg = Image(height=height, width=width, encoding="rgb8", is_bigendian=0, step=3 * width)
        msg.header.frame_id = frame_id
        msg.header.stamp.sec, msg.header.stamp.nanosec = struct.unpack("<iI", _STAMP_SENTINEL)
        self.size = 3 * width * height
        msg.data = bytes(self.size)
        buffer = bytearray(serialize_message(msg))
        self._stamp = buffer.find(_STAMP_SENTINEL)
        self._pixels = len(buffer) - self.size  # a uint8 sequence is the message's last field: its bytes end the buffer
        length = struct.unpack_from("<I", buffer, self._pixels - 4)[0]
        if self._stamp < 0 or length != self.size:
            raise RuntimeError("cannot locate the stamp or the pixels in a serialized Image")
        self._buffer = buffer

    def serialize(self, sim_time: float, rgb: bytes) -> bytes:
        total = round(sim_time * NANOSECONDS_PER_SECOND)
        struct.pack_into("<iI", self._buffer, self._stamp, total // NANOSECONDS_PER_SECOND, total % NANOSECONDS_PER_SECOND)
        self._buffer[self._pixels:] = rgb
        return bytes(self._buffer)


def camera_info_msg(frame_id: str, k: CameraIntrinsics) -> CameraInfo:
    """The intrinsics of an ideal pinhole camera (no distortion), as image_pipeline expects them."""
    msg = CameraInfo(width=k.width, height=k.height, distortion_model="plumb_bob", d=[0.0] * 5,
                     k=list(k.k()), r=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0], p=list(k.p()))
    msg.header.frame_id = frame_id
    return msg


@dataclass
class _Camera:
    layout: CameraLayout
    image_pub: Publisher
    info_pub: Publisher
    exposure_ms: float = DEFAULT_SETTINGS[0]
    rate_hz: float = DEFAULT_SETTINGS[1]
    size: tuple[int, int] = (DEFAULT_SETTINGS[2], DEFAULT_SETTINGS[3])  # width, height [px]
    next_frame: float = 0.0  # sim time [s] the next frame falls due
    renderer: CameraRenderer | None = None
    template: ImageTemplate | None = None
    info: CameraInfo | None = None
    failed: str = ""  # why rendering is impossible here (logged once)


class CameraStreams:
    """The cameras of one simulation (see the module's text).

    Args:
        node: the sim node.
        sim: its simulation.
        lock: the lock that guards ``sim``; ``publish_due``/``on_reset`` are called with it held.
    """

    def __init__(self, node: Node, sim: Simulation, lock: HandOffLock) -> None:
        self._node = node
        self._sim = sim
        self._lock = lock
        self._cameras: list[_Camera] = []
        self._worker = _RenderThread(node, sim)
        group = MutuallyExclusiveCallbackGroup()
        for layout in sim.robot.cameras:
            camera = _Camera(layout, node.create_publisher(Image, image_topic(layout.name), IMAGE_QOS),
                             node.create_publisher(CameraInfo, camera_info_topic(layout.name), INFO_QOS))
            self._cameras.append(camera)
            node.create_subscription(CameraSettings, camera_settings_topic(layout.name),
                                     functools.partial(self._on_settings, camera), LATCHED, callback_group=group)
            if layout.tilt_joint is not None:
                node.create_subscription(Float64, camera_tilt_topic(layout.name),
                                         functools.partial(self._on_tilt, camera), LATCHED, callback_group=group)
        self._publish_fixed_frames(node, sim)

    def _publish_fixed_frames(self, node: Node, sim: Simulation) -> None:
        """A camera fixed in the world (the Panda's scene camera) on /tf_static; a mounted one rides /tf with its links."""
        model = sim.model
        transforms = []
        for layout in sim.robot.cameras:
            body = model.body(layout.optical_frame)
            if int(model.body_parentid[body.id]) != 0:
                continue
            transform = TransformStamped()
            transform.header.frame_id = "world"
            transform.child_frame_id = layout.optical_frame
            p, q = body.pos.tolist(), body.quat.tolist()
            t, r = transform.transform.translation, transform.transform.rotation
            t.x, t.y, t.z = p[0], p[1], p[2]
            r.w, r.x, r.y, r.z = q[0], q[1], q[2], q[3]
            transforms.append(transform)
        if transforms:
            self._static_pub = node.create_publisher(TFMessage, TF_STATIC_TOPIC, LATCHED)
            self._static_pub.publish(TFMessage(transforms=transforms))

    def __len__(self) -> int:
        return len(self._cameras)

    # ----- inputs (executor threads) ---------------------------------------------------------
    def _on_settings(self, camera: _Camera, msg: CameraSettings) -> None:
        problem = settings_problem(msg)
        if problem:
            self._node.get_logger().warning(f"{camera.layout.name} settings from /camera refused: {problem}")
            return
        with self._lock:
            camera.exposure_ms, camera.rate_hz = float(msg.exposure_ms), float(msg.rate_hz)
            camera.size = (int(msg.width), int(msg.height))  # a new size takes a new renderer at the next frame
            camera.next_frame = min(camera.next_frame, self._sim.time + 1.0 / camera.rate_hz)

    def _on_tilt(self, camera: _Camera, msg: Float64) -> None:
        with self._lock:
            try:
                self._sim.set_camera_tilt(camera.layout.name, float(msg.data))
            except ValueError as error:
                self._node.get_logger().warning(f"{camera.layout.name} tilt from /head refused: {error}")

    # ----- frames ----------------------------------------------------------------------------------
    def publish_due(self, now: float) -> None:
        """Under the lock, at every publication stop (from the physics thread, or a service stepping a paused sim):
        hand each camera whose frame fell due, while it is watched, to the render thread."""
        for camera in self._cameras:
            if now + 1e-9 < camera.next_frame:
                continue
            period = 1.0 / camera.rate_hz
            camera.next_frame = camera.next_frame + period if camera.next_frame + period > now else now + period
            if camera.failed or (camera.image_pub.get_subscription_count() == 0
                                 and camera.info_pub.get_subscription_count() == 0):
                continue
            data = self._sim.data
            self._worker.submit(_Frame(camera, now, data.qpos.copy(), data.mocap_pos.copy(), data.mocap_quat.copy(),
                                       camera.exposure_ms / NOMINAL_EXPOSURE_MS, camera.size))

    def on_reset(self) -> None:
        """After a reset: frames fall due from the new sim time."""
        for camera in self._cameras:
            camera.next_frame = self._sim.time

    def close(self) -> None:
        """Stop the render thread (it frees the GL contexts it made)."""
        self._worker.stop()


@dataclass(frozen=True)
class _Frame:
    """A frame to render: the camera, the sim time it shows and the state then (copies), its settings."""

    camera: _Camera
    sim_time: float
    qpos: np.ndarray
    mocap_pos: np.ndarray
    mocap_quat: np.ndarray
    exposure_gain: float
    size: tuple[int, int]


class _RenderThread:
    """Renders and publishes frames on a thread of its own, which owns every GL context.

    An OpenGL context is current on one thread at a time, and ``/sim`` publishes from two (its physics
    thread, and the service thread that steps a paused sim); so one thread renders them all. A frame is
    rendered from a copy of the state at its sim time, so the picture is the same whenever it is drawn;
    one frame is in flight at a time: the next hand-over waits for it, so no frame is dropped and a sim
    that renders faster than it steps is slowed to the camera (the second CPU core renders while the
    physics steps).
    """

    def __init__(self, node: Node, sim: Simulation) -> None:
        self._node = node
        self._model = sim.model
        self._frames: queue.Queue[_Frame | None] = queue.Queue(maxsize=1)
        self._thread: threading.Thread | None = None

    def submit(self, frame: _Frame) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="camera", daemon=True)
            self._thread.start()
        try:
            self._frames.put(frame, timeout=SUBMIT_WAIT_S)
        except queue.Full:  # the render thread is gone (the context shut down): the physics must not wait for it
            frame.camera.failed = "the render thread stopped"

    def stop(self) -> None:
        if self._thread is not None:
            with contextlib.suppress(queue.Full):  # (a thread that ended with the context takes nothing more)
                self._frames.put(None, timeout=10.0)
            self._thread.join(timeout=10.0)
            self._thread = None

    def _run(self) -> None:
        data = mujoco.MjData(self._model)  # the state a frame shows, copied in
        renderers: list[CameraRenderer] = []
        try:
            while (frame := self._frames.get()) is not None:
                camera = frame.camera
                try:
                    renderer = self._renderer(camera, frame.size)
                except Exception as error:  # noqa: BLE001 - no GL here: say so once, keep simulating
                    camera.failed = f"{type(error).__name__}: {error}"
                    self._node.get_logger().error(
                        f"cannot render {camera.layout.name} ({camera.failed}); its images are off. Headless rendering "
                        "needs MUJOCO_GL=egl (or osmesa) and the GL libraries")
                    continue
                if renderer not in renderers:
                    renderers.append(renderer)
                try:
                    self._publish(camera, renderer, frame, data)
                except RCLError:
                    raise
                except Exception as error:  # noqa: BLE001 - a failed frame must not stop the thread the physics hands frames to
                    camera.failed = f"{type(error).__name__}: {error}"
                    self._node.get_logger().error(f"rendering {camera.layout.name} failed ({camera.failed}); its images are off")
        except RCLError:
            if self._node.context.ok():
                raise
        finally:
            for renderer in renderers:
                renderer.close()

    def _publish(self, camera: _Camera, renderer: CameraRenderer, frame: _Frame, data: mujoco.MjData) -> None:
        assert camera.template is not None and camera.info is not None
        if camera.image_pub.get_subscription_count() > 0:
            data.qpos[:], data.mocap_pos[:], data.mocap_quat[:] = frame.qpos, frame.mocap_pos, frame.mocap_quat
            rgb = renderer.render(data, frame.exposure_gain)
            camera.image_pub.publish(camera.template.serialize(frame.sim_time, rgb.tobytes()))
        set_time(camera.info.header.stamp, frame.sim_time)
        camera.info_pub.publish(camera.info)

    def _renderer(self, camera: _Camera, size: tuple[int, int]) -> CameraRenderer:
        """The camera's renderer at this size, made on this thread when first needed (or when the size changed)."""
        if camera.renderer is not None:
            shown = camera.renderer.intrinsics
            if (shown.width, shown.height) == size:
                return camera.renderer
            camera.renderer.close()
            camera.renderer = None
        width, height = size
        renderer = CameraRenderer(self._model, camera.layout, width, height)
        camera.template = ImageTemplate(camera.layout.optical_frame, width, height)
        camera.info = camera_info_msg(camera.layout.optical_frame, intrinsics(camera.layout, width, height))
        camera.renderer = renderer
        return renderer

