"""A world that fails to build leaves ``/sim`` as it was: the old scene is built again (sim time 0) with every
service and stream, and the next load works. The failure is injected in the scene's construction."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
import rclpy
from rclpy.parameter import Parameter

import nodes.sim.node as sim_node
from nodes.sim.node import SimNode
from sim_bridge import Simulation


@pytest.fixture
def node() -> Iterator[SimNode]:
    context = rclpy.Context()
    rclpy.init(context=context)
    made = SimNode(context=context, parameter_overrides=[Parameter("robot", value="g1"), Parameter("autostart", value=False)])
    made.trigger_configure()
    made.trigger_activate()
    yield made
    made.destroy()
    rclpy.try_shutdown(context=context)


def test_a_world_that_fails_to_build_leaves_the_old_one_running(node, monkeypatch):
    def names() -> tuple[list[str], list[str], list[str]]:
        return (sorted(s.srv_name for s in node.services), sorted(p.topic_name for p in node.publishers),
                sorted(s.topic_name for s in node.subscriptions))

    before = names()

    def failing(robot):
        if robot.scene == "course":
            raise RuntimeError("the course does not build today")
        return Simulation(robot)

    monkeypatch.setattr(sim_node, "Simulation", failing)
    with pytest.raises(RuntimeError, match="does not build"):
        node.load_world("course")
    assert node.sim is not None and node.sim.robot.scene == "open" and node.get_parameter("scene").value == "open"
    assert names() == before, "every service and stream of the open scene is there again, and nothing more"
    assert node.physics_running
    monkeypatch.undo()
    node.load_world("course")
    assert node.sim.robot.scene == "course" and node.get_parameter("scene").value == "course"
    assert len(names()[0]) == len(before[0]), "the course serves what the open scene served"
