r"""A held input on a new time grid: the means of a zero-order-hold signal over the grid's intervals.

A digital command set at each sample and held (``--input-hold zero``; :mod:`diffship.integrators`) is the
piecewise-constant signal :math:`u(\tau) = u_i` on :math:`[t_i, t_{i+1})`. On another grid :math:`T_j`, which the
simulation again holds over :math:`[T_j, T_{j+1})`, the value that carries the same impulse is that signal's mean
over the interval,

.. math:: \bar u_j = \frac{F(T_{j+1}) - F(T_j)}{T_{j+1} - T_j},\qquad F(\tau) = \int_{t_0}^{\tau} u,

and neither a sample of it (interpolation) nor the mean of the samples around :math:`T_j` (a block's mean, which
held from :math:`T_j` reaches the model :math:`(k-1)/2` samples late). NumPy only: the data layer's
``Run.resample`` and the fit's block averages (:mod:`diffship.fit.conditioning`) use it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["held_means"]


def held_means(t: np.ndarray, u: np.ndarray, grid: np.ndarray, t_end: float) -> np.ndarray:
    """Means of the held signal ``u`` sampled at ``t`` (the last sample held to ``t_end``) over the intervals of
    ``grid`` (module docstring); the last interval as long as the one before it, clipped at ``t_end``."""
    t, u, grid = (np.asarray(a, dtype=np.float64) for a in (t, u, grid))
    edges = np.append(t, t_end)
    F = np.concatenate([[0.0], np.cumsum(u * np.diff(edges))])

    def integral(tau):
        i = np.clip(np.searchsorted(edges, tau, side="right") - 1, 0, len(u) - 1)
        return F[i] + u[i] * (np.minimum(tau, t_end) - edges[i])

    step = grid[-1] - grid[-2] if grid.size > 1 else t_end - grid[-1]
    ends = np.append(grid[1:], min(grid[-1] + step, t_end))
    width = ends - grid
    return np.where(width > 0, (integral(ends) - integral(grid)) / np.where(width > 0, width, 1.0),
                    u[np.clip(np.searchsorted(t, grid, side="right") - 1, 0, len(u) - 1)])
