"""The zigzag autopilot of a record: how late it reversed the rudder after the heading reached the switch
angle. ``python -m diffship.fit`` writes it per training zigzag into the fit file; a prediction, and a
held-out zigzag flown again, use it (:mod:`diffship.predict.core`, :mod:`diffship.predict.cross`).
"""

from __future__ import annotations

import numpy as np

from ..data import Run
from ..manoeuvres import first_execute

__all__ = ["switch_delay"]


def _crossing(t: np.ndarray, y: np.ndarray, level: float, k: int) -> float:
    """Time at which ``y`` (increasing through ``level`` at sample ``k``) crosses it, linearly interpolated."""
    if k == 0 or y[k] == y[k - 1]:
        return float(t[k])
    return float(t[k - 1] + (level - y[k - 1]) * (t[k] - t[k - 1]) / (y[k] - y[k - 1]))


def switch_delay(run: Run, switch_deg: float | None) -> float:
    """Median delay [s] between the heading change (from the first execute) reaching ±switch angle and the
    rudder order of the reversal, in a zigzag (0 where none is found): how late the helmsman or autopilot
    of the record answered, which the predicted zigzag then reproduces. Both times are interpolated
    between samples (the delays, 0.2–0.3 s in the HSVA tests, are shorter than a resampled step); the
    order time is the reversal's ramp (its 10 % and 50 % crossings) extrapolated back to the plateau,
    as :func:`diffship.manoeuvres.first_execute` does for the first order."""
    sw = float(switch_deg or 0.0)
    if not run.has("psi") or sw <= 0:
        return 0.0
    i0, side = first_execute(run)
    t = np.asarray(run.time, dtype=np.float64)
    psi = np.unwrap(np.asarray(run["psi"], dtype=np.float64))
    h = np.degrees(psi - psi[i0])
    d = np.degrees(np.asarray(run["delta"], dtype=np.float64))
    delays, sign, k = [], side, i0
    for _ in range(8):
        cross = np.nonzero(sign * h[k:] >= sw)[0]
        if not cross.size:
            break
        kc = k + int(cross[0])
        tc = _crossing(t, sign * h, sw, kc)
        a = float(d[kc])  # the plateau the rudder leaves
        amp = 2.0 * abs(a)
        if amp < 1.0:
            break
        drop = sign * (a - d)  # grows from 0 to ≈ 2|δ| over the reversal
        j10 = np.nonzero(drop[kc:] >= 0.1 * amp)[0]
        j50 = np.nonzero(drop[kc:] >= 0.5 * amp)[0]
        if not (j10.size and j50.size):
            break
        k10, k50 = kc + int(j10[0]), kc + int(j50[0])
        t10, t50 = _crossing(t, drop, 0.1 * amp, k10), _crossing(t, drop, 0.5 * amp, k50)
        t_order = t10 - 0.25 * (t50 - t10)
        delays.append(max(0.0, t_order - tc))
        sign, k = -sign, k50
    return float(np.median(delays)) if delays else 0.0
