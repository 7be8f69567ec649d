"""What every node's console script does before and around ROS: ``--help``, and start-up errors in one line.

A node's ``main`` answers ``-h``/``--help`` (given before ``--ros-args``) at once, without starting
ROS, with its parameters, their defaults and ranges. A bad start-up parameter (out of range, wrong
type) or an unreadable params file ends the process with one line on stderr that names the
parameter, the value and what is allowed, and exit code :data:`EXIT_BAD_START`; no traceback.
"""

from __future__ import annotations

import contextlib
import faulthandler
import os
import re
import signal
import sys
from collections.abc import Iterator, Sequence
from typing import Any, NoReturn

from nodes.runtime.parameters import ParameterSpec, StartupError, allowed
from sim_ros.scheduling import yield_to_physics

EXIT_BAD_START = 2


def help_requested(argv: Sequence[str]) -> bool:
    """``-h`` or ``--help`` among the arguments before ``--ros-args`` (``argv[0]`` is the program)."""
    own = list(argv[1:])
    if "--ros-args" in own:
        own = own[: own.index("--ros-args")]
    return any(arg in ("-h", "--help") for arg in own)


def help_text(program: str, node_name: str, summary: str, specs: Sequence[ParameterSpec], notes: str = "") -> str:
    """The ``--help`` page of a node: usage, what it does, every parameter with default and range."""
    width = max((len(spec.name) for spec in specs), default=10)
    lines = [
        f"usage: {program} [-h] [--ros-args [-p NAME:=VALUE ...] [--params-file FILE] [-r __ns:=/NS] ...]",
        "",
        summary.strip(),
        "",
        f"parameters of /{node_name} (set at start with -p NAME:=VALUE; live with `ros2 param set /{node_name} NAME VALUE`",
        "or `sim param set`; read-only ones only at start):",
    ]
    for spec in specs:
        flags = ", read-only" if spec.read_only else ""
        default = str(spec.default).lower() if isinstance(spec.default, bool) else repr(spec.default)
        lines.append(f"  {spec.name:<{width}}  {spec.description}")
        lines.append(f"  {'':<{width}}  default {default}; {allowed(spec)}{flags}")
    if notes:
        lines += ["", notes.strip()]
    return "\n".join(lines) + "\n"


def params_file_error(error: Exception) -> StartupError:
    """The one-line error for ROS arguments rcl could not read (a params file above all)."""
    text = str(error).replace("\n", " ")
    cause = re.search(r"failed to initialize rcl: (.*?)(?:, at /\S+)+\s*$", text)
    return StartupError(f"cannot read the ROS arguments: {(cause.group(1) if cause else text).strip()}")


def init_ros(argv: Sequence[str], own_signals: bool = False) -> None:
    """``rclpy.init`` that turns unreadable ROS arguments (a bad params file) into a :class:`StartupError`.

    Args:
        own_signals: leave SIGINT and SIGTERM to the node (both raise KeyboardInterrupt in the main
            thread) instead of rclpy's handlers, which shut the ROS context down at once: a server
            that must still answer its clients on the way out needs the context alive.
    """
    import rclpy
    from rclpy._rclpy_pybind11 import RCLError
    from rclpy.signals import SignalHandlerOptions

    options = SignalHandlerOptions.ALL
    if own_signals:
        options = SignalHandlerOptions.NO
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGTERM, signal.default_int_handler)
    yield_to_physics()  # with SIM_SCHEDULING=batch: this process's threads, and Fast DDS's to come, behind /sim's stepping
    try:
        rclpy.init(args=with_namespaced_clock(argv), signal_handler_options=options)
    except RCLError as error:
        raise params_file_error(error) from None


def with_namespaced_clock(argv: Sequence[str]) -> list[str]:
    """``argv`` with ``-r /clock:=<ns>/clock`` added when it puts the node in a namespace ``<ns>`` (``__ns:=``)
    and does not remap /clock itself: rclpy's time source reads the absolute ``/clock``, while a namespaced
    bring-up's /sim publishes its own clock under the namespace."""
    args = list(argv)
    if "--ros-args" not in args:
        return args
    namespace = next((a.split(":=", 1)[1] for a in args if a.startswith("__ns:=")), "")
    if not namespace.strip("/") or any(a.startswith("/clock:=") for a in args):
        return args
    start = args.index("--ros-args") + 1
    return [*args[:start], "-r", f"/clock:=/{namespace.strip('/')}/clock", *args[start:]]


class StopRequest:
    """SIGINT/SIGTERM as a flag the spin loop reads: no exception is raised into running code.

    rclpy's own handlers shut the ROS context down from the signal (a wait set being built then
    raised: exit 1) and chain to Python's, whose KeyboardInterrupt lands anywhere, once inside the
    clean-up (exit -2). A KeyboardInterrupt can also land inside rclpy's executor while it holds a
    lock. Install it once the robot is known, before the node is built; the spin loop reads the flag
    between short waits, and a second signal during the clean-up only sets it again.
    """

    def __init__(self) -> None:
        self.requested = False

    @classmethod
    def install(cls) -> StopRequest:
        request = cls()
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, request._on_signal)
        return request

    def _on_signal(self, signum: int, frame: Any) -> None:
        self.requested = True  # a plain store: safe wherever the main thread was interrupted


def end_process(code: int) -> NoReturn:
    """End a node's process once it has cleaned up (goals ended, node destroyed, ROS shut down).

    Python's finalization is skipped: it joins the worker threads rclpy's executor leaves behind, and
    one still inside a callback when the node was destroyed held a stopped node up until it was killed
    (and at exit Python resets the Ctrl-C handler to the default, so a second Ctrl-C then ended it -2).
    Nothing is left to do but flush the output.
    """
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


CLEANUP_LIMIT_S = 20.0  # [s] wall time a node's clean-up after Ctrl-C may take before the process is ended


@contextlib.contextmanager
def bounded_cleanup(limit_s: float = CLEANUP_LIMIT_S) -> Iterator[None]:
    """A clean-up that hangs prints every thread's stack to stderr and ends the process (exit code 1)."""
    faulthandler.dump_traceback_later(limit_s, exit=True)
    try:
        yield
    finally:
        faulthandler.cancel_dump_traceback_later()


def fail(program: str, error: StartupError) -> int:
    """Print the one line and return the exit code."""
    sys.stderr.write(f"{program}: {error}\n")
    return EXIT_BAD_START


def program_name(argv: Sequence[str]) -> str:
    return (argv[0].rsplit("/", 1)[-1] if argv else "") or "node"

