"""Exceptions of the simulation core. Nodes turn them into refusals and error codes."""

from __future__ import annotations


class SimError(Exception):
    """Base class of every error raised by the simulation core."""


class UnknownNameError(SimError, KeyError):
    """A joint, body, site, keyframe or object name that the model does not have.

    The message lists the names that exist.
    """

    def __str__(self) -> str:  # KeyError quotes its message; show it plainly
        return str(self.args[0]) if self.args else ""


class InvalidGoalError(SimError, ValueError):
    """A goal or command that can never be executed (NaN, out of range, wrong frame)."""


class UnreachableError(SimError):
    """Inverse kinematics found no configuration that reaches the target."""


class SimulationFaultError(SimError):
    """The physics diverged (NaN or instability warning); the state must be reset."""
