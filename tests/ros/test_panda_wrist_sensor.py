"""The Panda's wrist force/torque sensor through /hand_sensors, from a client in another process (issue 12)."""

from __future__ import annotations

import numpy as np
import pytest
from geometry_msgs.msg import WrenchStamped

from nodes.conversions import seconds_of
from sim_interfaces.srv import CalibrateHandSensors
from tests.ros.processes import running

pytestmark = pytest.mark.slow


def test_the_panda_wrist_reads_the_hand_then_zero_after_calibration(client):
    with running(["bringup", "--robot", "panda", "--rtf", "2.0"]):
        wrench = client.record(WrenchStamped, "/wrist/wrench", keep=1000)
        client.wait_for(lambda: wrench.count >= 5, 90.0, "/wrist/wrench")
        force = wrench.latest.wrench.force
        assert wrench.latest.header.frame_id == "panda_wrist_ft"
        assert np.linalg.norm([force.x, force.y, force.z]) > 5.0, "the hand's weight (0.7 kg) and the sensor's offset"
        answer = client.call(CalibrateHandSensors, "/calibrate_hand_sensors", CalibrateHandSensors.Request(), timeout=60.0)
        assert answer.success and list(answer.names) == ["wrist"], answer.message
        now = seconds_of(wrench.latest.header.stamp)
        client.wait_for(lambda: sum(seconds_of(m.header.stamp) > now for m in wrench.messages()) >= 20, 60.0,
                        "calibrated wrenches")
        calibrated = [m.wrench.force for m in wrench.messages() if seconds_of(m.header.stamp) > now]
        mean = np.mean([[f.x, f.y, f.z] for f in calibrated], axis=0)
        assert np.linalg.norm(mean) < 0.1, mean
        wrench.stop()
