r"""The start rule of the held-out runs: every compared model starts from what the log knows.

A held-out simulation must start somewhere. Estimating its initial state freely (as MATLAB
``compare`` does) lets a structurally wrong model hide its error in the start: with an
unmodelled current the base model of a USV started 15–30 m away from the logged position,
6° off in heading and at u = −1.3 m/s where the log said 2.0 m/s, so that the drift only a
current explains was absorbed by the start, and the current — recovered to the third digit —
was rejected on the held-out runs (issue 28).

**Rule** (:class:`StartRule`, the same for the base and every candidate). Let
:math:`\hat x_{0}` be the logged state at the first sample (the low-pass filtered measurement,
as every fit's start, :func:`diffship.simulate.initial_state`) and :math:`\sigma_c` the noise
floor of the channel :math:`c` that logs state :math:`s`. The initial state of each run is

.. math::
    x_0 = \arg\min_{x}\ \sum_{k,c} \big(\hat y_c(t_k; x) - y_{kc}\big)^2/\sigma_c^2
    \quad\text{s.t.}\quad |x_s - \hat x_{0,s}| \le b\,\sigma_{c(s)}
    \ \text{for every logged state } s,

with the model held (b = ``bound`` noise floors, 3 by default): logged position, heading,
velocities and rate move only within their noise, so an offset of more than a few noise floors
cannot be bought by the start. States not logged themselves (filter states of a Nomoto model,
for example) are estimated without bound. With no structural error the unconstrained optimum
is already within :math:`\sigma/\sqrt{N}` of the logged value, so the bound is inactive and the
null scatter of E (the gap gate, :func:`~.where.structural_gate`) is unchanged.

The solver is a projected Levenberg–Marquardt over the per-run initial-state offsets only
(a few unknowns per run): at each step the bounds that are active with the gradient pointing
out are held, the damped Gauss–Newton step is taken in the others and projected on the box.
It uses the initial-state kernel's compiled residual and Jacobian (no new model compile).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from ..fit.kernel import PENALTY

__all__ = ["StartRule", "StartInfo", "bounded_offsets"]


@dataclasses.dataclass(frozen=True)
class StartRule:
    """How a held-out run's initial state is set (module docstring).

    Args:
        bound: logged states move at most this many noise floors from their logged value
            (``inf``: the former free estimate).
        max_steps: projected Levenberg–Marquardt steps.
    """

    bound: float = 3.0
    max_steps: int = 30

    def describe(self) -> str:
        return (f"held-out runs start at the logged state; logged states (position, heading, velocities, rate) "
                f"move at most {self.bound:g} noise floors to fit the run, unlogged states are estimated; "
                "the same rule for the base and every candidate")


@dataclasses.dataclass(frozen=True)
class StartInfo:
    """The start one model used on the held-out runs: per run and state, the offset from the
    logged value in noise floors (``offset_sigma``; NaN for unlogged states), and which bounds
    were active (the model wanted to start further away than the log allows)."""

    states: tuple[str, ...]
    offset_sigma: dict[str, dict[str, float]]
    at_bound: dict[str, tuple[str, ...]]

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


def bounded_offsets(res, jac, n_runs: int, lo: np.ndarray, hi: np.ndarray, max_steps: int = 30,
                    tol: float = 1e-10) -> np.ndarray:
    r"""Projected Levenberg–Marquardt: minimise ½‖res(d)‖² over the box lo ≤ d ≤ hi.

    ``res(d)`` and ``jac(d)`` give the residual vector and its Jacobian (NumPy arrays) at the
    flat offset vector ``d`` (``n_runs`` × per-run offsets); ``lo``/``hi`` per-run bounds,
    repeated over the runs. Returns the offsets (0 when the start itself blows up).
    """
    lo = np.tile(np.asarray(lo, float), n_runs)
    hi = np.tile(np.asarray(hi, float), n_runs)
    d = np.clip(np.zeros(lo.size), lo, hi)
    r = res(d)
    if not np.all(np.isfinite(r)) or np.any(np.abs(r) >= PENALTY):
        return d
    cost = 0.5 * float(r @ r)
    lam = 1e-3
    for _ in range(max_steps):
        J = jac(d)
        g = J.T @ r
        eps = 1e-12 * (1.0 + np.abs(d))
        held = ((d <= lo + eps) & (g > 0)) | ((d >= hi - eps) & (g < 0))
        free = ~held
        if not np.any(free):
            break
        Jf = J[:, free]
        A = Jf.T @ Jf
        dA = np.maximum(np.diag(A), 1e-12 * max(float(np.max(np.diag(A))), 1e-300))
        improved = False
        for _ in range(12):
            try:
                step = np.linalg.solve(A + lam * np.diag(dA), -g[free])
            except np.linalg.LinAlgError:
                lam *= 10.0
                continue
            d_new = d.copy()
            d_new[free] += step
            d_new = np.clip(d_new, lo, hi)
            r_new = res(d_new)
            c_new = 0.5 * float(r_new @ r_new) if np.all(np.isfinite(r_new)) and not np.any(np.abs(r_new) >= PENALTY) \
                else np.inf
            if c_new < cost:
                improved = True
                small = (cost - c_new) <= tol * cost
                d, r, cost = d_new, r_new, c_new
                lam = max(lam / 3.0, 1e-9)
                break
            lam *= 4.0
        if not improved or small:
            break
    return d


def logged_state_channels(model, x0_idx: Sequence[int], channels: Sequence[str]) -> list[str | None]:
    """For each estimated state, the channel that logs it directly (None: not logged itself)."""
    return [model.state_names[i] if model.state_names[i] in channels else None for i in x0_idx]


def held_out_starts(ws, data, values: dict[str, float], base_values: dict[str, float] | None,
                    floor: dict[str, float], rule: StartRule, run_names: Sequence[str]) -> tuple[list[np.ndarray], StartInfo]:
    """Initial states of the held-out runs in ``data`` (:meth:`~.screen.Workspace.data`) for the
    workspace model at effect values ``values`` and base values ``base_values``, by the rule
    (module docstring); and what start was used (:class:`StartInfo`)."""
    names = [ws.base.state_names[i] for i in ws.x0_idx]
    if not ws.x0_idx:
        return list(data["x0"]), StartInfo((), {}, {})
    kd = data["kd"].replace(model=ws.model_with(values, base_values))
    logged = logged_state_channels(ws.base, ws.x0_idx, floor)
    s = np.asarray(ws.x0_scale, float)
    half = np.array([rule.bound * floor[c] / s[j] if c is not None and np.isfinite(rule.bound) else np.inf
                     for j, c in enumerate(logged)])
    R = data["x0"].shape[0]

    def res(d):
        return np.asarray(ws.x0_kernel.call("residuals", d, kd))

    def jac(d):
        return np.asarray(ws.x0_kernel.call("jacobian", d, kd))

    d = bounded_offsets(res, jac, R, -half, half, max_steps=rule.max_steps)
    x0 = list(np.asarray(ws.x0_kernel.initial_states(d, kd)))
    D = d.reshape(R, len(names)) * s
    off, at = {}, {}
    for i, rn in enumerate(run_names):
        off[rn] = {n: (float(D[i, j] / floor[c]) if c is not None else float("nan"))
                   for j, (n, c) in enumerate(zip(names, logged))}
        at[rn] = tuple(n for j, n in enumerate(names) if np.isfinite(half[j]) and abs(d[i * len(names) + j]) >= half[j] * (1 - 1e-9))
    return x0, StartInfo(tuple(names), off, at)
