"""``/sim``'s own services: ``~/reset``, ``~/step``, ``~/pause``, ``~/resume`` and ``~/push``."""

from __future__ import annotations

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.node import Node
from std_srvs.srv import Trigger

from nodes.sim.control import SimControl, SteppingError
from sim_bridge import Simulation, UnknownNameError
from sim_interfaces.srv import Push, Reset, Step

MAX_STEP_REQUEST = 1_000_000  # control steps one ~/step call may ask for


class SimServices:
    """Serves ``/sim``'s own services on ``node``, one call at a time.

    Args:
        node: the sim node (the services are created on it).
        sim: its simulation.
        control: pauses, resets and steps it.
    """

    def __init__(self, node: Node, sim: Simulation, control: SimControl) -> None:
        self._node = node
        self._sim = sim
        self._control = control
        self._last_step: tuple[int, Step.Response] | None = None  # (request_id, answer) of the last step with an id
        services = MutuallyExclusiveCallbackGroup()
        node.create_service(Reset, "~/reset", self._on_reset, callback_group=services)
        node.create_service(Step, "~/step", self._on_step, callback_group=services)
        node.create_service(Push, "~/push", self._on_push, callback_group=services)
        node.create_service(Trigger, "~/pause", self._on_pause, callback_group=services)
        node.create_service(Trigger, "~/resume", self._on_resume, callback_group=services)

    def _on_reset(self, request: Reset.Request, response: Reset.Response) -> Reset.Response:
        with self._control.lock:
            try:
                self._control.reset_scene(request.keyframe or None)
            except UnknownNameError as error:
                response.success = False
                response.message = str(error)
                response.sim_time = self._sim.time
                return response
            response.success = True
            response.message = f"reset to keyframe {request.keyframe or self._sim.robot.default_keyframe!r}"
            response.sim_time = self._sim.time
        self._node.get_logger().info(response.message)
        return response

    def _on_push(self, request: Push.Request, response: Push.Response) -> Push.Response:
        body = request.body or self._sim.robot.base_body
        force, torque = request.wrench.force, request.wrench.torque
        with self._control.lock:
            response.sim_time = self._sim.time
            try:
                response.end_time = self._sim.push(body, (force.x, force.y, force.z), (torque.x, torque.y, torque.z),
                                                   request.duration)
            except (UnknownNameError, ValueError) as error:
                response.success = False
                response.message = str(error)
                return response
        response.success = True
        response.message = f"pushing {body} until t={response.end_time:.3f} s"
        return response

    def _on_pause(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        was = self._control.set_paused(True)
        response.success = True
        response.message = "already paused" if was else "paused"
        return response

    def _on_resume(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        was = self._control.set_paused(False)
        response.success = True
        response.message = "running" if was else "already running"
        return response

    def _on_step(self, request: Step.Request, response: Step.Response) -> Step.Response:
        """Step the paused sim; a request repeating the id of the last step is answered again without stepping."""
        with self._control.lock:
            last = self._last_step
            if request.request_id and last is not None and last[0] == request.request_id:
                answered = last[1]
                response.success, response.sim_time, response.goals_ended = (answered.success, answered.sim_time,
                                                                              answered.goals_ended)
                response.message = f"{answered.message} (request {request.request_id} again: answered, not stepped)"
                return response
            self._step(request, response)
            if request.request_id:
                self._last_step = (request.request_id, response)
        return response

    def _step(self, request: Step.Request, response: Step.Response) -> None:
        """Fill ``response`` for ``request`` (under the control lock)."""
        sim = self._sim
        if not self._control.paused:
            response.success = False
            response.message = "step is only allowed while paused; call ~/pause first"
        elif not 1 <= request.steps <= MAX_STEP_REQUEST:
            response.success = False
            response.message = f"steps must be in [1, {MAX_STEP_REQUEST}], got {request.steps}"
        else:
            try:
                response.goals_ended = self._control.step_while_paused(
                    sim.time + request.steps * sim.control_timestep - 1e-9, request.stop_at_goal_end)
            except SteppingError as error:
                response.goals_ended = error.goals_ended
                response.success = False
                response.message = f"{error}; the simulation was reset"
                response.sim_time = sim.time
                return
            response.success = True
            response.message = (f"stepped {request.steps} control steps" if not response.goals_ended
                                or not request.stop_at_goal_end else "stopped early: a goal ended")
        response.sim_time = sim.time
