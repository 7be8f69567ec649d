"""The package is where ROS 2 tools look for it: ament index, lib/sim executables, interfaces."""

from __future__ import annotations

import os
import pathlib
import sys

PREFIX = pathlib.Path(sys.prefix)


def test_sim_is_registered_in_the_ament_index_with_its_executables():
    assert (PREFIX / "share/ament_index/resource_index/packages/sim").is_file()
    assert (PREFIX / "share/sim/package.xml").is_file()
    for exe in ("sim_node", "bringup"):
        wrapper = PREFIX / "lib/sim" / exe
        assert wrapper.is_file() and os.access(wrapper, os.X_OK), exe
        assert (PREFIX / "bin" / exe).is_file(), f"console script {exe}"


def test_interface_packages_are_installed_and_importable():
    for package in ("sim_interfaces", "simulation_interfaces", "tf2_msgs"):
        assert (PREFIX / "share/ament_index/resource_index/packages" / package).is_file()
    assert (PREFIX / "share/sim_interfaces/action/Walk.action").is_file()
    from tf2_msgs.msg import TFMessage

    from sim_interfaces.action import MoveArm, NavigateToPose, PickPlace, Walk

    assert Walk.Result.FELL != Walk.Result.SUCCESS
    assert PickPlace.Feedback.RETREAT == 7
    assert hasattr(NavigateToPose.Feedback(), "distance_remaining")
    assert hasattr(MoveArm.Result(), "error_msg")
    assert TFMessage().transforms == []
    assert (PREFIX / "share/simulation_interfaces/action/SimulateSteps.action").is_file()
    from simulation_interfaces.action import SimulateSteps
    from simulation_interfaces.msg import Result

    assert Result.RESULT_OK == 1 and hasattr(SimulateSteps.Feedback(), "remaining_steps")
