"""A simulation wired for the fetch without ROS: the walker in front of the legs' skill host, the arm
controller, and fetch skills built on them (what /sim wires for the G1, for the core's tests and benchmarks)."""

from __future__ import annotations

from dataclasses import dataclass

from robot_models import RobotSpec
from sim_bridge.arm import ArmController
from sim_bridge.controller import Slot
from sim_bridge.core import Simulation
from sim_bridge.fetch.goal import FetchGoal
from sim_bridge.fetch.one_hand_fetch import fetch_skill
from sim_bridge.fetch.skill import FetchSkill
from sim_bridge.locomotion import WalkingController
from sim_bridge.navigation import grid_from_obstacles
from sim_bridge.skills import SkillHost


@dataclass
class FetchRig:
    """One simulation of a walking robot with palms and the controllers a fetch commands."""

    robot: RobotSpec
    sim: Simulation
    walker: WalkingController
    legs: SkillHost
    arms: ArmController

    @classmethod
    def of(cls, robot: RobotSpec) -> FetchRig:
        """A new simulation of ``robot`` (at its keyframe) with the walker and the arm controller in their slots."""
        sim = Simulation(robot)
        walker = WalkingController(sim.model, robot.biped)
        legs = SkillHost(walker)
        sim.set_controller(Slot.LOCOMOTION, legs)
        arms = ArmController(robot)
        sim.set_controller(Slot.ARM, arms)
        return cls(robot, sim, walker, legs, arms)

    def skill(self, goal: FetchGoal) -> FetchSkill:
        """A fetch of ``goal`` on this rig, planning around the robot's obstacles: with one hand for a small object,
        else with both palms."""
        return fetch_skill(self.robot, self.walker, self.arms, grid_from_obstacles(self.robot.obstacles), goal)
