"""Sim time as a run drives it: lock-stepped through ``/sim/step``, or followed on ``/clock`` when the sim runs free.

Lock-stepped, the paused sim advances only when asked, in whole control steps; ``rtf`` 0 asks as fast
as the machine allows, ``rtf`` > 0 paces the requests to that real-time factor. Either way the same
scenario gives the same numbers. Free-running (nodes already running, ``rtf`` > 0), the sim runs at its
own pace and the run follows ``/clock``.
"""

from __future__ import annotations

import contextlib
import itertools
import random
import time
from collections.abc import Callable, Iterable
from typing import Any

from rosgraph_msgs.msg import Clock

from sim_client.scenario.model.series import stamp_s
from sim_interfaces.srv import Step as StepSrv
from sim_ros.names import BATTERY_TOPIC, IMU_TOPIC, ODOM_TOPIC, wrench_topic
from sim_ros.session import RosSession, WaitTimeout

STARTUP_WALL_S = 90.0
SERVICE_WALL_S = 30.0
GOAL_END_WALL_S = 5.0  # wall seconds to wait for the results of goals /sim reports ended
# A step unanswered this long [s of wall time] is sent again with its id: /sim answers a repeated id without
# stepping again, so a lost request or answer costs this much, not the run (an answer is lost when the answering
# side has not matched the asking one yet: a fresh clone's run on a loaded machine once waited 30 s and failed).
STEP_RESEND_S = 2.0
CHUNK_S = 0.02  # sim time advanced between checks of conditions on measures [s]
# Sim time advanced at once when only goal ends (seen where they happen: /sim stops its step there) and
# times are awaited [s]: fewer /sim/step round trips per sim second, the same numbers. As fast as possible, a
# stride is 2 s of sim time: walk_2m recorded, lock-stepped on a warm bring-up, went from wall/sim 0.193 at 0.25 s
# to 0.161 at 1 s (medians of 4, alternated; 0.5 s: 0.170, 2 s: 0.151); on 29 November 1 s against 2 s, alternated,
# medians of 6: 0.173 -> 0.166. Well within what /sim's writers keep for a reader that lags, e.g. the recorder at
# the end of a burst (1000 messages: 10 s of /imu, 10 s of /joint_states at a scenario's 100 Hz; the runner waits
# for its streams at a run's end).
STRIDE_S = 2.0
# Paced (rtf > 0), or while a recorded camera is watched, a stride stays short: the sim moves in short jumps for
# whoever watches it at real time, and the camera's writer keeps its last 4 frames (0.4 s of sim time at 10 Hz)
# for the recorder, which the runner waits for after each step.
SHORT_STRIDE_S = 0.25
STREAM_RATES = ("imu_rate", "wrench_rate", "state_rate")  # /sim's rates of its periodic streams besides /clock's, /joint_states'


def stream_slack(topics: Iterable[str], periods: dict[str, float], namespace: str) -> dict[str, float]:
    """Of recorded ``topics`` (full names), /sim's periodic streams besides /clock and /joint_states: how long before a
    lock-stepped run's end [s of sim time] the last message of each may be stamped (a period of its rate, from
    ``periods`` by the names of ``STREAM_RATES``; /odom 0.05 s, as the runner waits for its own)."""
    slack: dict[str, float] = {}
    for topic in topics:
        name = topic.removeprefix(f"{namespace}/")
        rate_name = ("imu_rate" if name == IMU_TOPIC else "wrench_rate" if name.endswith(wrench_topic(""))
                     else "state_rate" if name == BATTERY_TOPIC else None)
        if name == ODOM_TOPIC:
            slack[topic] = 0.05
        elif rate_name in periods:
            slack[topic] = periods[rate_name] + 1e-6
    return slack


class StepFailure(RuntimeError):
    """A step could not be carried out (timeout, server missing, /sim refused); the run fails."""


def call_service(session: RosSession, client: Any, request: Any, what: str, resend_every_s: float | None = None) -> Any:
    """Wait for the service, call it and wait for its response (``SERVICE_WALL_S`` wall seconds each); with
    ``resend_every_s``, send the request again that often until answered (only a request safe to send twice)."""
    session.wait_for(client.service_is_ready, SERVICE_WALL_S, f"service {what}")
    if resend_every_s is None:
        return session.wait_future(client.call_async(request), SERVICE_WALL_S, f"response of {what}")
    return session.until_answered(lambda: client.call_async(request), SERVICE_WALL_S, f"response of {what}",
                                  every_s=resend_every_s, forget=client.remove_pending_request)


