r"""Channel weights of the simulation-error residual and the scales of its nuisance unknowns.

* :func:`channel_spread` — the first pass's normalisation ``s_c``: each channel's spread;
* :func:`channel_rms` — residual RMS per channel (the noise pass's ``s_c = σ_c``, the maximum-likelihood
  weighting for white Gaussian channel noise);
* :func:`correlation_time` — integrated autocorrelation time per channel (effective sample size ``N/τ``);
* :func:`concentrated_cost` and :func:`self_consistent_scales` — the likelihood of the fit with every
  channel's noise level unknown, and the channel scales at which the weighted least-squares optimum is
  its optimum;
* :func:`x0_scales` — the scale of each estimated initial-state offset.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..initial import correlation_time_of, state_scales
from ..models import AbstractModel
from .problem import Batch

__all__ = ["channel_spread", "channel_rms", "concentrated_cost", "correlation_time", "self_consistent_scales",
           "x0_scales"]


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
    return np.asarray([correlation_time_of([e[i, mask[i], c] for i in range(e.shape[0])], max_lag)
                       for c in range(n_channels)])


def x0_scales(model: AbstractModel, batch: Batch, states: Sequence[str]) -> np.ndarray:
    """Scale of each estimated initial-state offset (:func:`diffship.initial.state_scales`): the spread of the
    channel it shows up in."""
    return state_scales(model, batch.channels, channel_spread(batch), states)

def _sse(r: np.ndarray, mask: np.ndarray, scales: np.ndarray) -> tuple[np.ndarray, int]:
    """Per-channel sums of squared errors (model units) of normalised residuals ``r`` and the sample count."""
    e = np.asarray(r).reshape(np.shape(mask) + (len(scales),)) * np.asarray(scales)
    m = np.asarray(mask, dtype=bool)
    return np.asarray([float(np.sum(e[..., j][m] ** 2)) for j in range(len(scales))]), int(np.sum(m))


def concentrated_cost(r: np.ndarray, mask: np.ndarray, scales: np.ndarray, tau: np.ndarray,
                      prior_rows: np.ndarray | None = None) -> float:
    r"""The objective of an output-error fit whose channel noise levels are unknown (the likelihood
    with each channel's variance concentrated out), on effective samples:

    .. math::
        F = \sum_c \frac{N}{2\tau_c}\,\log\frac{\mathrm{SSE}_c}{N} + \tfrac12\lVert p\rVert^2

    with :math:`\mathrm{SSE}_c` the channel's sum of squared output errors over its ``N`` samples,
    :math:`\tau_c` its residuals' correlation time (:func:`correlation_time`; ``N/τ_c`` independent
    samples) and :math:`p` the prior rows (parameters, initial states). It does not depend on the scales
    the residuals were weighted with, so candidates solved under any weights are compared on one scale;
    its stationary points are the weighted least-squares optima at the scales
    :func:`self_consistent_scales` returns. The same data sampled faster give the same ``F`` (``N/τ_c``
    is a count of independent samples, not of samples).
    """
    sse, n = _sse(r, mask, scales)
    tau = np.asarray(tau, dtype=np.float64)
    p = 0.0 if prior_rows is None else 0.5 * float(np.sum(np.square(prior_rows)))
    return float(np.sum(n / (2.0 * tau) * np.log(np.maximum(sse, 1e-300) / max(n, 1)))) + p


def self_consistent_scales(r: np.ndarray, mask: np.ndarray, scales: np.ndarray, tau: np.ndarray,
                           floor: np.ndarray) -> np.ndarray:
    r"""The channel scales :math:`s_c = \sqrt{\tau_c\,\mathrm{SSE}_c/N}` at residuals ``r`` (weighted by
    ``scales``): the weighted least-squares optimum at these scales is a stationary point of
    :func:`concentrated_cost` once they stop changing (at least ``floor``: on noise-free data the
    residuals are round-off, which must not set the weights)."""
    sse, n = _sse(r, mask, scales)
    return np.maximum(np.sqrt(np.asarray(tau) * sse / max(n, 1)), floor)
