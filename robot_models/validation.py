"""Range checks for the typed configuration dataclasses (one helper instead of a check written out in each).

The lowest layer: ``robot_models`` and ``sim_bridge`` both use it in ``__post_init__``, so an invalid
value fails where the value is made, with a message that says what is allowed.
"""

from __future__ import annotations

import math
import numbers


def is_number(value: object) -> bool:
    """True for a finite real number: int, float or a NumPy scalar of either (bool is not a number here)."""
    return _finite_float(value) is not None


def _finite_float(value: object) -> float | None:
    """``value`` as a float if it is a finite real number (not a bool), else None."""
    if not isinstance(value, numbers.Real) or isinstance(value, bool):
        return None
    try:
        number = float(value)
    except OverflowError:  # an int too large for a float
        return None
    return number if math.isfinite(number) else None


def check_range(what: str, value: object, low: float | None = None, high: float | None = None, *,
                low_open: bool = False, high_open: bool = False, unit: str = "",
                error: type[Exception] = ValueError) -> None:
    """Raise ``error`` unless ``value`` is a finite number within the bounds.

    Args:
        what: the value's name as the user knows it (e.g. ``"IMU gyro_noise"``).
        value: the value to check.
        low, high: the bounds (``None`` = unbounded on that side).
        low_open, high_open: exclude the bound itself.
        unit: appended to the allowed range in the message (e.g. ``"m/s"``).
        error: the exception type to raise (``ValueError``, or a core error such as ``InvalidGoalError``).
    """
    number = _finite_float(value)
    inside = number is not None
    if number is not None and low is not None:
        inside = number > low if low_open else number >= low
    if inside and number is not None and high is not None:
        inside = number < high if high_open else number <= high
    if not inside:
        raise error(f"{what} must be {describe_range(low, high, low_open=low_open, high_open=high_open, unit=unit)}, "
                    f"got {value!r}")


def describe_range(low: float | None, high: float | None, *, low_open: bool = False, high_open: bool = False,
                   unit: str = "") -> str:
    """``"a finite number in [0, 1] m"``, ``"a finite number > 0"`` and the like."""
    suffix = f" {unit}" if unit else ""
    if low is not None and high is not None:
        return f"a finite number in {'(' if low_open else '['}{low}, {high}{')' if high_open else ']'}{suffix}"
    if low is not None:
        return f"a finite number {'>' if low_open else '>='} {low}{suffix}"
    if high is not None:
        return f"a finite number {'<' if high_open else '<='} {high}{suffix}"
    return "a finite number"
