r"""Ranking candidate structures by information criteria on **output** residuals.

Each candidate is refitted by output error and simulated over the training runs from the one
initial-state rule of the metrics (:func:`diffship.metrics.evaluate`). With ``e_c`` the simulation
residual of channel ``c`` (heading wrapped), ``N_c`` its samples and ``τ_c`` its integrated
autocorrelation time (:func:`diffship.fit.weights.correlation_time`), the Gaussian log-likelihood
counted over the *effective* samples :math:`N_c/\tau_c` gives

.. math::
    \mathrm{AIC} = \sum_c \frac{N_c}{\tau_c}\ln\frac{\mathrm{RSS}_c}{N_c} + 2k, \qquad
    \mathrm{BIC} = \sum_c \frac{N_c}{\tau_c}\ln\frac{\mathrm{RSS}_c}{N_c} + k\ln\sum_c \frac{N_c}{\tau_c},

``k`` the free parameters. Simulation residuals are strongly coloured (a model error drifts for
seconds), so counting every sample as independent would make any term that lowers the RSS a little
look significant. ``τ_c`` is taken once, from the candidate with the lowest residual (closest to
white), and used for every candidate so that their criteria are comparable (Burnham & Anderson,
*Model selection and multimodel inference*, 2nd ed., Springer 2002, §2.2, §6.4; Bayley & Hammersley,
J. R. Stat. Soc. B 8, 1946, for the effective sample size).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from ..data import Run
from ..fit.weights import correlation_time
from ..metrics import Evaluation
from ..stats import block_indices

__all__ = ["residuals", "effective_samples", "criteria", "selection_frequency"]


def residuals(model_outputs: Sequence[str], angles: Sequence[str], ev: Evaluation, runs: Sequence[Run],
              channels: Sequence[str]) -> dict[str, list[np.ndarray]]:
    """``{channel: [residual per run]}`` of a simulated evaluation (angles wrapped to (−π, π])."""
    out: dict[str, list[np.ndarray]] = {c: [] for c in channels}
    for run in runs:
        sim = ev.simulated[run.name]
        for c in channels:
            if not run.has(c):
                continue
            e = np.asarray(run[c]) - np.asarray(sim[c])
            if c in angles:
                e = (e + np.pi) % (2 * np.pi) - np.pi
            out[c].append(np.where(np.isfinite(e), e, 1e6))
    return out


def effective_samples(res: Mapping[str, list[np.ndarray]]) -> dict[str, float]:
    """``{channel: N_c/τ_c}`` of residuals per run (module docstring)."""
    out = {}
    for c, parts in res.items():
        if not parts:
            continue
        n_max = max(p.size for p in parts)
        e = np.zeros((len(parts), n_max, 1))
        mask = np.zeros((len(parts), n_max), dtype=bool)
        for i, p in enumerate(parts):
            e[i, :p.size, 0] = p
            mask[i, :p.size] = True
        tau = float(correlation_time(e.reshape(-1), mask, 1)[0])
        out[c] = max(sum(p.size for p in parts) / tau, 1.0)
    return out


def criteria(res: Mapping[str, list[np.ndarray]], n_eff: Mapping[str, float], k: int) -> dict[str, float]:
    """``{"aic", "bic", "loglik_eff", "n_eff"}`` of one candidate (module docstring)."""
    ll, n_tot = 0.0, 0.0
    for c, parts in res.items():
        if not parts or c not in n_eff:
            continue
        e = np.concatenate(parts)
        rss = float(e @ e)
        ll += n_eff[c] * math.log(max(rss / e.size, 1e-300))
        n_tot += n_eff[c]
    return {"aic": ll + 2 * k, "bic": ll + k * math.log(max(n_tot, 2.0)), "loglik_eff": -0.5 * ll, "n_eff": n_tot}


def selection_frequency(resids: Sequence[Mapping[str, list[np.ndarray]]], n_eff: Mapping[str, float],
                        ks: Sequence[int], n_terms: Sequence[int], criterion: str = "bic", *, n_boot: int = 200,
                        block: int = 50, seed: int = 0) -> np.ndarray:
    r"""How often each candidate wins the ranking over a paired moving-block bootstrap of the training
    samples: ``(n_candidates,)`` fractions summing to 1.

    Every resample draws blocks of ``block`` samples per run (the same rows for every candidate and
    channel: the comparison is paired) and recomputes each candidate's criterion
    (:func:`criteria`, the same effective sample sizes ``n_eff``) from its output residuals at those
    rows; the lowest wins (ties: fewer terms). A term's **inclusion probability** is the summed
    frequency of the candidates that contain it (Buckland, Burnham & Augustin, Biometrics 53, 1997,
    bootstrap selection frequencies). The candidates are not refitted per resample, so the spread
    is that of the comparison of the fitted structures; the in-sample optimism of a refit is what
    the criterion's penalty is for. ``resids[i]``: candidate ``i``'s ``{channel: [residual per run]}``
    (:func:`residuals`), all on the same runs.
    """
    n_c = len(resids)
    chans = [c for c in resids[0] if resids[0][c] and c in n_eff]
    sq = {c: [np.stack([np.asarray(r[c][j]) ** 2 for r in resids]) for j in range(len(resids[0][c]))] for c in chans}
    n_runs = max((len(v) for v in sq.values()), default=0)
    n_tot = sum(n_eff[c] for c in chans)
    pen = np.asarray(ks, dtype=float) * (math.log(max(n_tot, 2.0)) if criterion == "bic" else 2.0)
    tie = 1e-9 * np.asarray(n_terms, dtype=float)
    rng = np.random.default_rng(seed)
    wins = np.zeros(n_c)
    for _ in range(n_boot):
        drawn: dict[tuple[int, int], np.ndarray] = {}  # (run, length) -> rows: channels of a run share them

        def rows(j, n):
            if (j, n) not in drawn:
                drawn[(j, n)] = block_indices(n, 1, block, rng)[0]
            return drawn[(j, n)]

        crit = pen + tie
        for c in chans:
            parts = sq[c]
            key = (lambda j: j) if len(parts) == n_runs else (lambda j: (c, j))
            rss = sum(parts[j][:, rows(key(j), parts[j].shape[1])].sum(axis=1) for j in range(len(parts)))
            cnt = sum(parts[j].shape[1] for j in range(len(parts)))
            crit = crit + n_eff[c] * np.log(np.maximum(rss / cnt, 1e-300))
        wins[int(np.argmin(crit))] += 1
    return wins / max(n_boot, 1)
