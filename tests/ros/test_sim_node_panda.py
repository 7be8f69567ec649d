"""The /sim node with the Panda scene, from a client in another process."""

from __future__ import annotations

import time

import pytest
from sensor_msgs.msg import JointState
from tf2_msgs.msg import TFMessage

from robot_models import panda_constants
from sim_interfaces.msg import ObjectStates
from sim_ros.session import WaitTimeout
from tests.ros.processes import running

STARTUP_S = 60.0


@pytest.fixture(scope="class")
def panda(client):
    """A Panda sim node for the tests of one class (ended with it, before the lifecycle test starts its own)."""
    with running(["sim_node", "--ros-args", "-p", "robot:=panda", "-p", "real_time_factor:=0.0"]) as process:
        yield process


class TestRunning:
    """The tests that only watch a running Panda sim node share one."""

    def test_panda_publishes_its_joints_and_the_boxes(self, client, panda):
        objects = client.record(ObjectStates, "/objects")
        joints = client.record(JointState, "/joint_states")
        client.wait_for(lambda: objects.count > 2 and joints.count > 2, STARTUP_S, "/objects and /joint_states from the panda")
        names = list(objects.latest.names)
        assert names == list(panda_constants.BOX_NAMES)
        for pose, home in zip(objects.latest.poses, panda_constants.BOX_HOME_POSITIONS, strict=False):
            assert abs(pose.position.x - home[0]) < 0.005 and abs(pose.position.z - home[2]) < 0.005
        assert list(joints.latest.name) == list(panda_constants.ALL_JOINTS)
        tf = client.record(TFMessage, "/tf", keep=1000)

        def frames():
            return {(t.header.frame_id, t.child_frame_id) for m in tf.messages() for t in m.transforms}

        client.wait_for(lambda: ("world", "box_1") in frames() and ("panda_link0", "panda_link1") in frames(),
                        30.0, "/tf with the boxes and the links")

    def test_the_panda_scene_camera_sees_the_table_from_a_frame_on_tf_static(self, client, panda):
        from rclpy.qos import DurabilityPolicy, QoSProfile
        from sensor_msgs.msg import Image

        import robot_models

        camera = robot_models.cameras_of("panda")[0]
        images = client.record(Image, f"/{camera.name}/image_raw", keep=5)
        static = client.record(TFMessage, "/tf_static", qos=QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL))
        image = client.wait_for(lambda: images.latest, STARTUP_S, f"an image on /{camera.name}/image_raw")
        assert image.header.frame_id == camera.optical_frame and image.encoding == "rgb8"
        client.wait_for(lambda: any((t.header.frame_id, t.child_frame_id) == ("world", camera.optical_frame)
                                    for m in static.messages() for t in m.transforms), 30.0, "the camera's frame on /tf_static")
        images.stop()
        static.stop()


def test_lifecycle_transitions_through_the_standard_services(client):
    from lifecycle_msgs.msg import Transition
    from lifecycle_msgs.srv import ChangeState, GetState
    from rosgraph_msgs.msg import Clock

    def state() -> str:
        # A query: sent again until answered (the first call to a node just started can lose its response
        # while the node's side of discovery catches up on a loaded machine).
        return client.call(GetState, "/sim/get_state", GetState.Request(), timeout=STARTUP_S,
                           resend_every_s=2.0).current_state.label

    def change(transition: int, label: str = "", leads_to: str | None = None) -> bool:
        """A transition's answer. Not a query, so not blindly sent again: when its response is lost (the node's side
        of discovery behind, as for the queries), the state tells whether it took effect (``leads_to``) before the
        request is sent again; a refused transition changes nothing and is refused again."""
        request = ChangeState.Request(transition=Transition(id=transition, label=label))
        deadline = time.monotonic() + STARTUP_S
        while True:
            try:
                return client.call(ChangeState, "/sim/change_state", request, timeout=10.0).success
            except WaitTimeout:
                if leads_to is not None and state() == leads_to:
                    return True
                if time.monotonic() > deadline:
                    raise

    def sim_time(msg: Clock) -> float:
        return msg.clock.sec + msg.clock.nanosec * 1e-9

    args = ["sim_node", "--ros-args", "-p", "robot:=panda", "-p", "autostart:=false", "-p", "real_time_factor:=0.0"]
    with running(args) as process:
        clock = client.record(Clock, "/clock", keep=10)
        assert state() == "unconfigured"
        assert not change(Transition.TRANSITION_ACTIVATE), "activate is not a transition of unconfigured"
        assert not change(0, "fly")
        assert process.alive() and state() == "unconfigured", "a refused transition leaves the node serving"

        assert change(Transition.TRANSITION_CONFIGURE, leads_to="inactive") and state() == "inactive"
        assert change(Transition.TRANSITION_ACTIVATE, leads_to="active") and state() == "active"
        client.wait_for(lambda: clock.count > 5, STARTUP_S, "/clock once active")

        assert change(Transition.TRANSITION_DEACTIVATE, leads_to="inactive") and state() == "inactive"

        def landed() -> bool:  # the /clock still in flight when the node stopped has arrived: a round trip adds none
            before = clock.count
            return state() == "inactive" and clock.count == before

        client.wait_for(landed, STARTUP_S, "the /clock in flight at deactivation to land (a flood never does)")
        stopped_at, count = sim_time(clock.latest), clock.count
        assert state() == "inactive" and clock.count == count, "no /clock while inactive (unpaced, it would flood)"

        assert change(Transition.TRANSITION_CLEANUP, leads_to="unconfigured") and state() == "unconfigured"
        assert change(Transition.TRANSITION_CONFIGURE, leads_to="inactive")
        assert change(Transition.TRANSITION_ACTIVATE, leads_to="active")
        client.wait_for(lambda: clock.count > count + 5, STARTUP_S, "/clock after reactivation")
        assert sim_time(clock.latest) > stopped_at, "sim time keeps running forward"
        assert change(Transition.TRANSITION_ACTIVE_SHUTDOWN, leads_to="finalized") and state() == "finalized"