class SimTime:
    """The sim time of a run [s], and the means to let it pass.

    Args:
        session: the run's ROS session (its clock is sim time).
        lock_step: step the paused sim through ``/sim/step`` (else follow ``/clock``).
        rtf: real-time factor to pace lock-stepping to (0: as fast as possible); the free-running sim's.
        goals_done: how many of the run's goals have ended, to wait for the results of goals /sim
            reports ended in a step.
    """

    def __init__(self, session: RosSession, lock_step: bool, rtf: float, goals_done: Callable[[], int]) -> None:
        self.session = session
        self.lock_step = lock_step
        self.rtf = rtf
        self.clock = session.record(Clock, "clock", keep=10)  # the run's own: a reset restarts sim time at 0
        self._step = session.service_client(StepSrv, "sim/step")  # the session's (shared by a bring-up's runs)
        self._step_ids = itertools.count(random.SystemRandom().getrandbits(48) + 1)  # this run's step ids (nonzero)
        self._goals_done = goals_done
        self.control_dt = 0.0  # [s] of sim time per /sim/step step, measured by calibrate()
        self._sim_now = 0.0
        self._pace_anchor: tuple[float, float] | None = None  # (wall [s], sim [s]) that pacing counts from

    def now(self) -> float:
        """The latest sim time seen on /clock or in a /sim answer [s]."""
        latest = self.clock.latest
        if latest is not None:
            self._sim_now = max(self._sim_now, stamp_s(latest.clock))
        return self._sim_now

    def reached(self, sim_time: float) -> None:
        """Note a sim time [s] /sim answered with (a reset's)."""
        self._sim_now = max(self._sim_now, sim_time)

    def calibrate(self) -> None:
        """Lock-stepped: measure the sim time of one step. Free-running: wait for /clock."""
        if self.lock_step:
            t0 = self.step(1)
            self.control_dt = self.step(1) - t0
            if self.control_dt <= 0:
                raise StepFailure("/sim/step did not advance sim time; is the sim paused by someone else?")
        else:
            self.session.wait_for(lambda: self.clock.count > 0, STARTUP_WALL_S, "/clock")

    def step(self, steps: int) -> float:
        """Step the paused sim ``steps`` control steps; returns the sim time it reached [s]."""
        done_before = self._goals_done()
        # /sim stops early where a goal ends, so that the run sees each goal end where it happened.
        request = StepSrv.Request(steps=steps, stop_at_goal_end=True, request_id=next(self._step_ids))
        response = call_service(self.session, self._step, request, "/sim/step", resend_every_s=STEP_RESEND_S)
        if not response.success:
            raise StepFailure(f"/sim/step refused: {response.message}")
        self._sim_now = max(self._sim_now, response.sim_time)
        self.take_results(done_before, response.goals_ended)
        return float(response.sim_time)

    def take_results(self, done_before: int, ended: int) -> None:
        """Lock-stepped: wait for the results of ``ended`` goals /sim ended (in a step, or by a reset) before stepping
        on, so a goal's end is seen at the same sim time in every run. Bounded: a goal of another client ends too.

        A reset's goals were not waited for: with 1 s strides, a loaded machine's server answered a walk that a reset
        ended after the runner had stepped the 5 s that reset_mid_walk waits for it.
        """
        if not self.lock_step or ended <= 0:
            return

        def arrived() -> bool:
            return self._goals_done() >= done_before + ended

        with contextlib.suppress(WaitTimeout):
            self.session.wait_for(arrived, GOAL_END_WALL_S, "the results of goals that ended")

    def steps_for(self, dt: float) -> int:
        """Whole control steps in about ``dt`` [s] of sim time, at least one."""
        return max(1, round(dt / self.control_dt))

    def advance(self, dt: float) -> None:
        """Let about ``dt`` [s] of sim time pass."""
        target = self.now() + dt
        if self.lock_step:
            self._pace(self.step(self.steps_for(dt)))
        else:
            self.session.wait_for(lambda: self.now() >= target - 1e-9, max(10.0, 20.0 * dt / self.rtf), "sim time to advance")

    def _pace(self, sim_now: float) -> None:
        """At ``rtf`` > 0, wait until ``sim_now`` is due on the wall clock (the run's rhythm, not a wait for an event)."""
        if self.rtf <= 0.0:
            return
        wall = time.monotonic()
        if self._pace_anchor is None:
            self._pace_anchor = (wall, sim_now)
            return
        wall0, sim0 = self._pace_anchor
        delay = wall0 + (sim_now - sim0) / self.rtf - wall
        if delay > 0.0:
            time.sleep(delay)
