r"""A periodic residual that the steering does not explain: a wave-like disturbance? (where, not which)

Waves (or a periodic current, a pitching tow line) push a ship at their encounter period; a
model without them leaves a periodic residual at that period. For each fitted channel the
periodograms of the held-out residuals (each run detrended, Hann-windowed, normalised to unit
sum, averaged over runs) are tested with **Fisher's g** (Fisher 1929): with
:math:`g = \max_k P_k / \sum_k P_k` over the :math:`n` Fourier frequencies, the probability of a
larger g from noise alone is :math:`p \approx n (1 - g)^{n - 1}`. A peak counts when
:math:`p < 10^{-3}`, its period lies between 2 s and a third of the shortest run (so several
cycles are in every run), and the steering input has no clear line there (at most ten times
its average share of power within a bin: a residual at the zigzag period or its low harmonics
is the model's response to the rudder, not a disturbance). Fisher's test assumes white
residuals; structural residuals are coloured, so the p-value is a screening number, not a
calibrated one.

This is a *where* finding: the period is reported with the channels that show it, as a hint
(the library has no wave family with a period parameter; with random wave phases per run one
would need per-run phase states).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["periodic_residual"]


def _periodogram(x: np.ndarray) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    k = np.arange(x.size)
    x = x - np.polyval(np.polyfit(k, x, 1), k) if x.size > 2 else x - x.mean()
    p = np.abs(np.fft.rfft(x * np.hanning(x.size))) ** 2
    p = p[1:]  # no mean
    s = float(p.sum())
    return p / s if s > 0 else p


def periodic_residual(runs: Sequence, residuals: dict, steer: dict, channels: Sequence[str],
                      p_max: float = 1e-3, min_period: float = 2.0) -> dict | None:
    """The most significant periodic residual not driven by the steering input, or None.

    ``residuals``: run name → channel → residual array; ``steer``: run name → steering input.
    Returns ``{"period_s", "p_value", "channels"}``."""
    if not runs:
        return None
    n = min(r.n for r in runs)
    if n < 64:
        return None
    dt = float(np.median(np.diff(np.asarray(runs[0].time))))
    f = np.fft.rfftfreq(n, dt)[1:]
    band = (f > 0) & (1.0 / np.maximum(f, 1e-300) >= min_period) & (1.0 / np.maximum(f, 1e-300) <= n * dt / 3.0)
    if not np.any(band):
        return None
    P_in = np.mean([_periodogram(np.asarray(steer[r.name])[:n]) for r in runs], axis=0)
    best = None
    hits = []
    for c in channels:
        P = np.mean([_periodogram(np.asarray(residuals[r.name][c])[:n]) for r in runs], axis=0)
        Pb = np.where(band, P, 0.0)
        k = int(np.argmax(Pb))
        g = float(Pb[k] / max(P.sum(), 1e-300))
        m = P.size
        p = float(min(1.0, m * (1.0 - g) ** (m - 1)))
        driven = P_in[max(k - 1, 0):k + 2].max() > 10.0 / P_in.size  # a clear line of the input spectrum
        if p < p_max and not driven:
            hits.append((c, float(1.0 / f[k]), p))
    if not hits:
        return None
    c0, period, p = min(hits, key=lambda h: h[2])
    near = [c for c, T, _ in hits if abs(T - period) <= 0.1 * period]
    best = {"period_s": period, "p_value": p, "channels": near}
    return best
