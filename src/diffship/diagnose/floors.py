r"""Physical noise floors: what a positioning system can deliver.

The statistical floors of :mod:`.where` measure the scatter of a signal about a smooth curve;
for a tracked position (smooth by construction) that is the tracker's filter, not its accuracy.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from ..data import Run
from .where import PHYSICAL, NoiseEstimate

__all__ = ["distance_sailed", "physical_position_floor"]


def distance_sailed(run: Run) -> np.ndarray:
    """Distance sailed since the first sample [m]: ∫ U dt with U from the logged u, v, or from
    the position track differenced over 1 s where the velocities are not logged."""
    t = np.asarray(run.time, dtype=float)
    if run.has("u"):
        U = np.hypot(np.asarray(run["u"], float), np.asarray(run["v"], float) if run.has("v") else 0.0)
        return np.concatenate([[0.0], np.cumsum(0.5 * (U[1:] + U[:-1]) * np.diff(t))])
    if run.has("x0", "y0"):
        dt = float(np.median(np.diff(t)))
        k = max(1, int(round(1.0 / dt)))
        x, y = np.asarray(run["x0"], float), np.asarray(run["y0"], float)
        idx = np.arange(0, t.size, k)
        seg = np.hypot(np.diff(x[idx]), np.diff(y[idx]))
        return np.interp(t, t[idx], np.concatenate([[0.0], np.cumsum(seg)]))
    return np.zeros_like(t)


def physical_position_floor(est: dict[str, NoiseEstimate], runs: Sequence[Run], accuracy: float | None = None,
                            drift: float = 1e-3) -> dict[str, NoiseEstimate]:
    r"""Position floors a positioning system can deliver, not the scatter of a smooth track.

    A tracked position is smooth: its second differences measure the tracker's filter, not its
    accuracy (0.15 mm on the HSVA KVLCC2 logs, where heading was within 0.5°), and position
    errors then swamp every other channel of E. The floor of ``x0``, ``y0`` is

    .. math::
        \sigma_{pos} = \max(\hat\sigma_{stat},\ a,\ \kappa\,\mathrm{RMS}_k\, s_k)

    with *a* the positioning system's accuracy (``accuracy`` [m], when known: millimetres for
    optical tracking in a basin, about 0.02 m for RTK GNSS, metres for plain GNSS) and the
    **drift per distance** κ (``drift``, default 0.1 % of the distance sailed, the order of the
    scale and calibration errors of tracking and dead reckoning over a run): a track whose scale is
    off by κ is off by κ s(t) after a distance s(t), RMS κ·RMS(s) over the scored samples
    (:func:`distance_sailed` of ``runs``, the held-out runs). The estimate that sets the floor
    is named in ``method``."""
    out = dict(est)
    if not any(c in est for c in ("x0", "y0")):
        return out
    s = np.concatenate([distance_sailed(r) for r in runs]) if runs else np.zeros(1)
    by_drift = drift * float(np.sqrt(np.mean(s ** 2)))
    acc = float(accuracy) if accuracy else 0.0
    for c in ("x0", "y0"):
        e = est.get(c)
        if e is None:
            continue
        phys = max(acc, by_drift)
        if phys > e.sigma:
            how = (f"{PHYSICAL}: positioning accuracy {acc:g} m" if acc >= by_drift else
                   f"{PHYSICAL}: drift {100 * drift:g} % of the distance sailed (RMS {by_drift / drift:.3g} m)")
            out[c] = dataclasses.replace(e, sigma=float(phys), method=how,
                                         note=f"statistical estimate {e.sigma:.3g} m (a smooth track's scatter) is below it")
    return out


