"""The /sim node with the Panda scene, from a client in another process."""

from __future__ import annotations

from sensor_msgs.msg import JointState
from tf2_msgs.msg import TFMessage

from robot_models import panda_constants
from sim_interfaces.msg import ObjectStates
from tests.ros.processes import running

STARTUP_S = 60.0


def test_panda_publishes_its_joints_and_the_boxes(client):
    with running(["sim_node", "--ros-args", "-p", "robot:=panda", "-p", "real_time_factor:=0.0"]):
        objects = client.record(ObjectStates, "/objects")
        joints = client.record(JointState, "/joint_states")
        client.wait_for(lambda: objects.count > 2 and joints.count > 2, STARTUP_S, "/objects and /joint_states from the panda")
        names = list(objects.latest.names)
        assert names == list(panda_constants.BOX_NAMES)
        for pose, home in zip(objects.latest.poses, panda_constants.BOX_HOME_POSITIONS):
            assert abs(pose.position.x - home[0]) < 0.005 and abs(pose.position.z - home[2]) < 0.005
        assert list(joints.latest.name) == list(panda_constants.ALL_JOINTS)
        tf = client.record(TFMessage, "/tf", keep=1000)

        def frames():
            return {(t.header.frame_id, t.child_frame_id) for m in tf.messages() for t in m.transforms}

        client.wait_for(lambda: ("world", "box_1") in frames() and ("panda_link0", "panda_link1") in frames(),
                        30.0, "/tf with the boxes and the links")
