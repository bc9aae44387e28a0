"""How the runs were steered, read from their records: the rudder's moves and rate (the zigzag
autopilot's switch delay: :func:`diffship.predict.autopilot.switch_delay`). A prediction flies its
manoeuvres with these (``python -m diffship.predict``
takes them from the fit file, :mod:`diffship.fitfile`), so that a trained manoeuvre flown again
reproduces what was measured.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from .data import Run

__all__ = ["measured_helm_rate", "rudder_moves"]


def rudder_moves(run: Run, min_deg: float = 2.0) -> list[tuple[float, float, float]]:
    r"""The rudder's moves in a run: ``(t_start, change [°], rate [°/s])`` each.

    A move is a stretch of samples where the rudder angle changes faster than
    :math:`\max(0.5°/s,\ 0.1\,P_{99}|\dot\delta|)` (gaps of one sample bridged) by at least
    ``min_deg`` and a quarter of the run's rudder range; its rate is :math:`0.8\,|\Delta\delta|`
    over the time between the 10 % and 90 % crossings (linear interpolation), which does not depend
    on the sample rate the way the largest sample-to-sample difference does."""
    if not run.has("delta") or run.n < 3:
        return []
    t = np.asarray(run.time, dtype=np.float64)
    d = np.degrees(np.asarray(run["delta"], dtype=np.float64))
    rate = np.abs(np.diff(d)) / np.diff(t)
    if not np.any(rate > 0):
        return []
    moving = rate > max(0.5, 0.1 * float(np.percentile(rate, 99)))
    idx = np.flatnonzero(moving)
    out = []
    if not idx.size:
        return out
    groups = np.split(idx, np.flatnonzero(np.diff(idx) > 2) + 1)
    span = float(np.ptp(d))
    for g in groups:
        a, b = int(g[0]), int(g[-1]) + 1
        change = d[b] - d[a]
        if abs(change) < max(min_deg, 0.25 * span):
            continue
        seg_t, seg_d = t[a:b + 1], (d[a:b + 1] - d[a]) / change  # 0 → 1 along the move
        mono = np.maximum.accumulate(seg_d)
        t10, t90 = np.interp(0.1, mono, seg_t), np.interp(0.9, mono, seg_t)
        dur = float(t90 - t10) if t90 > t10 else float(seg_t[-1] - seg_t[0])
        if dur > 0:
            out.append((float(t[a]), float(change), 0.8 * abs(change) / dur if t90 > t10 else abs(change) / dur))
    return out


def measured_helm_rate(runs: Sequence[Run]) -> dict[str, Any] | None:
    """The steering-gear rate the training runs show: the median rate of their rudder moves
    (:func:`rudder_moves`), ``{"deg_s", "moves", "source"}``; ``None`` without rudder moves."""
    rates = [m[2] for r in runs for m in rudder_moves(r)]
    if not rates:
        return None
    return {"deg_s": float(np.median(rates)), "moves": len(rates),
            "source": f"median rate of {len(rates)} rudder moves in the training runs (10–90 % of each move)"}
