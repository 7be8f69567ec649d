"""The G1's head camera through /sim, /head and /camera, from a client in another process (issue 12 item 3).

The images are real renderings of the simulation (EGL on the CPU); the tilt is a servo turning the mount
under physics. Every check compares the image with a fact computed independently: the intrinsics from the
model's field of view, the shift of the picture from the tilt the joint reports, brightness from exposure.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from sensor_msgs.msg import CameraInfo, Image, JointState
from tf2_msgs.msg import TFMessage

import robot_models
from sim_interfaces.action import Walk
from sim_interfaces.srv import Reset
from sim_ros.stamps import seconds_of
from tests.ros.actions import ready_client
from tests.ros.processes import running

pytestmark = pytest.mark.slow
CAMERA = "head_camera"
SWAY_BRIGHTNESS = 10.0  # [of 255] a change of the picture's mean brightness larger than the standing sway makes


@pytest.fixture(scope="module")
def g1(client):
    with running(["bringup", "--robot", "g1", "--rtf", "1.0"]) as process:
        ready_client(client, Walk, "/walk", timeout=90.0)  # /sim and the servers are up
        client.wait_for(lambda: client.parameters("head").services_are_ready()
                        and client.parameters("camera").services_are_ready(), 60.0, "/head and /camera")
        yield process


@pytest.fixture(scope="module")
def layout() -> robot_models.cameras.CameraLayout:
    return next(c for c in robot_models.cameras_of("g1") if c.name == CAMERA)


def pixels(msg: Image) -> np.ndarray:
    assert msg.encoding == "rgb8" and msg.step == 3 * msg.width
    return np.frombuffer(bytes(msg.data), dtype=np.uint8).reshape(msg.height, msg.width, 3)


def frame_after(client, images, t: float, what: str) -> Image:
    """The first image stamped after sim time ``t``."""
    def ready() -> Image | None:
        fresh = [m for m in images.messages() if seconds_of(m.header.stamp) > t]
        return fresh[0] if fresh else None

    return client.wait_for(ready, 60.0, what)


def tilt_reached(client, joints, name: str, target: float, tolerance: float = 0.01) -> float:
    """Sim time at which the mount's joint is within ``tolerance`` of ``target`` (waits for it)."""
    def ready() -> float | None:
        latest = joints.latest
        if latest is None or name not in latest.name:
            return None
        angle = latest.position[list(latest.name).index(name)]
        return seconds_of(latest.header.stamp) if abs(angle - target) < tolerance else None

    return client.wait_for(ready, 30.0, f"{name} at {target} rad")


def vertical_shift_px(before: np.ndarray, after: np.ndarray, max_shift: int) -> int:
    """Rows by which ``after``'s picture moved up relative to ``before`` (best match of the row profiles)."""
    a = before.mean(axis=(1, 2))
    b = after.mean(axis=(1, 2))
    rows = len(a)
    errors = {}
    for shift in range(-max_shift, max_shift + 1):  # after[r] ~ before[r + shift]
        lo, hi = max(0, -shift), min(rows, rows - shift)
        errors[shift] = float(np.mean((b[lo:hi] - a[lo + shift:hi + shift]) ** 2))
    return min(errors, key=errors.__getitem__)


def test_images_and_camera_info_match_the_model(client, g1, layout):
    images = client.record(Image, f"/{CAMERA}/image_raw", keep=50)
    infos = client.record(CameraInfo, f"/{CAMERA}/camera_info", keep=200)
    image = client.wait_for(lambda: images.latest, 60.0, "a head camera image")
    client.wait_for(lambda: any(i.header.stamp == image.header.stamp for i in infos.messages()), 30.0,
                    "the camera info of that image")
    info = next(i for i in infos.messages() if i.header.stamp == image.header.stamp)
    assert image.header.frame_id == info.header.frame_id == layout.optical_frame
    assert (image.width, image.height) == (info.width, info.height)
    fy = (image.height / 2.0) / math.tan(math.radians(layout.fovy_deg) / 2.0)
    assert info.k[4] == pytest.approx(fy, rel=1e-6) and info.k[0] == pytest.approx(fy, rel=1e-6)
    assert (info.k[2], info.k[5]) == pytest.approx(((image.width - 1) / 2.0, (image.height - 1) / 2.0), abs=0.51)
    picture = pixels(image)
    assert picture.std() > 5.0, "the image shows something (not a blank frame)"
    images.stop()
    infos.stop()


def test_frames_come_at_camera_rate_in_sim_time(client, g1):
    ok, reason = client.set_parameter("camera", "camera_rate", 20.0)
    assert ok, reason
    images = client.record(Image, f"/{CAMERA}/image_raw", keep=100)

    def last_gaps() -> np.ndarray:
        return np.diff([seconds_of(m.header.stamp) for m in images.messages()][-10:])

    # /camera hands the new rate to /sim on a latched topic, so the first frames recorded may still
    # come at the old rate (10 Hz): wait until the rate has changed.
    # Frames ride along /sim's publication stops (every 5 ms of sim time at the default joint_state_rate).
    client.wait_for(lambda: images.count >= 12 and abs(float(np.median(last_gaps())) - 0.05) <= 0.011,
                    60.0, "ten frames at 20 Hz of sim time")
    gaps = last_gaps()
    assert np.median(gaps) == pytest.approx(0.05, abs=0.011), gaps
    images.stop()


