"""``sim``: the project's small command line (ros2cli is not on PyPI).

    sim up [--robot g1|panda] [--rtf X] [--foxglove]   bring up /sim and every server for the robot
    sim walk 2.0 [--speed 0.3]                   send a goal, stream feedback; Ctrl-C cancels it
    sim navigate X Y YAW
    sim move-arm X Y Z [--rpy R P Y] [--arm NAME]
    sim pick BOX --place X Y Z
    sim push FX FY FZ [--duration S] [--body B]  push a body (default: the base) with a force [N]
    sim param get|set|list|describe NODE [NAME] [VALUE]
    sim watch                                    live view of sim time, RTF, base pose, goals
    sim snapshot frame.png [--camera head_camera] save the camera's next image as a PNG
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import yaml

import robot_models
from sim_ros.processes import BIN

GOAL_WAIT_S = 3600.0
CLOSE_PROMPTLY_S = 15.0  # [s of wall time] `sim watch` waits this long for its ROS node to close after Ctrl-C


@contextmanager
def _interrupts() -> Iterator[threading.Event]:
    """An event set by Ctrl-C (SIGINT) or SIGTERM while the block runs; the old handlers come back after.

    rclpy's own SIGINT handler shuts the ROS context down without raising KeyboardInterrupt,
    so a command that must stop (or cancel its goal) on Ctrl-C installs this one instead.
    """
    event = threading.Event()
    previous = {sig: signal.signal(sig, lambda *_: event.set()) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield event
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


@contextmanager
def _closed_promptly(session: Any) -> Iterator[Any]:
    """``session`` (a RosSession), closed on the way out within ``CLOSE_PROMPTLY_S``; a close that hangs longer
    (a Fast DDS shutdown deadlock: README, Known limits) ends the process, so that Ctrl-C always quits."""
    try:
        yield session
    finally:
        closer = threading.Thread(target=session.close, name="close", daemon=True)
        closer.start()
        closer.join(CLOSE_PROMPTLY_S)
        if closer.is_alive():
            failed = sys.exc_info()[0] is not None
            print(f"the ROS node did not close within {CLOSE_PROMPTLY_S:g} s; exiting without it", file=sys.stderr)
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(1 if failed else 0)


def _feedback_line(feedback: Any, t: float) -> str:
    from sim_client.scenario.running.progress import feedback_summary

    summary = feedback_summary(feedback)
    return f"[t={t:8.2f} s] {summary}"


def _run_goal(client_type: Any, goal: Any, action_label: str, timeout: float, namespace: str = "") -> int:
    from sim_client.actions import ActionError
    from sim_ros.session import RosSession, WaitTimeout

    with RosSession("sim_cli", use_sim_time=True, namespace=namespace) as session:
        client = client_type(session)
        try:
            handle = client.send(goal, timeout=timeout)
        except (ActionError, WaitTimeout) as error:
            print(f"error: {error}", file=sys.stderr)
            return 2
        if not handle.accepted:
            print(f"{action_label}: goal rejected by {client.name} (see the server's log for the reason)")
            return 1
        print(f"{action_label}: goal accepted by {client.name}; Ctrl-C cancels it")
        shown = 0
        with _interrupts() as interrupted:
            canceled = False
            deadline = time.monotonic() + GOAL_WAIT_S
            while not handle.done and time.monotonic() < deadline:
                history = handle.feedback_history
                for sample in history[shown:]:
                    print(_feedback_line(sample.feedback, sample.sim_time), flush=True)
                shown = len(history)
                if interrupted.is_set():
                    interrupted.clear()
                    if canceled:  # a second Ctrl-C: stop waiting for the server's answer
                        print(f"{action_label}: left without the result (the cancel was sent)", flush=True)
                        return 130
                    canceled = True
                    print("canceling the goal ... (Ctrl-C again to leave without waiting)", flush=True)
                    handle.cancel()
                interrupted.wait(0.05)  # the feedback print period, or at once on Ctrl-C
            outcome = handle.wait(10.0)
        print(f"{action_label}: {outcome}")
        if outcome.result is not None:
            for name in ("final_distance", "final_position_error", "placement_error"):
                if hasattr(outcome.result, name):
                    print(f"  {name}: {getattr(outcome.result, name):.4f}")
        return 0 if outcome.succeeded else 1


def _push(options: argparse.Namespace) -> int:
    from sim_client.actions import push_request
    from sim_interfaces.srv import Push
    from sim_ros.session import RosSession, WaitTimeout

    request = push_request(options.body, options.force, options.torque, options.duration)
    with RosSession("sim_cli_push", use_sim_time=False, namespace=options.namespace) as session:
        try:
            response = session.call(Push, "sim/push", request, timeout=options.timeout)
        except WaitTimeout as error:
            print(f"error: {error}", file=sys.stderr)
            return 2
    print(response.message if response.success else f"refused: {response.message}")
    return 0 if response.success else 1


def _parse_value(text: str) -> Any:
    """A parameter value from the command line: YAML scalars (0.4, 3, true, text)."""
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError:
        return text
    return value if isinstance(value, (bool, int, float, str, list)) else text


def _param(options: argparse.Namespace) -> int:
    from sim_client.parameters import ParameterError, Parameters
    from sim_ros.session import RosSession, WaitTimeout

    with RosSession("sim_cli_param", use_sim_time=False, namespace=options.namespace) as session:
        params = Parameters(session, options.node, timeout=options.timeout)
        try:
            if options.verb == "list":
                for name in params.list():
                    print(f"  {name}")
                return 0
            if not options.name:
                print("error: give the parameter NAME", file=sys.stderr)
                return 2
            if options.verb == "get":
                value = params.get(options.name)
                print(f"{type(value).__name__} value is: {value}")
                return 0
            if options.verb == "describe":
                print(params.describe(options.name))
                return 0
            if options.value is None:
                print("error: give the VALUE to set", file=sys.stderr)
                return 2
            ok, reason = params.set(options.name, _parse_value(options.value))
            print("Set parameter successful" if ok else f"Setting parameter failed: {reason}")
            return 0 if ok else 1
        except (ParameterError, WaitTimeout) as error:
            print(f"error: {error}", file=sys.stderr)
            return 2


def _watch(options: argparse.Namespace) -> int:
    """Live view until Ctrl-C; a Ctrl-C that comes while it is still starting quits as quietly."""
    try:
        return _watch_view(options)
    except KeyboardInterrupt:
        return 0


def _watch_view(options: argparse.Namespace) -> int:
    from action_msgs.msg import GoalStatus, GoalStatusArray
    from nav_msgs.msg import Odometry
    from rich.console import Console
    from rich.live import Live
    from rich.table import Table
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import Float64

    from sim_client.actions import ACTION_CLIENTS
    from sim_client.scenario.model.series import yaw_of
    from sim_client.scenario.running.progress import feedback_summary
    from sim_ros.session import RosSession

    with _closed_promptly(RosSession("sim_watch", use_sim_time=False, namespace=options.namespace)) as session:
        clock = session.record(Clock, "clock", keep=2)
        rtf = session.record(Float64, "sim/real_time_factor", keep=2)
        odom = session.record(Odometry, "odom", keep=2)
        feedback: dict[str, Any] = {}
        status: dict[str, Any] = {}
        for client in ACTION_CLIENTS.values():
            name = client.default_name
            feedback[name] = session.record(client.action_type.Impl.FeedbackMessage, f"{name}/_action/feedback", keep=50)
            status[name] = session.record(GoalStatusArray, f"{name}/_action/status", keep=2)
        active_states = (GoalStatus.STATUS_ACCEPTED, GoalStatus.STATUS_EXECUTING, GoalStatus.STATUS_CANCELING)

        def view() -> Table:
            table = Table(title="sim watch (Ctrl-C to quit)", show_header=False, min_width=70)
            table.add_column("what", style="bold")
            table.add_column("value")
            stamp = clock.latest.clock if clock.latest else None
            table.add_row("sim time", f"{stamp.sec + stamp.nanosec * 1e-9:.2f} s" if stamp else "waiting for /clock ...")
            table.add_row("real-time factor", f"{rtf.latest.data:.2f}" if rtf.latest else "-")
            if odom.latest is not None:
                p = odom.latest.pose.pose
                v = odom.latest.twist.twist.linear
                table.add_row(f"base ({odom.latest.child_frame_id})",
                              f"x {p.position.x:+.3f}  y {p.position.y:+.3f}  z {p.position.z:.3f} m  "
                              f"yaw {math.degrees(yaw_of(p.orientation)):+.1f} deg  speed {math.hypot(v.x, v.y):.2f} m/s")
            any_goal = False
            for name, rec in status.items():
                latest = rec.latest
                if latest is None:
                    continue
                for goal_status in latest.status_list:
                    if goal_status.status not in active_states:
                        continue
                    any_goal = True
                    uuid = bytes(goal_status.goal_info.goal_id.uuid)
                    text = "no feedback yet"
                    for message in reversed(feedback[name].messages()):
                        if bytes(message.goal_id.uuid) == uuid:
                            text = feedback_summary(message.feedback)
                            break
                    table.add_row(f"goal {name} {uuid.hex()[:8]}", text)
            if not any_goal:
                table.add_row("active goals", "none")
            return table

        console = Console()
        if options.once:
            session.wait_for(lambda: clock.latest is not None and odom.latest is not None, options.timeout, "/clock and /odom")
            console.print(view())
            return 0
        if not console.is_terminal:  # piped into a log or another program: one snapshot per second
            with _interrupts() as interrupted:
                while True:
                    console.print(view())
                    if interrupted.wait(1.0):
                        return 0
        with _interrupts() as interrupted, Live(view(), console=console, refresh_per_second=4) as live:
            while not interrupted.wait(0.25):  # the terminal refresh period, until Ctrl-C
                live.update(view())
    return 0


def _snapshot(options: argparse.Namespace) -> int:
    """Save the next image of a camera of /sim as a PNG; print its stamp, size and brightness."""
    import numpy as np
    from matplotlib import image as mpimg
    from sensor_msgs.msg import Image

    from sim_ros.session import RosSession, WaitTimeout

    with RosSession("sim_snapshot", use_sim_time=True, namespace=options.namespace) as session:
        images = session.record(Image, f"{options.camera}/image_raw", keep=1)
        try:
            msg = session.wait_for(lambda: images.latest, options.timeout, f"an image on /{options.camera}/image_raw")
        except WaitTimeout as error:
            print(f"sim snapshot: {error} (is /sim up with a robot that has this camera?)", file=sys.stderr)
            return 1
    if msg.encoding != "rgb8":
        print(f"sim snapshot: encoding {msg.encoding!r} is not rgb8", file=sys.stderr)
        return 1
    pixels = np.frombuffer(bytes(msg.data), dtype=np.uint8).reshape(msg.height, msg.width, 3)
    mpimg.imsave(options.out, pixels)
    stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
    print(f"{options.out}: {msg.width}x{msg.height} from {msg.header.frame_id} at t={stamp:.3f} s, "
          f"mean brightness {pixels.mean():.1f} of 255")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="sim", description="Drive the headless simulator: bring it up, send goals, tune parameters, watch.")
    parser.add_argument("--namespace", default="", help="the bring-up's namespace (bringup --namespace); default: the root")
    sub = parser.add_subparsers(dest="command", required=True)
    up = sub.add_parser("up", help="bring up /sim and every server for the robot (bringup)")
    up.add_argument("--robot", choices=robot_models.ROBOT_NAMES, default=robot_models.G1)
    up.add_argument("--scene", default="", help=f"scene variant ({robot_models.scenes_summary()}); default: the robot's own")
    up.add_argument("--rtf", type=float, default=1.0, help="real-time factor; 0 = as fast as possible")
    up.add_argument("--foxglove", action="store_true", help="serve the watched topics to the Foxglove app (WebSocket)")
    up.add_argument("--foxglove-port", type=int, default=8765, help="its TCP port (default 8765)")
    up.add_argument("--foxglove-host", default="127.0.0.1", help="its address (default 127.0.0.1: this machine only)")
    walk = sub.add_parser("walk", help="walk a distance [m] straight ahead (negative = backwards)")
    walk.add_argument("distance", type=float)
    walk.add_argument("--speed", type=float, default=0.0, help="[m/s]; 0 = the walking_speed parameter")
    walk.add_argument("--timeout", type=float, default=0.0, help="[s of sim time]; 0 = automatic")
    nav = sub.add_parser("navigate", help="walk to a pose (x, y [m], yaw [rad]) around obstacles")
    nav.add_argument("x", type=float)
    nav.add_argument("y", type=float)
    nav.add_argument("yaw", type=float, nargs="?", default=0.0)
    move = sub.add_parser("move-arm", help="move an end effector to a position [m] (world frame)")
    move.add_argument("x", type=float)
    move.add_argument("y", type=float)
    move.add_argument("z", type=float)
    move.add_argument("--rpy", type=float, nargs=3, metavar=("R", "P", "Y"), help="orientation [rad]; omitted = position only")
    move.add_argument("--arm", default="", help="arm name (panda: arm; g1: left_arm, right_arm)")
    move.add_argument("--tolerance", type=float, default=0.005, help="position tolerance [m]")
    pick = sub.add_parser("pick", help="pick a box and place it")
    pick.add_argument("box")
    pick.add_argument("--place", type=float, nargs=3, metavar=("X", "Y", "Z"), required=True, help="[m]; Z <= 0 = on the table")
    for p in (walk, nav, move, pick):
        p.add_argument("--server-timeout", type=float, default=30.0, help="wall seconds to wait for the action server")
    push = sub.add_parser("push", help="push a body with a force [N] (world frame) for a while; e.g. sim push 0 150 0")
    push.add_argument("force", type=float, nargs=3, metavar=("FX", "FY", "FZ"))
    push.add_argument("--torque", type=float, nargs=3, default=(0.0, 0.0, 0.0), metavar=("TX", "TY", "TZ"), help="[N m]")
    push.add_argument("--duration", type=float, default=0.1, help="[s of sim time]")
    push.add_argument("--body", default="", help="body name; empty = the robot's base body")
    push.add_argument("--timeout", type=float, default=10.0, help="wall seconds to wait for /sim")
    param = sub.add_parser("param", help="get, set, list or describe a node's parameters")
    param.add_argument("verb", choices=("get", "set", "list", "describe"))
    param.add_argument("node")
    param.add_argument("name", nargs="?")
    param.add_argument("value", nargs="?")
    param.add_argument("--timeout", type=float, default=10.0)
    watch = sub.add_parser("watch", help="live view of sim time, real-time factor, base pose and active goals")
    watch.add_argument("--once", action="store_true", help="print one snapshot and exit")
    watch.add_argument("--timeout", type=float, default=30.0)
    snapshot = sub.add_parser("snapshot", help="save a camera's next image as a PNG (G1: head_camera; Panda: scene_camera)")
    snapshot.add_argument("out", help="the PNG file to write")
    snapshot.add_argument("--camera", default="head_camera", help="the camera's name (its topic: /<camera>/image_raw)")
    snapshot.add_argument("--timeout", type=float, default=30.0, help="wall seconds to wait for an image")
    return parser


def main(argv: list[str] | None = None) -> int:
    options = build_parser().parse_args(argv)
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    if options.command == "up":
        args = ["bringup", "--robot", options.robot, *(["--scene", options.scene] if options.scene else []),
                "--rtf", f"{options.rtf:g}"]
        if options.namespace:
            args += ["--namespace", options.namespace]
        if options.foxglove:
            args += ["--foxglove", "--foxglove-port", str(options.foxglove_port), "--foxglove-host", options.foxglove_host]
        print(f"running: {' '.join(args)}  (Ctrl-C stops)", flush=True)
        os.execv(str(BIN / "bringup"), args)
    if options.command == "param":
        return _param(options)
    if options.command == "watch":
        return _watch(options)
    if options.command == "push":
        return _push(options)
    if options.command == "snapshot":
        return _snapshot(options)
    from sim_client.actions import MoveArmClient, NavigateClient, PickPlaceClient, WalkClient

    if options.command == "walk":
        return _run_goal(WalkClient, WalkClient.goal(options.distance, options.speed, options.timeout),
                         f"walk {options.distance:g} m", options.server_timeout, options.namespace)
    if options.command == "navigate":
        return _run_goal(NavigateClient, NavigateClient.goal(options.x, options.y, options.yaw),
                         f"navigate to ({options.x:g}, {options.y:g}, {options.yaw:g})", options.server_timeout,
                         options.namespace)
    if options.command == "move-arm":
        goal = MoveArmClient.goal(options.x, options.y, options.z, rpy=tuple(options.rpy) if options.rpy else None,
                                  arm=options.arm, position_tolerance=options.tolerance,
                                  orientation_tolerance=0.05 if options.rpy else 0.0)
        what = f"move-arm to ({options.x:g}, {options.y:g}, {options.z:g})"
        return _run_goal(MoveArmClient, goal, what, options.server_timeout, options.namespace)
    goal = PickPlaceClient.goal(options.box, tuple(options.place))
    return _run_goal(PickPlaceClient, goal, f"pick {options.box}", options.server_timeout, options.namespace)


if __name__ == "__main__":
    sys.exit(main())
