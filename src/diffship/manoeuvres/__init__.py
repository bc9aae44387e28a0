"""Standard manoeuvres and the IMO metrics.

:mod:`~diffship.manoeuvres.drive` simulates a model through a zigzag, turning circle, pull-out or
spiral with a rate-limited steering gear in the loop; :mod:`~diffship.manoeuvres.imo` computes
the IMO metrics (overshoots, advance, tactical diameter, ...) identically on simulated and
measured runs.
"""

from .drive import (
    ScheduleLaw as ScheduleLaw,
    SpiralResult as SpiralResult,
    ZigzagLaw as ZigzagLaw,
    closed_loop as closed_loop,
    pull_out as pull_out,
    spiral as spiral,
    turning_circle as turning_circle,
    zigzag as zigzag,
)
from .imo import (
    TurningMetrics as TurningMetrics,
    check_turn_direction as check_turn_direction,
    rudder_release as rudder_release,
    side_name as side_name,
    side_sign as side_sign,
    ZigzagMetrics as ZigzagMetrics,
    first_execute as first_execute,
    imo_metrics as imo_metrics,
    pullout_metrics as pullout_metrics,
    turning_metrics as turning_metrics,
    zigzag_metrics as zigzag_metrics,
)

__all__ = [
    "ZigzagLaw", "ScheduleLaw", "closed_loop", "zigzag", "turning_circle", "pull_out", "spiral",
    "ZigzagMetrics", "TurningMetrics", "SpiralResult", "zigzag_metrics", "turning_metrics",
    "pullout_metrics", "imo_metrics", "first_execute",
    "check_turn_direction", "rudder_release", "side_name", "side_sign",
]
