"""How ``/sim`` advances its simulation: from one publication stop to the next, its in-loop plugins around each stretch.

A stretch of stepping is whole physics steps up to the next publication stop
(:meth:`~nodes.sim.publication.Publications.next_stop`): the plugins run before it (a stale
/cmd_vel expires) and after it (sensors, cameras, the skills' states), then the streams due are
published. A step that fails (the physics diverged, a controller raised) is logged and the
simulation reset to its keyframe. Every call is made under the simulation's lock.
"""

from __future__ import annotations

import math
import traceback
from typing import Any

from nodes.sim.control import SteppingError
from nodes.sim.controllers import InLoopPlugins
from nodes.sim.publication import Publications
from sim_bridge import Simulation, SimulationFaultError

MAX_CHUNK_S = 0.05  # longest stretch of sim time stepped without releasing the lock [s]


class Stepper:
    """Advances one simulation (see the module's text).

    Args:
        sim: the simulation.
        plugins: its in-loop controllers, sensors, cameras and skills.
        publications: its streams and their schedule.
        logger: the sim node's logger (a failed step is reported there).
    """

    def __init__(self, sim: Simulation, plugins: InLoopPlugins, publications: Publications, logger: Any) -> None:
        self._sim = sim
        self._plugins = plugins
        self._publications = publications
        self._logger = logger

    def advance(self) -> None:
        """The physics thread's stretch: up to the next stop, at most ``MAX_CHUNK_S``; a failed step is recovered from."""
        sim, plugins = self._sim, self._plugins
        now = sim.time
        dt = sim.physics_timestep
        chunk = min(MAX_CHUNK_S, plugins.max_chunk)
        steps = max(1, min(int(chunk / dt), math.ceil((self._publications.next_stop() - now) / dt - 1e-6)))
        plugins.before_step(now)
        try:
            sim.step_physics(steps)
        except Exception as error:  # noqa: BLE001 - the physics thread must survive a controller failure
            self.recover(error)
        plugins.after_step()
        self._publications.publish_due(sim.time)

    def advance_to(self, until_s: float, stop_at_goal_end: bool = False) -> int:
        """Step up to sim time ``until_s`` [s] in stretches, publishing what falls due; returns how many skill goals ended.

        With ``stop_at_goal_end``, it returns at the end of the first stretch in which a skill goal ended.

        Raises:
            SteppingError: a step failed; the simulation was reset to its keyframe before this is raised.
        """
        ended = 0
        try:
            while self._sim.time < until_s and not (stop_at_goal_end and ended):
                ended += self._advance_bounded(until_s)
        except Exception as error:  # a failed step is reported, the node keeps serving
            self.recover(error)
            raise SteppingError(str(error), ended) from error
        return ended

    def _advance_bounded(self, target: float) -> int:
        """One stretch of stepping toward ``target`` [s]; returns how many skill goals ended in it."""
        sim, plugins = self._sim, self._plugins
        due = min(self._publications.next_stop(), target)
        dt = sim.physics_timestep
        steps = max(1, math.ceil((due - sim.time) / dt - 1e-6))
        plugins.before_step(sim.time)
        sim.step_physics(steps)
        ended = plugins.after_step()
        self._publications.publish_due(sim.time)
        return ended

    def recover(self, error: Exception) -> None:
        """After the physics diverged or a controller failed: log why, reset to the keyframe."""
        sim = self._sim
        if isinstance(error, SimulationFaultError):
            self._logger.error(f"{error}; resetting to keyframe {sim.robot.default_keyframe!r}")
        else:
            self._logger.error(
                f"in-loop controller failed: {''.join(traceback.format_exception(error))}"
                f"resetting to keyframe {sim.robot.default_keyframe!r}")
        sim.reset()
        self._plugins.on_fault(str(error))
