"""What a camera's settings may be: the ranges ``/camera`` declares its parameters with and ``/sim`` checks.

``/camera`` sends the settings (sim_interfaces/CameraSettings) on ``/sim/<camera>/settings``; ``/sim``
renders with them. Both ends take the defaults and ranges from here.
"""

from __future__ import annotations

from sim_interfaces.msg import CameraSettings

NOMINAL_EXPOSURE_MS = 10.0  # the exposure at which an image shows the scene as lit (gain 1) [ms]
EXPOSURE_RANGE_MS = (0.1, 100.0)
RATE_RANGE_HZ = (0.5, 60.0)
WIDTH_RANGE_PX = (16, 1280)
HEIGHT_RANGE_PX = (16, 720)
DEFAULT_SETTINGS = (NOMINAL_EXPOSURE_MS, 10.0, 320, 240)  # exposure [ms], rate [Hz], width, height [px]


def settings_problem(msg: CameraSettings) -> str:
    """Why these settings cannot be used ('' when they can)."""
    checks = ((msg.exposure_ms, EXPOSURE_RANGE_MS, "exposure_ms"), (msg.rate_hz, RATE_RANGE_HZ, "rate_hz"),
              (msg.width, WIDTH_RANGE_PX, "width"), (msg.height, HEIGHT_RANGE_PX, "height"))
    for value, (low, high), name in checks:
        if not low <= value <= high:  # also refuses NaN
            return f"{name} {value} is outside [{low}, {high}]"
    return ""
