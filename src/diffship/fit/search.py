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
   SSPA zigzag: K 0.79, 1.10 or 0.67 for three option sets); at the self-consistent scales it is K 0.840–0.846
   at 5, 10, 20 and 50 Hz, with or without the warm-up, from 4 or 64 starts. Where the rounds cycle (the next
   scales are an earlier round's: a correlation time jumping between two readings of a channel), the candidate
   stops at the first repeat and the progress says so; before, it repeated the cycle to its step budget.

4. **Adaptive** (:func:`adaptive`): while fewer than two candidates reach the best point, the likelihood has
   optima the candidates went to instead, and more candidates are drawn (spread around the best and around the
   first start), up to :data:`MAX_CANDIDATES`, until a batch neither reaches nor beats the best; where every
   candidate agrees, nothing more is spent.

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

__all__ = ["DOMINATED", "F_TOL", "FIRST_ROUND_STEPS", "JUDGED_STEPS", "MAX_CANDIDATES", "SCALES_MOVING", "adaptive", "reached", "REWEIGHT_RTOL", "SAME_OBJECTIVE",
           "bound_escape", "candidates", "objective_or_cost", "reweighted_solves"]

#: A candidate is done when its channel scales change by less than this (relative) at a converged point.
REWEIGHT_RTOL = 2e-3
#: From the fourth round on, a candidate whose objective is this far above the best's stops (dominated: on one
#: scale, a likelihood 50 units worse is far outside any standard error); of two within SAME_OBJECTIVE (one standard
#: error along one direction) of each other, the higher merges into the lower: on that scale it is no better, and
#: following both costs a second whole-run solve for the same answer.
DOMINATED = 50.0
SAME_OBJECTIVE = 0.5
#: From the third round on, a candidate whose likelihood changed by less than this over a round is done (a tenth
#: of a standard error: further rounds move it along a ridge the data do not determine).
F_TOL = 0.05
#: A candidate whose channel scales moved by more than this (relative, the largest channel) over its last round goes
#: back to rounds of FIRST_ROUND_STEPS; one whose scales moved less takes a round twice as long as its last. While
#: the scales move, the weights follow the residuals every few steps, as iteratively reweighted least squares
#: does; long rounds at scales that are still moving cost steps that the next scales undo. On the bundled SSPA
#: zigzag at 50 Hz (``python benchmarks/robustness.py --timing-only``): rounds growing regardless took 675
#: whole-run steps to the answer (K 0.8396), these rounds 134 (K 0.8397).
SCALES_MOVING = 0.05
#: Candidates are compared (dominated, merged) from the fourth round on, once each has converged in a round or
#: taken this many steps (four short rounds).
JUDGED_STEPS = 20
#: The adaptive search draws candidates up to this many in all (:func:`adaptive`).
MAX_CANDIDATES = 32
#: Levenberg–Marquardt steps of a candidate's first round, at the channels' sensor noise: a few, so that its
#: scales adapt to its own residuals before the solve goes far; later rounds as :data:`SCALES_MOVING` says.
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
                      period: np.ndarray | None = None, progress=None, label: str = "solve",
                      stall_ends: bool = False) -> list[dict]:
    r"""Every candidate solved on the whole runs at its own self-consistent channel scales (module docstring,
    rule 3), together: rounds of :data:`FIRST_ROUND_STEPS` while a candidate's scales move by more than
    :data:`SCALES_MOVING`, otherwise each twice its last, up to ``cap`` Levenberg–Marquardt
    steps (the data's traced step cap, per candidate), after each round each candidate's scales :math:`s_c = \sqrt{\tau_c\,\mathrm{SSE}_c/N}` re-estimated from its residuals
    (``reweight``; τ its residuals' correlation times where ``effective_samples``); a candidate is done when
    its solve converged at scales that moved by less than :data:`REWEIGHT_RTOL`, when its likelihood changed by less
    than :data:`F_TOL` over a round (from the third), or after ``total`` steps; with ``stall_ends``, also when a round
    stopped because its cost stalled (the solve's stall rule) at scales that moved by less than :data:`SCALES_MOVING`.
    After
    the third round (once each has converged in a round or taken :data:`JUDGED_STEPS` steps) the candidates are compared by the likelihood on one scale: one :data:`DOMINATED` behind the
    best stops there, and of two within :data:`SAME_OBJECTIVE` of each other the higher is merged into the lower. Every candidate's first round runs at ``scales`` (the channels' sensor noise: a start far
    from the optimum has drifting residuals whose scales would leave the data almost no weight in that round).
    Returns per candidate ``{"z", "status", "steps", "r", "r_prior", "r_scales", "scales", "tau",
    "jac", "merged_into", "blew_up", "dominated"}``: ``r`` and ``jac`` are normalised by ``r_scales`` (the scales
    of the solve that made them); ``scales`` are the next round's, and compare with nothing."""
    n_c = len(scales)
    per = np.zeros(len(zs[0])) if period is None else np.asarray(period)
    out = [{"z": np.asarray(z), "status": None, "steps": 0, "r": None, "r_prior": None, "scales": np.asarray(scales),
            "r_scales": np.asarray(scales), "tau": np.ones(n_c), "jac": None, "merged_into": None, "blew_up": False,
            "done": False, "dominated": False, "round_steps": min(FIRST_ROUND_STEPS, cap)}
           for z in zs]
    mask = np.asarray(data.mask)
    capped = data.with_step_cap(cap)
    n_round = 0
    while True:
        active = [i for i, c in enumerate(out) if not c["done"] and c["merged_into"] is None and c["steps"] < total]
        if not active:
            break
        # rounds that grow: short while the scales adapt to the candidate's residuals (the solve follows the
        # likelihood, as iteratively reweighted least squares does), long once they have settled (SCALES_MOVING)
        caps = {i: out[i]["round_steps"] if reweight else cap for i in active}
        # stacked on the host: jnp.stack would compile a program per field shape
        stacked = jax.tree_util.tree_map(lambda a: np.stack([np.asarray(a)] * len(active)), data.with_step_cap(cap))
        n_round += 1
        stacked = stacked.replace(scales=np.stack([out[i]["scales"] for i in active]),
                                  step_cap=np.asarray([caps[i] for i in active], np.int32))
        solved = kernel.solve_many(np.stack([out[i]["z"] for i in active]), stacked, per_problem=True, progress=progress,
                                   label=label, **lm)
        for i, (z, res, k, r, *jac) in zip(active, solved):
            c = out[i]
            d = capped.replace(scales=jnp.asarray(c["scales"]))
            rd, rp = (np.asarray(x) for x in kernel.split(np.asarray(r), d))
            c.update(z=wrap_periodic(np.asarray(z), per), status=res, steps=c["steps"] + int(k), r=rd, r_prior=rp,
                     r_scales=np.asarray(c["scales"]), jac=jac[0] if jac else None)
            if not np.all(np.isfinite(np.asarray(r))) or np.any(rd == PENALTY):  # the kernel marks a blow-up exactly
                c.update(done=True, blew_up=True)
                continue
            converged = _code(res) == _code(optx.RESULTS.successful)
            if not reweight:
                c["done"] = converged or int(k) < caps[i]
                continue
            tau = correlation_time(rd, mask, n_c) if effective_samples else np.ones(n_c)
            new = self_consistent_scales(rd, mask, c["scales"], tau, floor)
            f_own = concentrated_cost(rd, mask, c["scales"], tau, rp)
            # a small change of the likelihood means a ridge only over a round of the growing schedule (a short round
            # of a candidate whose scales still move changes it little because it is short)
            settled = n_round >= 3 and caps[i] > FIRST_ROUND_STEPS and abs(f_own - c.get("f_last", np.inf)) < F_TOL
            moved = float(np.max(np.abs(np.log(new / c["scales"]))))
            c["round_steps"] = FIRST_ROUND_STEPS if moved > SCALES_MOVING else min(2 * caps[i], cap)
            c["judged"] = c.get("judged", False) or converged or c["steps"] >= JUDGED_STEPS
            c["f_last"] = f_own
            # the next scales against this round's and every earlier round's, the latest first: this round's (period
            # 1) is convergence at self-consistent scales; an earlier one's is a cycle, where the rounds would repeat
            # from there (a correlation time jumping between two readings of a channel; measured on the 6-DOF ROV
            # test problem: a six-round cycle, repeated to the step budget, 45 of the fit's 58 s): stop at the repeat
            seen = c.setdefault("seen", [])
            seen.append(np.asarray(c["scales"]))
            period = next((len(seen) - k for k in range(len(seen) - 1, -1, -1)
                           if float(np.max(np.abs(new / seen[k] - 1.0))) < REWEIGHT_RTOL), 0) if converged else 0
            crawl = stall_ends and not converged and int(k) < caps[i] and moved <= SCALES_MOVING
            if period or settled or crawl:
                c.update(done=True, tau=tau, cycle=period if period > 1 else 0)
                if period > 1 and progress:
                    progress(f"{label}: start {i + 1}: the channel scales cycle with a period of {period} rounds "
                             "(a correlation time jumps between two readings): stopped at the first repeat")
            else:
                c.update(scales=new, tau=tau)
        live = [i for i, c in enumerate(out) if c["merged_into"] is None and not c["blew_up"]]
        if reweight and n_round > 3 and len(live) > 1 and all(out[i].get("judged") for i in live):
            # after a full round the candidates compare on one scale (the likelihood at their smallest correlation
            # times): one that reaches another's point merges into it; one far behind the best is dominated
            tau_ref = np.min(np.stack([out[i]["tau"] for i in live]), axis=0)
            f = {i: concentrated_cost(out[i]["r"], mask, out[i]["r_scales"], tau_ref, out[i]["r_prior"]) for i in live}
            best = min(f.values())
            for a_, i in enumerate(live):
                if f[i] > best + DOMINATED:
                    out[i].update(done=True, dominated=True)
                    continue
                for j in live[:a_]:
                    if out[j]["merged_into"] is None and abs(f[i] - f[j]) <= SAME_OBJECTIVE:
                        lo, hi = (i, j) if f[i] <= f[j] else (j, i)
                        out[hi]["merged_into"] = lo
                        if hi == i:
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
    with np.errstate(over="ignore", invalid="ignore"):
        Jt = J * col
        if not np.all(np.isfinite(Jt)):  # a parameter so deep on its bound that θ's column overflows: no step
            return None
        m = int(np.sum(r != 0))
        s2 = float(r @ r) / max(m - n, 1)
        try:
            step, *_ = np.linalg.lstsq(Jt, -r, rcond=None)
            cov = np.linalg.pinv(Jt.T @ Jt, hermitian=True)[:n_p, :n_p]
            length = math.sqrt(max(float(step[:n_p] @ np.linalg.pinv(cov, hermitian=True) @ step[:n_p]) / s2, 0.0))
        except (np.linalg.LinAlgError, ValueError):
            return None
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


