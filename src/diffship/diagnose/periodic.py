r"""A periodic residual that the steering does not explain: a wave-like disturbance? (where, not which)

Waves (or a periodic current, a pitching tow line) push a ship at their encounter period; a
model without them leaves a periodic residual at that period. For each fitted channel the
periodograms of the held-out residuals (each run detrended, Hann-windowed, normalised to unit
sum, averaged over runs) are tested with **Fisher's g** (Fisher 1929): with
:math:`g = \max_k P_k / \sum_k P_k` over the :math:`n` Fourier frequencies, the probability of a
larger g from noise alone is :math:`p \approx n (1 - g)^{n - 1}`. A peak counts when
:math:`p < 10^{-3}`, its period lies between 2 s and a third of the shortest run (so several
cycles are in every run), and the steering input of no run has a clear line there (at most ten
times its average share of power within a bin: a residual at a zigzag's period or its harmonics
is the model's response to the rudder, not a disturbance; runs are checked one by one, since
zigzags of different periods put their harmonics in different bins and a mean over runs would
dilute each run's line below the threshold). Fisher's test assumes white
residuals; structural residuals are coloured, so the p-value is a screening number, not a
calibrated one.

This is a *where* finding: the period is reported with the channels that show it. It is also
the start of the ``wave`` effect's period (:mod:`diffship.models.effects.wave`):
:func:`training_period` runs the same test on the base fit's **training** residuals (before the
screen, so the candidate exists with a start) and refines the Fourier-bin period by a least-squares
scan (:func:`refine_period`): the period whose cosine/sine pair, fitted per run and channel,
explains the most residual power. The Fourier bin is :math:`1/t_{run}` wide in frequency, so its
period can be off by :math:`T^2/(2 t_{run})` — on 40-s runs at 6 s, 0.45 s, which is 40 % of a
cycle of phase drift over the run, outside a local fit's reach; the scan's resolution is a
twentieth of a bin.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..metrics import evaluate
from ..models.effects import steering_inputs

__all__ = ["periodic_residual", "refine_period", "training_period"]


def _periodogram(x: np.ndarray) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    k = np.arange(x.size)
    x = x - np.polyval(np.polyfit(k, x, 1), k) if x.size > 2 else x - x.mean()
    p = np.abs(np.fft.rfft(x * np.hanning(x.size))) ** 2
    p = p[1:]  # no mean
    s = float(p.sum())
    return p / s if s > 0 else p


def periodic_residual(runs: Sequence, residuals: dict, steer: dict | None, channels: Sequence[str],
                      p_max: float = 1e-3, min_period: float = 2.0, cycles: float = 3.0) -> dict | None:
    """The most significant periodic residual not driven by the steering input, or None.

    ``residuals``: run name → channel → residual array; ``steer``: run name → steering input (``None``: a line
    in the steering too is kept — under an autopilot the rudder answers a sea state at its period); ``cycles``: the
    fewest periods in the shortest run.
    Returns ``{"period_s", "p_value", "channels"}``."""
    if not runs:
        return None
    n = min(r.n for r in runs)
    if n < 64:
        return None
    dt = float(np.median(np.diff(np.asarray(runs[0].time))))
    f = np.fft.rfftfreq(n, dt)[1:]
    band = (f > 0) & (1.0 / np.maximum(f, 1e-300) >= min_period) & (1.0 / np.maximum(f, 1e-300) <= n * dt / cycles)
    if not np.any(band):
        return None
    P_ins = [_periodogram(np.asarray(steer[r.name])[:n]) for r in runs] if steer else []
    best = None
    hits = []
    for c in channels:
        P = np.mean([_periodogram(np.asarray(residuals[r.name][c])[:n]) for r in runs], axis=0)
        Pb = np.where(band, P, 0.0)
        k = int(np.argmax(Pb))
        g = float(Pb[k] / max(P.sum(), 1e-300))
        m = P.size
        p = float(min(1.0, m * (1.0 - g) ** (m - 1)))
        # a line of any run's input: the residual periodogram is a mean over runs, and zigzags of different periods
        # put their harmonics in different bins, so one run's response to its own rudder is matched with that run
        driven = any(P_in[max(k - 1, 0):k + 2].max() > 10.0 / P_in.size for P_in in P_ins)
        if p < p_max and not driven:
            hits.append((c, float(1.0 / f[k]), p))
    if not hits:
        return None
    c0, period, p = min(hits, key=lambda h: h[2])
    near = [c for c, T, _ in hits if abs(T - period) <= 0.1 * period]
    best = {"period_s": period, "p_value": p, "channels": near}
    return best


def refine_period(runs: Sequence, residuals: dict, channels: Sequence[str], period: float,
                  scales: dict | None = None, span_bins: float = 1.5, n_grid: int = 61) -> float:
    r"""The period near ``period`` [s] whose harmonic explains the most residual power.

    For each trial frequency :math:`f` within ``span_bins`` Fourier bins (:math:`1/t_{run}`) of
    :math:`1/T`, regress every run's (mean-removed) residual of every channel on
    :math:`(\cos 2\pi f t, \sin 2\pi f t)` and add the explained sums of squares, channels
    normalised by ``scales`` (per-run amplitudes: the scan does not assume one phase for all runs);
    the best frequency of a grid of ``n_grid`` is returned as a period."""
    if not runs:
        return float(period)
    t_run = min(float(np.asarray(r.time)[-1] - np.asarray(r.time)[0]) for r in runs)
    f0 = 1.0 / period
    df = span_bins / max(t_run, 1e-9)
    fs = np.linspace(max(f0 - df, 0.5 * f0), f0 + df, n_grid)
    score = np.zeros(fs.size)
    for r in runs:
        t = np.asarray(r.time, dtype=float) - float(np.asarray(r.time)[0])
        for c in channels:
            e = np.asarray(residuals[r.name][c], dtype=float)
            e = (e - e.mean()) / ((scales or {}).get(c, 1.0) or 1.0)
            for k, f in enumerate(fs):
                A = np.stack([np.cos(2 * np.pi * f * t), np.sin(2 * np.pi * f * t)], axis=1)
                coef, *_ = np.linalg.lstsq(A, e, rcond=None)
                score[k] += float(np.sum((A @ coef) ** 2))
    return float(1.0 / fs[int(np.argmax(score))])


def training_period(model, runs: Sequence, initial_states: Sequence, channels: Sequence[str],
                    integrator=None, scales: dict | None = None, p_max: float = 1e-3, ev=None) -> dict | None:
    """The periodic residual of ``model`` (a base fit) on its training ``runs`` from the fit's
    ``initial_states`` (``ev``: that simulation's :class:`~diffship.metrics.Evaluation`, when the caller has it),
    with its period refined (:func:`refine_period`), or None.

    Returns :func:`periodic_residual`'s dict plus ``"period_bin_s"`` (the Fourier-bin period)."""
    if ev is None:
        kw = {} if integrator is None else {"integrator": integrator}
        x0 = list(initial_states) if len(initial_states) == len(runs) else None
        ev = evaluate(model, runs, x0, channels=channels, **kw)
    if not ev.ok:
        return None
    res = ev.errors(runs, [c for c in channels if c in ev.rmse], model.angle_outputs)
    chans = list(res[runs[0].name]) if runs else []
    i = steering_inputs(model)[-1]  # the steering input (rudder, nozzle, or yaw moment), as :mod:`.where`
    steer = {r.name: np.asarray(r[model.input_names[i]], dtype=float) for r in runs}
    found = periodic_residual(runs, res, steer, chans, p_max=p_max)
    if found is None:
        return None
    T = refine_period(runs, res, found["channels"], found["period_s"], scales)
    return {**found, "period_bin_s": found["period_s"], "period_s": T}
