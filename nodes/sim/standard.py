"""The ROS simulation standard (``simulation_interfaces``) on ``/sim``, as Gazebo and Isaac Sim serve it.

Served under ``/sim/``: get_simulator_features, reset_simulation, get_simulation_state,
set_simulation_state, step_simulation, the simulate_steps action, and the entity services of
:mod:`nodes.sim.standard_entities` (get_entities, get_entities_states, get_entity_state,
set_entity_state, get_entity_info, get_entity_bounds; and spawn_entity, spawn_entities,
delete_entity, get_spawnables, which answer RESULT_FEATURE_UNSUPPORTED: a MuJoCo model is compiled,
and the controllers, skills and /tf publishers of /sim hold its ids, so bodies are not added or
removed at run time). A whole scene is replaced by another (load_world and the other world services,
:mod:`nodes.sim.world`): everything scene-bound is built again.

Conventions (also in ``custom_info`` of the features):
- one step is one physics step (``mj_step``, the model's timestep); the controllers still run on
  their control-step grid, however the steps are split;
- entity states are ground truth in ``world``: the pose of the entity's canonical frame (a robot's
  base body), the velocity of its origin and its angular velocity in world axes;
- STOPPED is paused at the keyframe with sim time at 0 (SetSimulationState STOPPED pauses and resets
  with SCOPE_ALL); it becomes PAUSED at the first step and PLAYING when resumed;
- a reset of time goes with a reset of the state (goals in the control step measure sim time).

Every refusal is a result with the standard's code and a message naming what is allowed; nothing is
changed by a refused call. Changes happen under the node's lock (:class:`~nodes.sim.control.SimControl`),
as /sim's own services do.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.node import Node

from nodes.sim.control import SimControl, SteppingError
from nodes.sim.standard_entities import OK, EntityServices, result
from sim_bridge import Simulation
from simulation_interfaces.action import SimulateSteps
from simulation_interfaces.msg import Result, SimulationState, SimulatorFeatures
from simulation_interfaces.srv import (
    GetSimulationState,
    GetSimulatorFeatures,
    ResetSimulation,
    SetSimulationState,
    StepSimulation,
)

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
    SimulatorFeatures.WORLD_LOADING, SimulatorFeatures.AVAILABLE_WORLDS, SimulatorFeatures.WORLD_INFO_GETTING,  # nodes.sim.world
)
STATE_NAMES = {SimulationState.STATE_STOPPED: "STOPPED", SimulationState.STATE_PLAYING: "PLAYING",
               SimulationState.STATE_PAUSED: "PAUSED", SimulationState.STATE_QUITTING: "QUITTING",
               SimulationState.STATE_NO_WORLD: "NO_WORLD", SimulationState.STATE_LOADING_WORLD: "LOADING_WORLD"}
SCOPE_BITS = ResetSimulation.Request.SCOPE_TIME | ResetSimulation.Request.SCOPE_STATE | ResetSimulation.Request.SCOPE_SPAWNED


class SimulationStandard:
    """Creates the standard's services and action on the sim node and answers them.

    Args:
        node: the configured sim node (the services and the action are created on it).
        sim: its simulation.
        control: pauses, resets and steps it, under its lock.
    """

    def __init__(self, node: Node, sim: Simulation, control: SimControl) -> None:
        self._node = node
        self._sim = sim
        self._control = control
        # Paused at the keyframe with nothing stepped since: the standard's STOPPED (also at a paused start).
        self._stopped_at: float | None = sim.time if control.paused else None
        self._action_lock = threading.Lock()  # one SimulateSteps goal at a time
        changes = MutuallyExclusiveCallbackGroup()  # one at a time
        queries = ReentrantCallbackGroup()
        services: tuple[tuple[Any, str, Callable[[Any, Any], Any], Any], ...] = (
            (GetSimulatorFeatures, "get_simulator_features", self._on_features, queries),
            (GetSimulationState, "get_simulation_state", self._on_get_state, queries),
            (SetSimulationState, "set_simulation_state", self._on_set_state, changes),
            (ResetSimulation, "reset_simulation", self._on_reset, changes),
            (StepSimulation, "step_simulation", self._on_step, changes),
        )
        for srv_type, name, callback, group in services:
            node.create_service(srv_type, f"~/{name}", callback, callback_group=group)
        self._entities = EntityServices(node, sim, control, changes, queries, self._state_changed)
        self._action = ActionServer(
            node, SimulateSteps, "~/simulate_steps", execute_callback=self._execute_steps,
            goal_callback=lambda goal: GoalResponse.ACCEPT, cancel_callback=lambda handle: CancelResponse.ACCEPT,
            callback_group=ReentrantCallbackGroup())

    def _state_changed(self) -> None:
        self._stopped_at = None  # no longer the state of a reset

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
            "Spawning and deleting are not supported (a compiled MuJoCo model); move entities with SetEntityState. "
            "Worlds are the robot's scenes, loaded by name (load_world uri 'course' or 'g1/course').")
        return response

    def _state(self) -> int:
        control = self._control
        if not control.paused and control.physics_running:
            return SimulationState.STATE_PLAYING
        if self._stopped_at is not None and self._stopped_at == self._sim.time:
            return SimulationState.STATE_STOPPED
        return SimulationState.STATE_PAUSED

    def _on_get_state(self, request: GetSimulationState.Request,
                      response: GetSimulationState.Response) -> GetSimulationState.Response:
        with self._control.lock:
            response.state.state = self._state()
        response.result = result(OK)
        return response

    def _on_set_state(self, request: SetSimulationState.Request,
                      response: SetSimulationState.Response) -> SetSimulationState.Response:
        target = request.state.state
        control = self._control
        settable = (SimulationState.STATE_PLAYING, SimulationState.STATE_PAUSED, SimulationState.STATE_STOPPED)
        with control.lock:
            current = self._state()
            if target not in settable:
                allowed = ", ".join(f"{STATE_NAMES[s]} ({s})" for s in settable)
                name = STATE_NAMES.get(target, "an unknown state")
                code = Result.RESULT_FEATURE_UNSUPPORTED if target == SimulationState.STATE_QUITTING \
                    else SetSimulationState.Response.INCORRECT_TRANSITION
                why = " (stop the sim_node process, or use the lifecycle shutdown transition)" \
                    if target == SimulationState.STATE_QUITTING else ""
                response.result = result(code, f"cannot set {name} ({target}){why}; allowed: {allowed}")
                return response
            if target == current:
                response.result = result(SetSimulationState.Response.ALREADY_IN_TARGET_STATE,
                                         f"already {STATE_NAMES[target]}")
                return response
            if target == SimulationState.STATE_PLAYING:
                if not control.physics_running:
                    response.result = result(
                        SetSimulationState.Response.STATE_TRANSITION_ERROR,
                        "the /sim lifecycle node is not active, so its physics does not run: activate it "
                        "(/sim/change_state) first; stepping works meanwhile")
                    return response
                control.set_paused(False)
                self._stopped_at = None
            elif target == SimulationState.STATE_PAUSED:
                control.set_paused(True)  # from STOPPED: stays where it is, now counted as paused
                self._stopped_at = None
            else:
                control.set_paused(True)
                control.reset_scene(keep_time=False)
                self._stopped_at = self._sim.time
        response.result = result(OK, f"{STATE_NAMES[current]} -> {STATE_NAMES[target]}")
        self._node.get_logger().info(f"simulation state: {response.result.error_message}")
        return response

    def _on_reset(self, request: ResetSimulation.Request, response: ResetSimulation.Response) -> ResetSimulation.Response:
        scope = request.scope
        req = ResetSimulation.Request
        whole = scope in (req.SCOPE_DEFAULT, req.SCOPE_ALL)
        allowed = "SCOPE_DEFAULT (0) or SCOPE_ALL (255): state and time; SCOPE_STATE (2): state, time runs on; " \
                  "SCOPE_TIME | SCOPE_STATE (3)"
        if not whole and scope & ~SCOPE_BITS:
            response.result = result(Result.RESULT_FEATURE_UNSUPPORTED, f"unknown scope bits in {scope}; allowed: {allowed}")
            return response
        if not whole and scope & req.SCOPE_SPAWNED:
            response.result = result(Result.RESULT_FEATURE_UNSUPPORTED,
                                     f"SCOPE_SPAWNED: spawning is not supported, nothing is ever spawned; allowed: {allowed}")
            return response
        if not whole and not scope & req.SCOPE_STATE:
            response.result = result(Result.RESULT_FEATURE_UNSUPPORTED,
                                     "SCOPE_TIME alone is not supported: the clock restarts together with the state "
                                     f"(goals in the control step measure sim time); allowed: {allowed}")
            return response
        keep_time = not (whole or scope & req.SCOPE_TIME)
        control = self._control
        with control.lock:
            control.reset_scene(keep_time=keep_time)
            # Paused and reset with the clock: the standard's STOPPED.
            self._stopped_at = self._sim.time if control.paused and not keep_time else None
            response.result = result(OK, f"reset to keyframe {self._sim.robot.default_keyframe!r}"
                                         f"{'' if keep_time else ', sim time 0'}")
        self._node.get_logger().info(f"reset_simulation: {response.result.error_message}")
        return response

    # ----- stepping ----------------------------------------------------------------------
    def _holding(self) -> bool:
        """Whether nothing else steps: paused, or the physics thread does not run (an inactive node)."""
        return self._control.paused or not self._control.physics_running

    def _step_refusal(self, steps: int, limit: int) -> Result | None:
        """Why ``steps`` cannot be stepped now (a result to answer), or None."""
        if not self._holding():
            return result(Result.RESULT_OPERATION_FAILED,
                          "stepping needs a paused simulation: set STATE_PAUSED with set_simulation_state (or /sim/pause)")
        if not 1 <= steps <= limit:
            return result(Result.RESULT_OPERATION_FAILED, f"steps must be in [1, {limit}] physics steps "
                          f"of {self._sim.physics_timestep * 1e3:g} ms, got {steps}")
        return None

    def _advance(self, steps: int) -> Result | None:
        """Step a paused simulation under the lock; a result when it cannot (resumed meanwhile, a fault)."""
        sim = self._sim
        with self._control.lock:
            if not self._holding():
                return result(Result.RESULT_OPERATION_FAILED, "the simulation was resumed while stepping; stopped there")
            if not self._node.context.ok():
                return result(Result.RESULT_OPERATION_FAILED, "/sim is shutting down")
            try:
                self._control.step_while_paused(sim.time + steps * sim.physics_timestep - 1e-9)
            except SteppingError as error:
                return result(Result.RESULT_OPERATION_FAILED, f"{error}; the simulation was reset to its keyframe")
            self._stopped_at = None
        return None

    def _chunk(self) -> int:
        """Physics steps per stretch of stepping (the lock is released between stretches)."""
        return max(1, int(STRETCH_S / self._sim.physics_timestep))

    def _on_step(self, request: StepSimulation.Request, response: StepSimulation.Response) -> StepSimulation.Response:
        steps = int(request.steps)
        with self._control.lock:
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
        response.result = result(OK, f"stepped {steps} physics steps; sim time {self._sim.time:.6f} s")
        return response

    def _execute_steps(self, handle: ServerGoalHandle) -> SimulateSteps.Result:
        steps = int(handle.request.steps)
        outcome = SimulateSteps.Result()
        if not self._action_lock.acquire(blocking=False):
            outcome.result = result(Result.RESULT_OPERATION_FAILED,
                                    "another SimulateSteps goal is running; cancel it or wait for its result")
            handle.abort()
            return outcome
        try:
            with self._control.lock:
                refusal = self._step_refusal(steps, MAX_ACTION_STEPS)
            if refusal is not None:
                outcome.result = refusal
                handle.abort()
                return outcome
            feedback = SimulateSteps.Feedback()
            done = 0
            next_feedback = 0.0
            while done < steps:
                if handle.is_cancel_requested:
                    outcome.result = result(Result.RESULT_OK, f"canceled after {done} of {steps} steps")
                    handle.canceled()
                    return outcome
                count = min(self._chunk(), steps - done)
                failure = self._advance(count)
                if failure is not None:
                    failure.error_message += f" (after {done} of {steps} steps)"
                    outcome.result = failure
                    handle.abort()
                    return outcome
                done += count
                now = time.monotonic()
                if now >= next_feedback or done == steps:  # a stretch of steps takes well under a millisecond
                    next_feedback = now + FEEDBACK_PERIOD_S
                    feedback.completed_steps, feedback.remaining_steps = done, steps - done
                    handle.publish_feedback(feedback)
            outcome.result = result(OK, f"stepped {steps} physics steps; sim time {self._sim.time:.6f} s")
            handle.succeed()
            return outcome
        finally:
            self._action_lock.release()
