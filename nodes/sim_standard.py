"""The ROS simulation standard (``simulation_interfaces``) on ``/sim``, as Gazebo and Isaac Sim serve it.

Served under ``/sim/``: get_simulator_features, reset_simulation, get_simulation_state,
set_simulation_state, step_simulation, the simulate_steps action, get_entities, get_entities_states,
get_entity_state, set_entity_state, get_entity_info, get_entity_bounds; and spawn_entity,
spawn_entities, delete_entity, get_spawnables, which answer RESULT_FEATURE_UNSUPPORTED: a MuJoCo
model is compiled, and the controllers, skills and /tf publishers of /sim hold its ids, so bodies are
not added or removed at run time.

Conventions (also in ``custom_info`` of the features):
- one step is one physics step (``mj_step``, the model's timestep); the controllers still run on
  their control-step grid, however the steps are split;
- entity states are ground truth in ``world``: the pose of the entity's canonical frame (a robot's
  base body), the velocity of its origin and its angular velocity in world axes;
- STOPPED is paused at the keyframe with sim time at 0 (SetSimulationState STOPPED pauses and resets
  with SCOPE_ALL); it becomes PAUSED at the first step and PLAYING when resumed;
- a reset of time goes with a reset of the state (goals in the control step measure sim time).

Every refusal is a result with the standard's code and a message naming what is allowed; nothing is
changed by a refused call. Changes happen under the node's lock, as /sim's own services do.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
from geometry_msgs.msg import Vector3
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup

from nodes.conversions import set_pose, set_time
from sim_bridge import Pose, SimError, UnknownNameError
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
from sim_bridge.skills import LEGS
from simulation_interfaces.action import SimulateSteps
from simulation_interfaces.msg import (
    Bounds,
    EntityCategory,
    EntityFilters,
    EntityState as EntityStateMsg,
    Result,
    SimulationState,
    SimulatorFeatures,
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
    GetSimulationState,
    GetSimulatorFeatures,
    GetSpawnables,
    ResetSimulation,
    SetEntityState,
    SetSimulationState,
    SpawnEntities,
    SpawnEntity,
    StepSimulation,
)

if TYPE_CHECKING:
    from nodes.sim_node import SimNode

MAX_SERVICE_STEPS = 1_000_000  # one StepSimulation call [physics steps]; the action takes more and can be canceled
MAX_ACTION_STEPS = 100_000_000
STRETCH_S = 0.05  # sim time stepped under the lock at a time: queries, cancels and feedback go between [s]
FEEDBACK_PERIOD_S = 0.02  # SimulateSteps feedback at most this often [s of wall time], and at the end

FEATURES = (
    SimulatorFeatures.ENTITY_TAGS, SimulatorFeatures.ENTITY_BOUNDS, SimulatorFeatures.ENTITY_BOUNDS_BOX,
    SimulatorFeatures.ENTITY_CATEGORIES, SimulatorFeatures.ENTITY_STATE_GETTING, SimulatorFeatures.ENTITY_STATE_SETTING,
    SimulatorFeatures.ENTITY_INFO_GETTING, SimulatorFeatures.SIMULATION_RESET, SimulatorFeatures.SIMULATION_RESET_TIME,
    SimulatorFeatures.SIMULATION_RESET_STATE, SimulatorFeatures.SIMULATION_STATE_GETTING,
    SimulatorFeatures.SIMULATION_STATE_SETTING, SimulatorFeatures.SIMULATION_STATE_PAUSE,
    SimulatorFeatures.STEP_SIMULATION_SINGLE, SimulatorFeatures.STEP_SIMULATION_MULTIPLE,
    SimulatorFeatures.STEP_SIMULATION_ACTION,
)
CATEGORIES = {
    EntityKind.ROBOT: EntityCategory.CATEGORY_ROBOT,
    EntityKind.OBJECT: EntityCategory.CATEGORY_OBJECT,
    EntityKind.OBSTACLE: EntityCategory.CATEGORY_STATIC_OBJECT,
}
STATE_NAMES = {SimulationState.STATE_STOPPED: "STOPPED", SimulationState.STATE_PLAYING: "PLAYING",
               SimulationState.STATE_PAUSED: "PAUSED", SimulationState.STATE_QUITTING: "QUITTING",
               SimulationState.STATE_NO_WORLD: "NO_WORLD", SimulationState.STATE_LOADING_WORLD: "LOADING_WORLD"}
SCOPE_BITS = ResetSimulation.Request.SCOPE_TIME | ResetSimulation.Request.SCOPE_STATE | ResetSimulation.Request.SCOPE_SPAWNED
WORLD_FRAME_NAMES = f"empty, {', '.join(WORLD_FRAMES)}"


def _result(code: int, message: str = "") -> Result:
    return Result(result=code, error_message=message)


OK = Result.RESULT_OK


class SimulationStandard:
    """Creates the standard's services and action on the sim node and answers them.

    Args:
        node: the configured sim node (its simulation, plugins and lock exist).
    """

    def __init__(self, node: SimNode) -> None:
        assert node.sim is not None
        self._node = node
        self._sim = node.sim
        self._entities = SceneEntities(node.sim)
        # Paused at the keyframe with nothing stepped since: the standard's STOPPED (also at a paused start).
        self._stopped_at: float | None = self._sim.time if node.paused else None
        self._action_lock = threading.Lock()  # one SimulateSteps goal at a time
        control = MutuallyExclusiveCallbackGroup()  # changes, one at a time
        queries = ReentrantCallbackGroup()
        services: tuple[tuple[Any, str, Callable[[Any, Any], Any], Any], ...] = (
            (GetSimulatorFeatures, "get_simulator_features", self._on_features, queries),
            (GetSimulationState, "get_simulation_state", self._on_get_state, queries),
            (SetSimulationState, "set_simulation_state", self._on_set_state, control),
            (ResetSimulation, "reset_simulation", self._on_reset, control),
            (StepSimulation, "step_simulation", self._on_step, control),
            (GetEntities, "get_entities", self._on_get_entities, queries),
            (GetEntitiesStates, "get_entities_states", self._on_get_entities_states, queries),
            (GetEntityState, "get_entity_state", self._on_get_entity_state, queries),
            (SetEntityState, "set_entity_state", self._on_set_entity_state, control),
            (GetEntityInfo, "get_entity_info", self._on_get_entity_info, queries),
            (GetEntityBounds, "get_entity_bounds", self._on_get_entity_bounds, queries),
            (SpawnEntity, "spawn_entity", self._on_unsupported, queries),
            (SpawnEntities, "spawn_entities", self._on_spawn_entities, queries),
            (DeleteEntity, "delete_entity", self._on_unsupported, queries),
            (GetSpawnables, "get_spawnables", self._on_unsupported, queries),
        )
        for srv_type, name, callback, group in services:
            node.create_service(srv_type, f"~/{name}", callback, callback_group=group)
        self._action = ActionServer(
            node, SimulateSteps, "~/simulate_steps", execute_callback=self._execute_steps,
            goal_callback=lambda goal: GoalResponse.ACCEPT, cancel_callback=lambda handle: CancelResponse.ACCEPT,
            callback_group=ReentrantCallbackGroup())

    # ----- features and state ------------------------------------------------------------
    def _on_features(self, request: GetSimulatorFeatures.Request,
                     response: GetSimulatorFeatures.Response) -> GetSimulatorFeatures.Response:
        sim = self._sim
        response.features.features = list(FEATURES)
        response.features.spawn_formats = []
        response.features.custom_info = (
            f"MuJoCo scene {sim.robot.name}/{sim.robot.scene}. One step = one physics step of "
            f"{sim.physics_timestep * 1e3:g} ms (control step {sim.control_timestep * 1e3:g} ms). Entity states are "
            "in world: pose of the canonical frame, velocity of its origin and angular velocity in world axes. "
            "SCOPE_TIME resets the clock together with the state only. STOPPED = paused at the keyframe, t = 0. "
            "Spawning and deleting are not supported (a compiled MuJoCo model); move entities with SetEntityState.")
        return response

    def _state(self) -> int:
        node = self._node
        if not node.paused and node.physics_running:
            return SimulationState.STATE_PLAYING
        if self._stopped_at is not None and self._stopped_at == self._sim.time:
            return SimulationState.STATE_STOPPED
        return SimulationState.STATE_PAUSED

    def _on_get_state(self, request: GetSimulationState.Request,
                      response: GetSimulationState.Response) -> GetSimulationState.Response:
        with self._node.lock:
            response.state.state = self._state()
        response.result = _result(OK)
        return response

    def _on_set_state(self, request: SetSimulationState.Request,
                      response: SetSimulationState.Response) -> SetSimulationState.Response:
        target = request.state.state
        node = self._node
        settable = (SimulationState.STATE_PLAYING, SimulationState.STATE_PAUSED, SimulationState.STATE_STOPPED)
        with node.lock:
            current = self._state()
            if target not in settable:
                allowed = ", ".join(f"{STATE_NAMES[s]} ({s})" for s in settable)
                name = STATE_NAMES.get(target, "an unknown state")
                code = Result.RESULT_FEATURE_UNSUPPORTED if target == SimulationState.STATE_QUITTING \
                    else SetSimulationState.Response.INCORRECT_TRANSITION
                why = " (stop the sim_node process, or use the lifecycle shutdown transition)" \
                    if target == SimulationState.STATE_QUITTING else ""
                response.result = _result(code, f"cannot set {name} ({target}){why}; allowed: {allowed}")
                return response
            if target == current:
                response.result = _result(SetSimulationState.Response.ALREADY_IN_TARGET_STATE,
                                          f"already {STATE_NAMES[target]}")
                return response
            if target == SimulationState.STATE_PLAYING:
                if not node.physics_running:
                    response.result = _result(
                        SetSimulationState.Response.STATE_TRANSITION_ERROR,
                        "the /sim lifecycle node is not active, so its physics does not run: activate it "
                        "(/sim/change_state) first; stepping works meanwhile")
                    return response
                node.set_paused(False)
                self._stopped_at = None
            elif target == SimulationState.STATE_PAUSED:
                node.set_paused(True)  # from STOPPED: stays where it is, now counted as paused
                self._stopped_at = None
            else:
                node.set_paused(True)
                node.reset_scene(keep_time=False)
                self._stopped_at = self._sim.time
        response.result = _result(OK, f"{STATE_NAMES[current]} -> {STATE_NAMES[target]}")
        node.get_logger().info(f"simulation state: {response.result.error_message}")
        return response

    def _on_reset(self, request: ResetSimulation.Request, response: ResetSimulation.Response) -> ResetSimulation.Response:
        scope = request.scope
        req = ResetSimulation.Request
        whole = scope in (req.SCOPE_DEFAULT, req.SCOPE_ALL)
        allowed = "SCOPE_DEFAULT (0) or SCOPE_ALL (255): state and time; SCOPE_STATE (2): state, time runs on; " \
                  "SCOPE_TIME | SCOPE_STATE (3)"
        if not whole and scope & ~SCOPE_BITS:
            response.result = _result(Result.RESULT_FEATURE_UNSUPPORTED, f"unknown scope bits in {scope}; allowed: {allowed}")
            return response
        if not whole and scope & req.SCOPE_SPAWNED:
            response.result = _result(Result.RESULT_FEATURE_UNSUPPORTED,
                                      f"SCOPE_SPAWNED: spawning is not supported, nothing is ever spawned; allowed: {allowed}")
            return response
        if not whole and not scope & req.SCOPE_STATE:
            response.result = _result(Result.RESULT_FEATURE_UNSUPPORTED,
                                      "SCOPE_TIME alone is not supported: the clock restarts together with the state "
                                      f"(goals in the control step measure sim time); allowed: {allowed}")
            return response
        keep_time = not (whole or scope & req.SCOPE_TIME)
        node = self._node
        with node.lock:
            node.reset_scene(keep_time=keep_time)
            # Paused and reset with the clock: the standard's STOPPED.
            self._stopped_at = self._sim.time if node.paused and not keep_time else None
            response.result = _result(OK, f"reset to keyframe {self._sim.robot.default_keyframe!r}"
                                          f"{'' if keep_time else ', sim time 0'}")
        node.get_logger().info(f"reset_simulation: {response.result.error_message}")
        return response

    # ----- stepping ----------------------------------------------------------------------
    def _holding(self) -> bool:
        """Whether nothing else steps: paused, or the physics thread does not run (an inactive node)."""
        return self._node.paused or not self._node.physics_running

    def _step_refusal(self, steps: int, limit: int) -> Result | None:
        """Why ``steps`` cannot be stepped now (a result to answer), or None."""
        if not self._holding():
            return _result(Result.RESULT_OPERATION_FAILED,
                           "stepping needs a paused simulation: set STATE_PAUSED with set_simulation_state (or /sim/pause)")
        if not 1 <= steps <= limit:
            return _result(Result.RESULT_OPERATION_FAILED, f"steps must be in [1, {limit}] physics steps "
                           f"of {self._sim.physics_timestep * 1e3:g} ms, got {steps}")
        return None

    def _advance(self, steps: int) -> Result | None:
        """Step a paused simulation under the lock; a result when it cannot (resumed meanwhile, a fault)."""
        node = self._node
        with node.lock:
            if not self._holding():
                return _result(Result.RESULT_OPERATION_FAILED, "the simulation was resumed while stepping; stopped there")
            if not node.context.ok():
                return _result(Result.RESULT_OPERATION_FAILED, "/sim is shutting down")
            try:
                node.step_while_paused(steps)
            except SimError as error:
                return _result(Result.RESULT_OPERATION_FAILED, str(error))
            self._stopped_at = None
        return None

    def _chunk(self) -> int:
        """Physics steps per stretch of stepping (the lock is released between stretches)."""
        return max(1, int(STRETCH_S / self._sim.physics_timestep))

    def _on_step(self, request: StepSimulation.Request, response: StepSimulation.Response) -> StepSimulation.Response:
        steps = int(request.steps)
        with self._node.lock:
            refusal = self._step_refusal(steps, MAX_SERVICE_STEPS)
        if refusal is not None:
            response.result = refusal
            return response
        done = 0
        while done < steps:  # the lock is released between stretches: queries are answered meanwhile
            count = min(self._chunk(), steps - done)
            failure = self._advance(count)
            if failure is not None:
                failure.error_message += f" (after {done} of {steps} steps)"
                response.result = failure
                return response
            done += count
        response.result = _result(OK, f"stepped {steps} physics steps; sim time {self._sim.time:.6f} s")
        return response

    def _execute_steps(self, handle: ServerGoalHandle) -> SimulateSteps.Result:
        steps = int(handle.request.steps)
        result = SimulateSteps.Result()
        if not self._action_lock.acquire(blocking=False):
            result.result = _result(Result.RESULT_OPERATION_FAILED,
                                    "another SimulateSteps goal is running; cancel it or wait for its result")
            handle.abort()
            return result
        try:
            with self._node.lock:
                refusal = self._step_refusal(steps, MAX_ACTION_STEPS)
            if refusal is not None:
                result.result = refusal
                handle.abort()
                return result
            feedback = SimulateSteps.Feedback()
            done = 0
            next_feedback = 0.0
            while done < steps:
                if handle.is_cancel_requested:
                    result.result = _result(Result.RESULT_OK, f"canceled after {done} of {steps} steps")
                    handle.canceled()
                    return result
                count = min(self._chunk(), steps - done)
                failure = self._advance(count)
                if failure is not None:
                    failure.error_message += f" (after {done} of {steps} steps)"
                    result.result = failure
                    handle.abort()
                    return result
                done += count
                now = time.monotonic()
                if now >= next_feedback or done == steps:  # a stretch of steps takes well under a millisecond
                    next_feedback = now + FEEDBACK_PERIOD_S
                    feedback.completed_steps, feedback.remaining_steps = done, steps - done
                    handle.publish_feedback(feedback)
            result.result = _result(OK, f"stepped {steps} physics steps; sim time {self._sim.time:.6f} s")
            handle.succeed()
            return result
        finally:
            self._action_lock.release()

    # ----- entities ----------------------------------------------------------------------
    def _filtered(self, filters: EntityFilters) -> tuple[Result, list[Entity]]:
        """Entities passing every filter, or a result saying which filter cannot be applied."""
        try:
            entities = self._entities.matching(filters.filter)
        except EntityStateError as error:
            return _result(Result.RESULT_OPERATION_FAILED, str(error)), []
        if filters.categories:
            wanted = {c.category for c in filters.categories}
            entities = [e for e in entities if CATEGORIES[e.kind] in wanted]
        tags = filters.tags
        if tags.tags:
            if tags.filter_mode not in (TagsFilter.FILTER_MODE_ANY, TagsFilter.FILTER_MODE_ALL):
                return _result(Result.RESULT_OPERATION_FAILED, f"tags.filter_mode {tags.filter_mode} is not one of "
                               "FILTER_MODE_ANY (0), FILTER_MODE_ALL (1)"), []
            match = any if tags.filter_mode == TagsFilter.FILTER_MODE_ANY else all
            entities = [e for e in entities if match(tag in e.tags for tag in tags.tags)]
        bounds = filters.bounds
        if bounds.type == Bounds.TYPE_EMPTY:
            return _result(OK), entities
        points = [np.array([p.x, p.y, p.z]) for p in bounds.points]
        if bounds.type == Bounds.TYPE_SPHERE and len(points) == 2 and points[1][0] >= 0.0:
            centre, radius = points[0], float(points[1][0])
            return _result(OK), [e for e in entities if box_overlaps_sphere(*self._entities.world_box(e.name), centre, radius)]
        if bounds.type == Bounds.TYPE_BOX and len(points) == 2:
            low, high = np.minimum(points[0], points[1]), np.maximum(points[0], points[1])
            return _result(OK), [e for e in entities if boxes_overlap(*self._entities.world_box(e.name), low, high)]
        if bounds.type == Bounds.TYPE_CONVEX_HULL:
            return _result(Result.RESULT_FEATURE_UNSUPPORTED, "convex hull bounds are not supported; allowed: "
                           "TYPE_SPHERE (centre, (radius, 0, 0)) or TYPE_BOX (two corners), in world"), []
        return _result(Result.RESULT_OPERATION_FAILED, f"bounds of type {bounds.type} with {len(points)} points: "
                       "TYPE_SPHERE needs 2 points (centre, (radius >= 0, 0, 0)), TYPE_BOX 2 corners"), []

    def _on_get_entities(self, request: GetEntities.Request, response: GetEntities.Response) -> GetEntities.Response:
        with self._node.lock:
            response.result, entities = self._filtered(request.filters)
        response.entities = [e.name for e in entities]
        return response

    def _on_get_entities_states(self, request: GetEntitiesStates.Request,
                                response: GetEntitiesStates.Response) -> GetEntitiesStates.Response:
        with self._node.lock:
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
        with self._node.lock:
            try:
                response.state = self._state_msg(request.entity)
            except UnknownNameError as error:
                response.result = _result(Result.RESULT_NOT_FOUND, str(error))
                return response
        response.result = _result(OK)
        return response

    def _on_get_entity_info(self, request: GetEntityInfo.Request, response: GetEntityInfo.Response) -> GetEntityInfo.Response:
        try:
            entity = self._entities.get(request.entity)
        except UnknownNameError as error:
            response.result = _result(Result.RESULT_NOT_FOUND, str(error))
            return response
        response.info.category.category = CATEGORIES[entity.kind]
        response.info.description = entity.description
        response.info.tags = list(entity.tags)
        response.result = _result(OK)
        return response

    def _on_get_entity_bounds(self, request: GetEntityBounds.Request,
                              response: GetEntityBounds.Response) -> GetEntityBounds.Response:
        with self._node.lock:
            try:
                low, high = self._entities.local_box(request.entity)
            except UnknownNameError as error:
                response.result = _result(Result.RESULT_NOT_FOUND, str(error))
                return response
        response.bounds.type = Bounds.TYPE_BOX
        response.bounds.points = [Vector3(x=float(p[0]), y=float(p[1]), z=float(p[2])) for p in (low, high)]
        response.result = _result(OK, "axis-aligned box in the entity's frame, at its present configuration")
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
            return _result(Result.RESULT_FEATURE_UNSUPPORTED,
                           f"states are set in the world frame; header.frame_id {frame!r} is not one of: {WORLD_FRAME_NAMES}")
        acceleration = [state.acceleration.linear.x, state.acceleration.linear.y, state.acceleration.linear.z,
                        state.acceleration.angular.x, state.acceleration.angular.y, state.acceleration.angular.z]
        if request.set_acceleration and any(a != 0.0 for a in acceleration):
            return _result(Result.RESULT_FEATURE_UNSUPPORTED,
                           "accelerations cannot be set (they follow from forces): set pose and/or twist, "
                           "or push a body with /sim/push")
        try:
            entity = self._entities.get(request.entity)
        except UnknownNameError as error:
            return _result(Result.RESULT_NOT_FOUND, str(error))
        if not (request.set_pose or request.set_twist):
            return _result(OK, "nothing to set: set_pose and set_twist are false")
        p, q = state.pose.position, state.pose.orientation
        pose = Pose(np.array([p.x, p.y, p.z]), np.array([q.w, q.x, q.y, q.z])) if request.set_pose else None
        linear = angular = None
        if request.set_twist:
            t = state.twist
            linear = np.array([t.linear.x, t.linear.y, t.linear.z])
            angular = np.array([t.angular.x, t.angular.y, t.angular.z])
        node = self._node
        plugins = node.plugins
        assert plugins is not None
        with node.lock:
            if entity.kind is EntityKind.ROBOT and plugins.skills.busy(LEGS):
                return _result(Result.RESULT_INCORRECT_STATE,
                               f"a Walk or NavigateToPose goal drives {entity.name}: cancel it before moving the robot")
            try:
                self._entities.set_state(entity.name, pose, linear, angular)
            except InvalidPoseError as error:
                return _result(SetEntityState.Response.INVALID_POSE, str(error))
            except (FixedEntityError, EntityStateError) as error:
                return _result(Result.RESULT_OPERATION_FAILED, str(error))
            if entity.kind is EntityKind.ROBOT and plugins.walking is not None:
                # The gait and balance references are in world coordinates: start them again from here.
                plugins.walking.reset(self._sim.model, self._sim.data)
                plugins.on_reset()
            self._stopped_at = None  # no longer the state of a reset
            node.publish_now()
        what = " and ".join(w for w, on in (("pose", request.set_pose), ("twist", request.set_twist)) if on)
        return _result(OK, f"set the {what} of {entity.name}")

    # ----- not supported: the model is compiled ------------------------------------------
    def _unsupported_message(self) -> str:
        movable = ", ".join(e.name for e in self._entities.entities if e.movable)
        return ("spawning and deleting entities is not supported: /sim simulates a compiled MuJoCo model whose "
                f"bodies its controllers and publishers hold; move an entity with set_entity_state ({movable})")

    def _on_unsupported(self, request: Any, response: Any) -> Any:
        response.result = _result(Result.RESULT_FEATURE_UNSUPPORTED, self._unsupported_message())
        return response

    def _on_spawn_entities(self, request: SpawnEntities.Request, response: SpawnEntities.Response) -> SpawnEntities.Response:
        message = self._unsupported_message()
        response.result = _result(Result.RESULT_FEATURE_UNSUPPORTED, message)
        response.results = [SpawnResult(result=_result(Result.RESULT_FEATURE_UNSUPPORTED, message))
                            for _ in request.spawn_requests]
        return response
