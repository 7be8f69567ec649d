"""The entities of the ROS simulation standard on ``/sim``: find, read, move; spawning and deleting are refused.

Served under ``/sim/``: get_entities, get_entities_states, get_entity_state, set_entity_state,
get_entity_info, get_entity_bounds; and spawn_entity, spawn_entities, delete_entity, get_spawnables,
which answer RESULT_FEATURE_UNSUPPORTED (see :mod:`nodes.sim.standard`). Entity states are ground
truth in ``world``: the pose of the entity's canonical frame (a robot's base body), the velocity of
its origin and its angular velocity in world axes.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from geometry_msgs.msg import Vector3
from rclpy.callback_groups import CallbackGroup
from rclpy.node import Node

from nodes.sim.control import SimControl
from sim_bridge import Pose, Simulation, UnknownNameError
from sim_bridge.entities import (
    Entity,
    EntityKind,
    EntityStateError,
    FixedEntityError,
    InvalidPoseError,
    SceneEntities,
    box_overlaps_sphere,
    boxes_overlap,
)
from sim_bridge.frames import WORLD_FRAMES, is_world
from sim_ros.conversions import set_pose
from sim_ros.stamps import set_time
from simulation_interfaces.msg import (
    Bounds,
    EntityCategory,
    EntityFilters,
    EntityState as EntityStateMsg,
    Result,
    SpawnResult,
    TagsFilter,
)
from simulation_interfaces.srv import (
    DeleteEntity,
    GetEntities,
    GetEntitiesStates,
    GetEntityBounds,
    GetEntityInfo,
    GetEntityState,
    GetSpawnables,
    SetEntityState,
    SpawnEntities,
    SpawnEntity,
)

CATEGORIES = {
    EntityKind.ROBOT: EntityCategory.CATEGORY_ROBOT,
    EntityKind.OBJECT: EntityCategory.CATEGORY_OBJECT,
    EntityKind.OBSTACLE: EntityCategory.CATEGORY_STATIC_OBJECT,
}
WORLD_FRAME_NAMES = f"empty, {', '.join(WORLD_FRAMES)}"
OK = Result.RESULT_OK


def result(code: int, message: str = "") -> Result:
    """A standard's Result: its code and a message (for a refusal: what is allowed)."""
    return Result(result=code, error_message=message)


