r"""Channel weights of the simulation-error residual and the scales of its nuisance unknowns.

* :func:`channel_spread` — the first pass's normalisation ``s_c``: each channel's spread;
* :func:`channel_rms` — residual RMS per channel (the noise pass's ``s_c = σ_c``, the maximum-likelihood
  weighting for white Gaussian channel noise);
* :func:`correlation_time` — integrated autocorrelation time per channel (effective sample size ``N/τ``);
* :func:`x0_scales` — the scale of each estimated initial-state offset.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..models import AbstractModel
from .problem import Batch

__all__ = ["channel_spread", "channel_rms", "correlation_time", "x0_scales"]


def channel_spread(batch: Batch) -> np.ndarray:
    """Default channel scales: standard deviation of each channel over all runs (floored)."""
    out = []
    for j in range(len(batch.channels)):
        v = batch.ys[..., j][batch.mask]
        out.append(max(float(np.std(v)), 1e-3 * float(np.max(np.abs(v)) + 1e-12), 1e-9))
    return np.asarray(out)


def channel_rms(r: np.ndarray, mask: np.ndarray, scales: np.ndarray) -> np.ndarray:
    """Per-channel RMS (model units) of normalised residuals ``r`` over the unmasked samples."""
    e = np.asarray(r).reshape(mask.shape + (len(scales),))
    return np.asarray([max(float(np.sqrt(np.mean((e[..., j][mask] * s) ** 2))), 1e-12)
                       for j, s in enumerate(scales)])


def correlation_time(r: np.ndarray, mask: np.ndarray, n_channels: int, max_lag: int = 400) -> np.ndarray:
    r"""Integrated autocorrelation time (in samples) of each channel's residuals, pooled over runs.

    :math:`\tau_c = 1 + 2\sum_{k\ge1}\rho_c(k)`, summed up to the first lag where the pooled
    autocorrelation falls below zero (the initial positive sequence), at most ``max_lag`` or a
    quarter of the shortest run. ``N/τ`` is the effective number of independent samples: white
    residuals give τ ≈ 1; residuals dominated by a slowly varying model error give τ ≫ 1.
    """
    e = np.asarray(r).reshape(mask.shape + (n_channels,))
    n_min = int(np.min(np.sum(mask, axis=1)))
    K = max(1, min(max_lag, n_min // 4))
    out = []
    for c in range(n_channels):
        num = np.zeros(K + 1)
        den = 0.0
        for i in range(e.shape[0]):
            x = e[i, mask[i], c]
            x = x - x.mean()
            den += float(x @ x)
            for k in range(1, K + 1):
                num[k] += float(x[:-k] @ x[k:])
        rho = num[1:] / den if den > 0 else np.zeros(K)
        neg = np.flatnonzero(rho < 0)
        rho = rho[: neg[0]] if neg.size else rho
        out.append(max(1.0, 1.0 + 2.0 * float(np.sum(rho))))
    return np.asarray(out)


def x0_scales(model: AbstractModel, batch: Batch, states: Sequence[str]) -> np.ndarray:
    """Scale of each estimated initial-state offset: the spread of the channel it shows up in."""
    spread = channel_spread(batch)
    state_channel = getattr(model, "STATE_CHANNEL", {})

    def one(state):
        c = state if state in batch.channels else state_channel.get(state)
        return spread[batch.channels.index(c)] if c in batch.channels else 1.0

    return np.asarray([one(s) for s in states], dtype=np.float64)