def test_tilting_the_head_moves_the_floor_up_the_image_by_what_the_optics_predict(client, g1, layout):
    joints = client.record(JointState, "/joint_states", keep=5)
    images = client.record(Image, f"/{CAMERA}/image_raw", keep=20)
    assert layout.tilt_joint is not None
    ok, reason = client.set_parameter("head", "head_tilt_angle", 0.0)
    assert ok, reason
    level = pixels(frame_after(client, images, tilt_reached(client, joints, layout.tilt_joint, 0.0), "a level frame"))
    ok, reason = client.set_parameter("head", "head_tilt_angle", 0.2)
    assert ok, reason
    reached = tilt_reached(client, joints, layout.tilt_joint, 0.2)
    down = frame_after(client, images, reached + 0.1, "a frame 0.2 rad down")
    tilted = pixels(down)
    fy = (down.height / 2.0) / math.tan(math.radians(layout.fovy_deg) / 2.0)
    expected = fy * math.tan(0.2)
    shift = vertical_shift_px(level, tilted, max_shift=int(2 * expected))
    assert shift == pytest.approx(expected, rel=0.25), f"the picture moved {shift} px up; a 0.2 rad tilt predicts {expected:.0f}"
    ok, reason = client.set_parameter("head", "head_tilt_angle", 0.0)
    assert ok, reason
    joints.stop()
    images.stop()


def test_tf_carries_the_optical_frame_on_the_tilt_mount(client, g1, layout):
    tf = client.record(TFMessage, "/tf", keep=2000)

    def parent_of(child: str) -> str | None:
        for m in tf.messages():
            for t in m.transforms:
                if t.child_frame_id == child:
                    return t.header.frame_id
        return None

    client.wait_for(lambda: parent_of(layout.optical_frame), 30.0, f"{layout.optical_frame} on /tf")
    chain, frame = [], layout.optical_frame
    while frame is not None and frame != "pelvis" and len(chain) < 10:
        chain.append(frame)
        frame = parent_of(frame)
    assert frame == "pelvis", f"{layout.optical_frame} reaches the robot's base in /tf: {chain}"
    tf.stop()


def test_exposure_brightens_monotonically_and_saturates(client, g1):
    images = client.record(Image, f"/{CAMERA}/image_raw", keep=20)
    ok, reason = client.set_parameter("camera", "camera_exposure", 10.0)
    assert ok, reason
    client.wait_for(lambda: images.count >= 3, 60.0, "frames")
    before = float(pixels(images.latest).mean())
    means = []
    for exposure in (2.0, 10.0, 40.0, 100.0):
        ok, reason = client.set_parameter("camera", "camera_exposure", exposure)
        assert ok, reason
        # The setting travels /camera -> /sim on a latched topic, a moment later under load. The standing
        # robot sways (its head with it: the mean moves ~1 of 255), far less than any of these exposure
        # steps changes it (>= 30), so the picture's brightness jumps when, and only when, the setting arrives.
        client.wait_for(lambda before=before: abs(float(pixels(images.latest).mean()) - before) > SWAY_BRIGHTNESS,
                        60.0, f"a frame at exposure {exposure} ms")
        since = images.count
        client.wait_for(lambda since=since: images.count >= since + 2, 60.0, "frames at the new exposure")
        picture = pixels(images.latest)
        means.append((float(picture.mean()), float((picture == 255).mean())))
        before = means[-1][0]
    brightness = [m for m, _ in means]
    assert brightness == sorted(brightness) and brightness[-1] > brightness[0] + 40, means
    assert means[-1][1] > means[1][1] + 0.2, f"long exposures saturate: {means}"
    ok, reason = client.set_parameter("camera", "camera_exposure", 10.0)
    assert ok, reason
    images.stop()


def test_out_of_range_settings_are_refused_with_the_range_and_nothing_changes(client, g1, layout):
    high = layout.tilt_range_rad[1]
    ok, reason = client.set_parameter("head", "head_tilt_angle", high + 1.0)
    assert not ok and f"{high}" in reason, reason
    assert client.get_parameter("head", "head_tilt_angle") == pytest.approx(0.0)
    for name, value in (("camera_exposure", 0.0), ("camera_rate", 1000.0), ("image_width", 100000)):
        ok, reason = client.set_parameter("camera", name, value)
        assert not ok and reason, (name, reason)
    images = client.record(Image, f"/{CAMERA}/image_raw", keep=5)
    client.wait_for(lambda: images.count >= 2, 60.0, "frames still coming")
    images.stop()


def test_a_new_image_size_applies_live_and_a_reset_keeps_the_tilt(client, g1, layout):
    images = client.record(Image, f"/{CAMERA}/image_raw", keep=20)
    for name, value in (("image_width", 160), ("image_height", 120)):
        ok, reason = client.set_parameter("camera", name, value)
        assert ok, reason
    client.wait_for(lambda: images.latest is not None and (images.latest.width, images.latest.height) == (160, 120),
                    60.0, "a 160x120 frame")
    assert layout.tilt_joint is not None
    joints = client.record(JointState, "/joint_states", keep=5)
    ok, reason = client.set_parameter("head", "head_tilt_angle", 0.3)
    assert ok, reason
    tilt_reached(client, joints, layout.tilt_joint, 0.3)
    response = client.call(Reset, "/sim/reset", Reset.Request(), timeout=60.0)
    assert response.success, response.message
    tilt_reached(client, joints, layout.tilt_joint, 0.3)  # the commanded tilt, not the keyframe's
    for name, value in (("image_width", 320), ("image_height", 240)):
        client.set_parameter("camera", name, value)
    client.set_parameter("head", "head_tilt_angle", 0.0)
    joints.stop()
    images.stop()
