r"""The search of an output-error fit: proposals, whole-run candidates, and the likelihood that decides.

A fit must not be decided by where it starts or by a short horizon. Three rules make the answer a
property of the data and the model:

1. **Proposals** (:func:`candidates`): every start is first fitted on the first part of every run (the
   warm-up, :mod:`diffship.fit.warmup`): cheap, well conditioned steps that find basins. The warm-up
   proposes; it does not pick.
2. **Whole-run candidates**: the distinct converged proposals (lowest warm-up cost first), then the other
   proposals, then the starts as they are — as many as there are starts (``--starts N``: N whole-run
   candidates) — are solved on the whole runs together (:meth:`~diffship.fit.kernel.Kernel.solve_many`).
   On the bundled SSPA zigzag at 50 Hz every start's warm-up reached one point whose whole-run optimum
   was a local one (heading 2.6°); the starts themselves, solved on the whole runs, found the better.
3. **The likelihood decides** (:func:`~diffship.fit.weights.concentrated_cost`): every candidate is solved at
   its own **self-consistent channel scales** (:func:`reweighted_solves`): rounds of Levenberg–Marquardt steps,
   between them the scales :math:`s_c = \sqrt{\tau_c\,\mathrm{SSE}_c/N}` re-estimated from the candidate's
   residuals, so that it ends where the weighted least-squares optimum is the likelihood's (with each
   channel's noise level unknown, on ``N/τ_c`` effective samples); candidates are then compared by that
   likelihood at one set of correlation times — a number that does not depend on the weights a candidate was
   solved with. Weights taken from a warm-up's or a start's residuals made the answer depend on the path (the
   SSPA zigzag: K 0.79, 1.10 or 0.67 for three option sets); at the self-consistent scales it is K 0.826–0.834
   at 5, 10, 20 and 50 Hz, with or without the warm-up, from 4 or 64 starts.

A parameter stopped on a log-mapped bound is released by :func:`bound_escape` (the Gauss–Newton step in
the parameters themselves, where the fit space hides it).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from ..params import ParamSpec
from .identifiability import per_scale_columns
from .kernel import PENALTY
from .warmup import same_points, wrap_periodic
from .weights import concentrated_cost, correlation_time, self_consistent_scales

__all__ = ["REWEIGHT_RTOL", "ROUND_STEPS", "bound_escape", "candidates", "objective_or_cost", "reweighted_solves"]

#: A candidate is done when its channel scales change by less than this (relative) at a converged point.
REWEIGHT_RTOL = 2e-3
#: Levenberg–Marquardt steps per round of the whole-run candidates (their scales re-estimated between rounds);
#: the first round, at the channels' sensor noise, is shorter: the scales adapt before the solve goes far.
ROUND_STEPS = 25
FIRST_ROUND_STEPS = 5


def candidates(starts: Sequence[np.ndarray], proposals: Sequence[tuple[int, np.ndarray, float, bool]],
               period: np.ndarray, n: int | None = None) -> list[tuple[int, np.ndarray, str]]:
    """The whole-run candidates ``[(start index, z, "warm-up point" | "start"), ...]`` (module docstring,
    rule 2): ``proposals`` are ``(start index, z, warm-up cost, converged)``; distinct means unknowns
    apart by more than 10⁻⁴ of a scale (initial angles modulo a turn, ``period``) or costs by more than
    10⁻⁴ of themselves (:func:`~diffship.fit.warmup.same_points`). ``n`` candidates (default: one per start)."""
    n = len(starts) if n is None else int(n)
    ordered = (sorted((p for p in proposals if p[3]), key=lambda p: p[2])
               + sorted((p for p in proposals if not p[3]), key=lambda p: p[2]))
    rep = same_points([p[1] for p in ordered], [p[2] for p in ordered], period=period)
    out = [(p[0], np.asarray(p[1]), "warm-up point") for k, p in enumerate(ordered) if rep[k] == k]
    for i, z in enumerate(starts):
        if len(out) >= n:
            break
        if not any(np.all(np.abs(wrap_periodic(np.asarray(z) - zc, period)) <= 1e-4) for _, zc, _ in out):
            out.append((i, np.asarray(z), "start"))
    return out[:max(n, 1)]


def reweighted_solves(kernel, zs: Sequence[np.ndarray], data, scales: np.ndarray, lm: dict, *, cap: int, total: int,
                      floor: np.ndarray, reweight: bool = True, effective_samples: bool = True,
                      period: np.ndarray | None = None, progress=None, label: str = "solve") -> list[dict]:
    """Every candidate solved on the whole runs at its own self-consistent channel scales (module docstring,
    rule 3), together: rounds of ``cap`` Levenberg–Marquardt steps (the data's traced step cap), after each
    round each candidate's scales :math:`s_c = \sqrt{\tau_c\,\mathrm{SSE}_c/N}` re-estimated from its residuals
    (``reweight``; τ its residuals' correlation times where ``effective_samples``); a candidate is done when
    its solve converged at scales that moved by less than :data:`REWEIGHT_RTOL`, or after ``total`` steps; a
    candidate that reaches another's point (every unknown within 10⁻³ of a scale, angles modulo ``period``)
    is merged into it. Every candidate's first round runs at ``scales`` (the channels' sensor noise: a start far
    from the optimum has drifting residuals whose scales would leave the data almost no weight in that round).
    Returns per candidate ``{"z", "status", "steps", "r", "r_prior", "scales", "tau",
    "jac", "merged_into", "blew_up"}``."""
    n_c = len(scales)
    per = np.zeros(len(zs[0])) if period is None else np.asarray(period)
    out = [{"z": np.asarray(z), "status": None, "steps": 0, "r": None, "r_prior": None, "scales": np.asarray(scales),
            "tau": np.ones(n_c), "jac": None, "merged_into": None, "blew_up": False, "done": False} for z in zs]
    mask = np.asarray(data.mask)
    capped = data.with_step_cap(cap)
    first = data.with_step_cap(min(FIRST_ROUND_STEPS, cap)) if reweight else capped
    n_round = 0
    while True:
        active = [i for i, c in enumerate(out) if not c["done"] and c["merged_into"] is None and c["steps"] < total]
        if not active:
            break
        stacked = jax.tree_util.tree_map(lambda a: jnp.stack([a] * len(active)), first if n_round == 0 else capped)
        n_round += 1
        stacked = stacked.replace(scales=jnp.asarray(np.stack([out[i]["scales"] for i in active])))
        solved = kernel.solve_many(np.stack([out[i]["z"] for i in active]), stacked, per_problem=True, progress=progress,
                                   label=label, **lm)
        for i, (z, res, k, r, *jac) in zip(active, solved):
            c = out[i]
            d = capped.replace(scales=jnp.asarray(c["scales"]))
            rd, rp = (np.asarray(x) for x in kernel.split(np.asarray(r), d))
            c.update(z=wrap_periodic(np.asarray(z), per), status=res, steps=c["steps"] + int(k), r=rd, r_prior=rp,
                     jac=jac[0] if jac else None)
            if not np.all(np.isfinite(np.asarray(r))) or np.any(rd == PENALTY):  # the kernel marks a blow-up exactly
                c.update(done=True, blew_up=True)
                continue
            converged = _code(res) == _code(optx.RESULTS.successful)
            if not reweight:
                c["done"] = converged or int(k) < cap
                continue
            tau = correlation_time(rd, mask, n_c) if effective_samples else np.ones(n_c)
            new = self_consistent_scales(rd, mask, c["scales"], tau, floor)
            if converged and float(np.max(np.abs(new / c["scales"] - 1.0))) < REWEIGHT_RTOL:
                c.update(done=True, tau=tau)
            else:
                c.update(scales=new, tau=tau)
        live = [i for i, c in enumerate(out) if c["merged_into"] is None and not c["blew_up"]]
        for a_, i in enumerate(live):
            for j in live[:a_]:
                if out[j]["merged_into"] is None and np.all(np.abs(wrap_periodic(out[i]["z"] - out[j]["z"], per)) <= 1e-3):
                    out[i]["merged_into"] = j
                    break
    return out


def _code(res) -> int:
    return int(jax.tree_util.tree_leaves(res)[0])


def objective_or_cost(rd: np.ndarray, rp: np.ndarray, mask: np.ndarray, scales: np.ndarray,
                      tau: np.ndarray | None) -> float:
    """The candidates' comparison number: the concentrated likelihood at ``tau``, or without correlation
    times (fixed channel scales) the weighted cost ½‖r‖²."""
    if tau is None:
        return 0.5 * float(rd @ rd + rp @ rp)
    return concentrated_cost(rd, mask, scales, tau, rp)


def bound_escape(spec: ParamSpec, z: np.ndarray, r: np.ndarray, J: np.ndarray, n_p: int,
                 gntol: float) -> tuple[np.ndarray, float] | None:
    r"""The Gauss–Newton step in the parameters θ (not the fit variables ``z``) where it is long.

    A bounded parameter lives in a log-mapped ``z`` (:mod:`diffship.params`): on its bound,
    :math:`\partial\theta/\partial z \to 0`, so the Jacobian in ``z`` loses that column and LM stops
    ("converged": the step in ``z`` is short) even where the cost falls steeply as the parameter
    leaves the bound. In θ/scale the step :math:`\delta = -J_\theta^{+} r` sees it: if its marginal
    length over the parameters exceeds ``gntol`` standard errors (:mod:`diffship.fit._lm`), the
    point ``θ + δ`` (kept 10⁻³ scales inside the bounds; initial-state unknowns moved by their part
    of the step) is returned with that length, else ``None``. Measured on the MMG KVLCC2 zigzag
    (``benchmarks/kvlcc2_second_minimum.py``): J'_z pinned at 10⁻⁶ on its bound 0, step 1.26 se
    long, pointing to the optimum (J'_z 0.011) that LM with J'_z unbounded reaches from there.
    """
    n = J.shape[1]
    col = per_scale_columns(spec, z, n)
    Jt = J * col
    m = int(np.sum(r != 0))
    s2 = float(r @ r) / max(m - n, 1)
    step, *_ = np.linalg.lstsq(Jt, -r, rcond=None)
    cov = np.linalg.pinv(Jt.T @ Jt, hermitian=True)[:n_p, :n_p]
    length = math.sqrt(max(float(step[:n_p] @ np.linalg.pinv(cov, hermitian=True) @ step[:n_p]) / s2, 0.0))
    if not length > gntol:
        return None
    names = spec.free_names
    theta = np.asarray(spec.from_z(jnp.asarray(z[:n_p])))
    new = {}
    for i, name in enumerate(names):
        p = spec[name]
        v = theta[i] + step[i] * p.scale
        new[name] = float(np.clip(v, p.lower + 1e-3 * p.scale, p.upper - 1e-3 * p.scale))
    try:
        z_theta = spec.to_z(new)
    except Exception:  # pragma: no cover - clipped inside the bounds
        return None
    return np.concatenate([z_theta, z[n_p:] + step[n_p:] / col[n_p:]]), length