class EntityServices:
    """Creates the standard's entity services on the sim node and answers them.

    Args:
        node: the sim node (the services are created on it).
        sim: its simulation.
        control: its lock, and what moving the robot must tell it.
        changes: the callback group of the standard's services that change the simulation (one at a time).
        queries: the callback group of those that only read it.
        on_set: called under the lock after an entity's state was set (the state is no longer a reset's).
    """

    def __init__(self, node: Node, sim: Simulation, control: SimControl, changes: CallbackGroup, queries: CallbackGroup,
                 on_set: Callable[[], None]) -> None:
        self._node = node
        self._sim = sim
        self._control = control
        self._on_set = on_set
        self._entities = SceneEntities(sim)
        services: tuple[tuple[Any, str, Callable[[Any, Any], Any], CallbackGroup], ...] = (
            (GetEntities, "get_entities", self._on_get_entities, queries),
            (GetEntitiesStates, "get_entities_states", self._on_get_entities_states, queries),
            (GetEntityState, "get_entity_state", self._on_get_entity_state, queries),
            (SetEntityState, "set_entity_state", self._on_set_entity_state, changes),
            (GetEntityInfo, "get_entity_info", self._on_get_entity_info, queries),
            (GetEntityBounds, "get_entity_bounds", self._on_get_entity_bounds, queries),
            (SpawnEntity, "spawn_entity", self._on_unsupported, queries),
            (SpawnEntities, "spawn_entities", self._on_spawn_entities, queries),
            (DeleteEntity, "delete_entity", self._on_unsupported, queries),
            (GetSpawnables, "get_spawnables", self._on_unsupported, queries),
        )
        for srv_type, name, callback, group in services:
            node.create_service(srv_type, f"~/{name}", callback, callback_group=group)

    # ----- queries -------------------------------------------------------------------------
    def _filtered(self, filters: EntityFilters) -> tuple[Result, list[Entity]]:
        """Entities passing every filter, or a result saying which filter cannot be applied."""
        try:
            entities = self._entities.matching(filters.filter)
        except EntityStateError as error:
            return result(Result.RESULT_OPERATION_FAILED, str(error)), []
        if filters.categories:
            wanted = {c.category for c in filters.categories}
            entities = [e for e in entities if CATEGORIES[e.kind] in wanted]
        tags = filters.tags
        if tags.tags:
            if tags.filter_mode not in (TagsFilter.FILTER_MODE_ANY, TagsFilter.FILTER_MODE_ALL):
                return result(Result.RESULT_OPERATION_FAILED, f"tags.filter_mode {tags.filter_mode} is not one of "
                              "FILTER_MODE_ANY (0), FILTER_MODE_ALL (1)"), []
            match = any if tags.filter_mode == TagsFilter.FILTER_MODE_ANY else all
            entities = [e for e in entities if match(tag in e.tags for tag in tags.tags)]
        bounds = filters.bounds
        if bounds.type == Bounds.TYPE_EMPTY:
            return result(OK), entities
        points = [np.array([p.x, p.y, p.z]) for p in bounds.points]
        if bounds.type == Bounds.TYPE_SPHERE and len(points) == 2 and points[1][0] >= 0.0:
            centre, radius = points[0], float(points[1][0])
            return result(OK), [e for e in entities if box_overlaps_sphere(*self._entities.world_box(e.name), centre, radius)]
        if bounds.type == Bounds.TYPE_BOX and len(points) == 2:
            low, high = np.minimum(points[0], points[1]), np.maximum(points[0], points[1])
            return result(OK), [e for e in entities if boxes_overlap(*self._entities.world_box(e.name), low, high)]
        if bounds.type == Bounds.TYPE_CONVEX_HULL:
            return result(Result.RESULT_FEATURE_UNSUPPORTED, "convex hull bounds are not supported; allowed: "
                          "TYPE_SPHERE (centre, (radius, 0, 0)) or TYPE_BOX (two corners), in world"), []
        return result(Result.RESULT_OPERATION_FAILED, f"bounds of type {bounds.type} with {len(points)} points: "
                      "TYPE_SPHERE needs 2 points (centre, (radius >= 0, 0, 0)), TYPE_BOX 2 corners"), []

    def _on_get_entities(self, request: GetEntities.Request, response: GetEntities.Response) -> GetEntities.Response:
        with self._control.lock:
            response.result, entities = self._filtered(request.filters)
        response.entities = [e.name for e in entities]
        return response

    def _on_get_entities_states(self, request: GetEntitiesStates.Request,
                                response: GetEntitiesStates.Response) -> GetEntitiesStates.Response:
        with self._control.lock:
            response.result, entities = self._filtered(request.filters)
            response.entities = [e.name for e in entities]
            response.states = [self._state_msg(e.name) for e in entities]
        return response

    def _state_msg(self, name: str) -> EntityStateMsg:
        state = self._entities.state(name)
        msg = EntityStateMsg()
        msg.header.frame_id = "world"
        set_time(msg.header.stamp, self._sim.time)
        set_pose(msg.pose, state.pose.position, state.pose.orientation_wxyz)
        for vector, value in ((msg.twist.linear, state.linear_velocity), (msg.twist.angular, state.angular_velocity),
                              (msg.acceleration.linear, state.linear_acceleration),
                              (msg.acceleration.angular, state.angular_acceleration)):
            vector.x, vector.y, vector.z = (float(v) for v in value)
        return msg

    def _on_get_entity_state(self, request: GetEntityState.Request,
                             response: GetEntityState.Response) -> GetEntityState.Response:
        with self._control.lock:
            try:
                response.state = self._state_msg(request.entity)
            except UnknownNameError as error:
                response.result = result(Result.RESULT_NOT_FOUND, str(error))
                return response
        response.result = result(OK)
        return response

    def _on_get_entity_info(self, request: GetEntityInfo.Request, response: GetEntityInfo.Response) -> GetEntityInfo.Response:
        try:
            entity = self._entities.get(request.entity)
        except UnknownNameError as error:
            response.result = result(Result.RESULT_NOT_FOUND, str(error))
            return response
        response.info.category.category = CATEGORIES[entity.kind]
        response.info.description = entity.description
        response.info.tags = list(entity.tags)
        response.result = result(OK)
        return response

    def _on_get_entity_bounds(self, request: GetEntityBounds.Request,
                              response: GetEntityBounds.Response) -> GetEntityBounds.Response:
        with self._control.lock:
            try:
                low, high = self._entities.local_box(request.entity)
            except UnknownNameError as error:
                response.result = result(Result.RESULT_NOT_FOUND, str(error))
                return response
        response.bounds.type = Bounds.TYPE_BOX
        response.bounds.points = [Vector3(x=float(p[0]), y=float(p[1]), z=float(p[2])) for p in (low, high)]
        response.result = result(OK, "axis-aligned box in the entity's frame, at its present configuration")
        return response

    def _on_set_entity_state(self, request: SetEntityState.Request,
                             response: SetEntityState.Response) -> SetEntityState.Response:
        response.result = self._set_entity_state(request)
        if response.result.result == OK:
            self._node.get_logger().info(f"set_entity_state {request.entity}: {response.result.error_message}")
        return response

    def _set_entity_state(self, request: SetEntityState.Request) -> Result:
        state = request.state
        frame = state.header.frame_id
        if not is_world(frame):
            return result(Result.RESULT_FEATURE_UNSUPPORTED,
                          f"states are set in the world frame; header.frame_id {frame!r} is not one of: {WORLD_FRAME_NAMES}")
        acceleration = [state.acceleration.linear.x, state.acceleration.linear.y, state.acceleration.linear.z,
                        state.acceleration.angular.x, state.acceleration.angular.y, state.acceleration.angular.z]
        if request.set_acceleration and any(a != 0.0 for a in acceleration):
            return result(Result.RESULT_FEATURE_UNSUPPORTED,
                          "accelerations cannot be set (they follow from forces): set pose and/or twist, "
                          "or push a body with /sim/push")
        try:
            entity = self._entities.get(request.entity)
        except UnknownNameError as error:
            return result(Result.RESULT_NOT_FOUND, str(error))
        if not (request.set_pose or request.set_twist):
            return result(OK, "nothing to set: set_pose and set_twist are false")
        p, q = state.pose.position, state.pose.orientation
        pose = Pose(np.array([p.x, p.y, p.z]), np.array([q.w, q.x, q.y, q.z])) if request.set_pose else None
        linear = angular = None
        if request.set_twist:
            t = state.twist
            linear = np.array([t.linear.x, t.linear.y, t.linear.z])
            angular = np.array([t.angular.x, t.angular.y, t.angular.z])
        control = self._control
        with control.lock:
            if entity.kind is EntityKind.ROBOT and control.legs_busy():
                return result(Result.RESULT_INCORRECT_STATE,
                              f"a Walk or NavigateToPose goal drives {entity.name}: cancel it before moving the robot")
            try:
                self._entities.set_state(entity.name, pose, linear, angular)
            except InvalidPoseError as error:
                return result(SetEntityState.Response.INVALID_POSE, str(error))
            except (FixedEntityError, EntityStateError) as error:
                return result(Result.RESULT_OPERATION_FAILED, str(error))
            if entity.kind is EntityKind.ROBOT:
                control.robot_moved()
            self._on_set()
            control.publish_now()
        what = " and ".join(w for w, on in (("pose", request.set_pose), ("twist", request.set_twist)) if on)
        return result(OK, f"set the {what} of {entity.name}")

    # ----- not supported: the model is compiled ------------------------------------------
    def _unsupported_message(self) -> str:
        movable = ", ".join(e.name for e in self._entities.entities if e.movable)
        return ("spawning and deleting entities is not supported: /sim simulates a compiled MuJoCo model whose "
                f"bodies its controllers and publishers hold; move an entity with set_entity_state ({movable})")

    def _on_unsupported(self, request: Any, response: Any) -> Any:
        response.result = result(Result.RESULT_FEATURE_UNSUPPORTED, self._unsupported_message())
        return response

    def _on_spawn_entities(self, request: SpawnEntities.Request, response: SpawnEntities.Response) -> SpawnEntities.Response:
        message = self._unsupported_message()
        response.result = result(Result.RESULT_FEATURE_UNSUPPORTED, message)
        response.results = [SpawnResult(result=result(Result.RESULT_FEATURE_UNSUPPORTED, message))
                            for _ in request.spawn_requests]
        return response
