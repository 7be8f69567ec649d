"""Worlds of ``/sim``: the robot's scenes, loaded at run time, so one bring-up serves runs in several scenes.

Served under ``/sim/`` with the ROS simulation standard's types (``simulation_interfaces``), as Gazebo and
Isaac Sim serve them: ``load_world``, ``get_available_worlds``, ``get_current_world``. A world is one of the
robot's scenes (``robot_models``; the G1's: open, course, tables), named by ``world_resource.uri``: the
scene's name (``course``) or ``<robot>/<scene>`` (``g1/course``, as ``get_simulator_features`` names it).

Loading a world ends the running goals, stops the physics thread, destroys what the old scene made on the node
(publishers, subscriptions, services, the SimulateSteps action, timers, parameter callbacks), builds the new
scene as a fresh ``/sim`` would (sim time 0, its keyframe) keeping the node's parameter values, and starts the
physics again as it was (playing or paused). The node's read-only ``scene`` parameter says the scene loaded, and
``~/world`` (latched) announces it: the action servers reload the model they validate goals on.

These services are made once, when the node is made: they outlive every world.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.node import Node

import robot_models
from nodes.sim.standard_entities import OK, result
from sim_ros.names import LATCHED, WORLD_TOPIC
from simulation_interfaces.msg import Result, WorldResource
from simulation_interfaces.srv import GetAvailableWorlds, GetCurrentWorld, LoadWorld


def world_resource(robot: str, scene: str) -> WorldResource:
    """The standard's description of one scene of ``robot``."""
    world = WorldResource(name=scene, description=f"the {robot} in its {scene!r} scene", tags=[robot])
    world.world_resource.uri = scene
    return world


def scene_of(robot: str, uri: str) -> str:
    """The scene a LoadWorld ``uri`` names: ``<scene>`` or ``<robot>/<scene>``.

    Raises:
        robot_models.UnknownSceneError: not a scene of ``robot`` (the message lists its scenes).
    """
    scene = uri.strip().removeprefix(f"{robot}/")
    robot_models.check_scene(robot, scene or "?")
    return scene


@dataclass
class MadeEntities:
    """What a configure made on a node, to destroy it all when the world is replaced."""

    publishers: list[Any] = field(default_factory=list)
    subscriptions: list[Any] = field(default_factory=list)
    clients: list[Any] = field(default_factory=list)
    services: list[Any] = field(default_factory=list)
    timers: list[Any] = field(default_factory=list)
    guards: list[Any] = field(default_factory=list)
    waitables: list[Any] = field(default_factory=list)
    parameter_callbacks: list[Callable[..., Any]] = field(default_factory=list)

    @staticmethod
    def _of(node: Node) -> MadeEntities:
        return MadeEntities(list(node.publishers), list(node.subscriptions), list(node.clients), list(node.services),
                            list(node.timers), list(node.guards), list(node.waitables),
                            list(node._on_set_parameters_callbacks))  # rclpy's own list: no public getter

    @staticmethod
    def made_by(node: Node, build: Callable[[], Any]) -> tuple[Any, MadeEntities]:
        """Run ``build`` and return what it returned and what it made on ``node``; if it raises, what it made is
        destroyed before the exception goes on."""
        before = MadeEntities._of(node)

        def made_since() -> MadeEntities:
            after = MadeEntities._of(node)
            return MadeEntities(**{name: [e for e in getattr(after, name) if not any(e is b for b in getattr(before, name))]
                                   for name in MadeEntities.__dataclass_fields__})
        try:
            built = build()
        except BaseException:
            made_since().destroy(node)
            raise
        return built, made_since()

    def destroy(self, node: Node) -> None:
        """Destroy every entity this holds (the node keeps serving what it had before)."""
        for waitable in self.waitables:  # the SimulateSteps action server
            destroy = getattr(waitable, "destroy", None)
            if callable(destroy):
                destroy()
            else:
                node.remove_waitable(waitable)
        for callback in self.parameter_callbacks:
            node.remove_on_set_parameters_callback(callback)
        for destroy_one, entities in ((node.destroy_timer, self.timers), (node.destroy_service, self.services),
                                      (node.destroy_client, self.clients), (node.destroy_subscription, self.subscriptions),
                                      (node.destroy_publisher, self.publishers),
                                      (node.destroy_guard_condition, self.guards)):
            for entity in entities:
                destroy_one(entity)
        for name in MadeEntities.__dataclass_fields__:
            getattr(self, name).clear()


class WorldServices:
    """``~/load_world``, ``~/get_available_worlds``, ``~/get_current_world`` and the latched ``~/world``.

    Args:
        node: the sim node (made once with it).
        robot: the robot it simulates.
        current: the scene loaded now ("" before the first configure).
        load: replaces the world by a scene of the robot (from a service thread; raises on failure).
    """

    def __init__(self, node: Node, robot: str, current: Callable[[], str], load: Callable[[str], None]) -> None:
        self._robot = robot
        self._current = current
        self._load = load
        self._world_pub = node.create_publisher(WorldResource, WORLD_TOPIC, LATCHED)
        queries = ReentrantCallbackGroup()
        node.create_service(LoadWorld, "~/load_world", self._on_load, callback_group=MutuallyExclusiveCallbackGroup())
        node.create_service(GetAvailableWorlds, "~/get_available_worlds", self._on_available, callback_group=queries)
        node.create_service(GetCurrentWorld, "~/get_current_world", self._on_current, callback_group=queries)

    def announce(self) -> None:
        """Publish the scene loaded now on ``~/world`` (latched: a server started later gets it too)."""
        self._world_pub.publish(world_resource(self._robot, self._current()))

    def _on_load(self, request: LoadWorld.Request, response: LoadWorld.Response) -> LoadWorld.Response:
        resource = request.world_resource
        scenes = ", ".join(robot_models.scenes_of(self._robot))
        if resource.resource_string:
            response.result = result(LoadWorld.Response.UNSUPPORTED_FORMAT,
                                     f"worlds are the {self._robot}'s scenes, named by uri ({scenes}); no resource_string")
            return response
        if not resource.uri:
            response.result = result(LoadWorld.Response.NO_RESOURCE, f"name a scene of the {self._robot} by uri: {scenes}")
            return response
        try:
            scene = scene_of(self._robot, resource.uri)
        except robot_models.UnknownSceneError as error:
            response.result = result(Result.RESULT_NOT_FOUND, str(error))
            return response
        try:
            self._load(scene)
        except Exception as error:  # noqa: BLE001 - the reason goes back to the caller; /sim keeps serving
            response.result = result(Result.RESULT_OPERATION_FAILED, f"loading {scene!r} failed: {error}")
            return response
        self.announce()
        response.world = world_resource(self._robot, scene)
        response.result = result(OK)
        return response

    def _on_available(self, request: GetAvailableWorlds.Request,
                      response: GetAvailableWorlds.Response) -> GetAvailableWorlds.Response:
        response.worlds = [world_resource(self._robot, scene) for scene in robot_models.scenes_of(self._robot)]
        response.result = result(OK)
        return response

    def _on_current(self, request: GetCurrentWorld.Request, response: GetCurrentWorld.Response) -> GetCurrentWorld.Response:
        scene = self._current()
        if not scene:
            response.result = result(Result.RESULT_INCORRECT_STATE, "no world yet: /sim is not configured")
            return response
        response.world = world_resource(self._robot, scene)
        response.result = result(OK)
        return response