def reached(sols: list[dict], mask: np.ndarray) -> int:
    """How many candidates (a merged one with the point it reached) are within 0.5 of the best objective on one
    scale (the likelihood at the smallest correlation times among them); each candidate's objective is stored
    as ``"f"``."""
    good = [s_ for s_ in sols if not s_["blew_up"] and s_["r"] is not None]
    if not good:
        return 0
    tau = np.min(np.stack([s_["tau"] for s_ in good]), axis=0)
    for s_ in sols:
        src = root(sols, s_)
        s_["f"] = (np.inf if src["blew_up"] or src["r"] is None else
                   objective_or_cost(src["r"], src["r_prior"], mask, src["r_scales"], tau))
    best = min(s_["f"] for s_ in sols)
    return sum(1 for s_ in sols if s_["f"] <= best + 0.5)


def adaptive(cands: list, sols: list[dict], solve, more, mask: np.ndarray, n: int, say=None) -> tuple[list, list]:
    """The adaptive part of the search: while fewer than two candidates reach the best point (the likelihood has
    other optima the candidates went to), ``n`` more are drawn — ``more(best candidate, n, round)`` gives their
    unknowns — and solved (``solve``), up to :data:`MAX_CANDIDATES` in all; ``n = 0``: none. It stops as soon as
    a batch neither reaches the best point nor beats it: the best stands against fresh candidates (a mis-specified
    model's rugged likelihood sends every draw elsewhere, and more draws only cost time — a USV missing its
    current drew 24 more in 70 s for nothing). Returns the candidates ``(start index, z, kind)`` and their
    solutions, extended."""
    round_ = 0
    while n > 0 and len(cands) < MAX_CANDIDATES and reached(sols, mask) < 2:
        live = [j for j, s_ in enumerate(sols) if not s_["blew_up"]]
        if not live:
            break
        b = min(live, key=lambda j: sols[j].get("f", np.inf))
        zs = more(sols[b], min(n, MAX_CANDIDATES - len(cands)), round_)
        if not zs:
            break
        round_ += 1
        if say:
            say(f"output error: {reached(sols, mask)} of {len(sols)} candidates reached the best point: {len(zs)} more")
        new = [(cands[b][0], z, "spread around the best") for z in zs]
        extra = solve(new)
        for s_ in extra:  # merged within the new batch: its index in the whole list
            s_["merged_into"] = None if s_["merged_into"] is None else s_["merged_into"] + len(sols)
        cands, sols = cands + new, sols + extra
        if reached(sols, mask) < 2 and min(range(len(sols)), key=lambda j: sols[j]["f"]) < len(sols) - len(extra):
            if say:
                say(f"output error: none of the {len(extra)} more reached or beat the best point: it stands")
            break
    return cands, sols


def root(sols: list[dict], s_: dict) -> dict:
    """The candidate ``s_`` ended at: itself, or the one it merged into (followed to the end of a chain)."""
    seen = 0
    while s_["merged_into"] is not None and seen < len(sols):
        s_, seen = sols[s_["merged_into"]], seen + 1
    return s_
