"""The warm-up of output error's first solve: rounds of Levenberg–Marquardt steps and one whole-run
solve per distinct point (:class:`~diffship.fit.output_error.OutputError`, ``warmup``).

Every start is first fitted on the first part of every run (growing horizon). Two rules keep the
starts' cost down without letting a start decide the result:

* **Dominated starts** (:func:`warm_rounds`): the warm-up runs in rounds; a start still running
  after a round at a cost above a start that has converged on the warm-up is stopped, and the starts
  report says so. Measured on the USV fit of ``benchmarks/timing``: three starts converged in 11–28
  steps, the fourth (the model's reference values) crawled 67 steps to the same point (cost 5.2 after
  30 steps against 4.29): stopped after 30, the same optimum.
* **Same points** (:func:`same_points`): starts the warm-up brought to one point share one whole-run
  solve; an initial angle a whole turn apart is the same point.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import jax
import numpy as np
import optimistix as optx

__all__ = ["warm_rounds", "same_points", "wrap_periodic"]


def warm_rounds(kernel, zs, data, lm: dict, total: int, say, label: str, cap: int | None = None):
    """The warm-up from every start in rounds of ``cap`` steps (default ``lm["max_steps"]``; a smaller
    ``cap`` is the data's traced step cap, :class:`~diffship.fit.kernel.KernelData`), one compiled program,
    up to ``total`` steps per start: after each round a start still running (its round ended on the
    cap; a stall stops before it and is not continued) goes on from where it is, unless its cost
    ½‖r‖² is above that of a start that has converged (dominated: stopped there). Returns
    ``([(z, result, steps, residuals), ...], dominated indices)`` in start order."""
    cap = int(lm["max_steps"] if cap is None else cap)
    out = [list(o) for o in kernel.solve_many(np.stack(zs), data, progress=say, label=label, **lm)]
    last = [int(o[2]) for o in out]  # steps of each start's last round
    dominated: set[int] = set()
    def code(res):
        return int(jax.tree_util.tree_leaves(res)[0])

    ok, capped = code(optx.RESULTS.successful), code(optx.RESULTS.nonlinear_max_steps_reached)

    def cost(o):
        r = np.asarray(o[3])
        return 0.5 * float(r @ r) if np.all(np.isfinite(r)) else math.inf

    while True:
        conv = [cost(o) for o in out if code(o[1]) == ok]
        best = min(conv) if conv else math.inf
        # unfinished: the last round ended on its cap (a stall stops before it, and is not continued)
        running = [i for i, o in enumerate(out) if i not in dominated and code(o[1]) == capped
                   and last[i] == cap and int(o[2]) < total and math.isfinite(cost(o))]
        newly = {i for i in running if cost(out[i]) > best * (1 + 1e-6) + 1e-12}
        dominated |= newly
        going = [i for i in running if i not in newly]
        if not going:
            break
        more = kernel.solve_many(np.stack([np.asarray(out[i][0]) for i in going]), data, progress=say,
                                 label=label, **lm)
        for i, o in zip(going, more):
            out[i], last[i] = [o[0], o[1], int(out[i][2]) + int(o[2]), o[3]], int(o[2])
    return out, sorted(dominated)


def wrap_periodic(x: np.ndarray, period: np.ndarray) -> np.ndarray:
    """``x`` taken to (−period/2, period/2] where ``period > 0`` (an initial angle in its scaled
    units), unchanged where it is 0."""
    per = np.asarray(period, dtype=np.float64)
    return np.where(per > 0, x - per * np.round(x / np.where(per > 0, per, 1.0)), x)


def same_points(zs: Sequence[np.ndarray], costs: Sequence[float], rtol: float = 1e-4, ztol: float = 1e-4,
                period: np.ndarray | None = None) -> list[int]:
    """For each start, the index of the first start at the same point: every unknown equal to
    ``ztol`` in the scaled fit space (parameters' scales and initial-state scales: 10⁻⁴ of a scale
    is far inside a standard error) and whole-run costs equal to ``rtol`` (relative: a long
    simulation amplifies the last digits — four warm-ups of a USV fit 3·10⁻⁶ apart in ``z`` differed
    by 2·10⁻⁶ of the cost). ``period``: per unknown, a period (> 0) over which two values are the
    same point (an initial angle: 2π in its scaled units, :meth:`OutputError.angle_periods`); the
    difference is taken modulo it. Non-finite costs are never merged."""
    def gap(a, b):
        d = np.asarray(a) - np.asarray(b)
        return np.abs(d if period is None else wrap_periodic(d, period))

    rep = []
    for i, (z, c) in enumerate(zip(zs, costs)):
        j = next((j for j in range(i) if rep[j] == j and math.isfinite(c) and math.isfinite(costs[j])
                  and abs(c - costs[j]) <= rtol * max(abs(c), abs(costs[j]))
                  and np.all(gap(z, zs[j]) <= ztol)), i)
        rep.append(j)
    return rep
