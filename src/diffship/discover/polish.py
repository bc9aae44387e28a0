r"""Polish a discovered structure on the output-error cost: removals, swaps and additions, every move refitted.

The screens (:mod:`.oescreen`, :mod:`.screen`) linearise once, at the base fit. The missing terms bias that fit, so
a near-collinear stand-in can look better than the true term. On the benchmark's sway truth, :math:`v|v||r|`
stood in for :math:`v^2 r`, and :math:`r|v||r|` for :math:`v r^2`. Alone, each stand-in lowers the cost more than
the true term does. Together, the true pair lowers it most. A greedy forward path takes the stand-in first and keeps
it.

Starting from the best structure the screens' candidates reached, each round tries three kinds of move from that
structure's own optimum:

1. **removal** of each term;
2. **swap** of each term for each of the ``k_swap`` terms of its own equation with the largest linearised gain
   once that term is taken out. The gain is computed on the simulation Jacobian at the structure's optimum, with
   the term's contribution removed from the residual linearly (Miller, *Subset selection in regression*, 2nd ed.,
   2002, §3.5, the replacement algorithm);
3. **addition** of the ``k_add`` terms with the largest linearised gain, while fewer than ``max_terms`` are in.

Every move is refitted by output error. The refits run on one compiled all-terms model
(:class:`~diffship.diagnose.screen.Workspace`): switching a term on is data, not a new program. Each refit starts
from the structure's optimum. The best move is taken when it lowers the criterion:

- a removal, by any amount;
- a swap or an addition, by at least ``margin``.

The rounds stop when no move is taken, or after ``max_rounds``.

The criterion is the BIC of the normalised training residuals, :math:`n\ln(2C/m) + k\ln n`. Here :math:`C` is the
refit's cost, :math:`m` the residual count, :math:`n = m/\kappa` the effective sample count, and κ the variance
inflation of autocorrelated residuals at the base fit (:func:`~diffship.diagnose.screen.inflation`). The polish
proposes; the structure it ends at is refitted by the driver and ranked with the others (:mod:`.rank`), which
decides.

Measured on the sway truth of ``benchmarks/independent/discovery_truths.py``: from the screens' best,
``Y_u_r_av + Y_v_r_r + N_r_av_ar``, the polish took three moves: swap ``Y_u_r_av`` → ``Y_v_v_r``, remove
``Y_v_r_r``, swap ``N_r_av_ar`` → ``N_v_r_r``. It ends at the true pair ``Y_v_v_r + N_v_r_r`` (32 refits).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Sequence

import numpy as np

from ..data import Run
from ..diagnose.screen import Workspace, inflation
from ..errors import DiffshipError
from ..fit import FitResult
from ..models.terms import term_class
from ..params import ParamSpec
from .oescreen import conditional_gains

__all__ = ["Polish", "polish"]


@dataclasses.dataclass(frozen=True)
class Polish:
    """The path of :func:`polish`.

    Attributes:
        start, selected: the structure polished and the one it ends at.
        path: ``(kind, move, structure after, criterion)`` per move taken (kind ``remove``, ``swap`` or ``add``).
        values: ``{term: value}`` and ``base``: ``{base parameter: value}`` at the selected structure's optimum.
        refits: workspace refits run; seconds: wall time (compilation included).
    """

    start: tuple[str, ...]
    selected: tuple[str, ...]
    path: tuple[tuple[str, str, tuple[str, ...], float], ...]
    values: dict[str, float]
    base: dict[str, float]
    refits: int
    seconds: float


def polish(res0: FitResult, spec: ParamSpec, runs: Sequence[Run], terms: Sequence[str], start: Sequence[str], *,
           start_values: dict[str, float] | None = None, start_base: dict[str, float] | None = None,
           max_terms: int = 4, k_swap: int = 2, k_add: int = 2, max_rounds: int = 6, margin: float = 2.0,
           max_iter: int = 60, progress: Callable[[str], None] | None = None) -> Polish:
    """Polish the structure ``start`` (module docstring).

    ``res0`` is the base fit (its model, channels, noise scales, initial states and integrator); ``spec`` gives the
    base's free and fixed parameters; ``terms`` is the library. ``start_values`` and ``start_base`` are the start
    structure's term and base values (default: the base fit, with the terms at zero).
    """
    say = progress or (lambda s: None)
    t0 = time.perf_counter()
    chans = tuple(res0.channels)
    scales = {c: res0.noise_std.get(c, res0.channel_scales.get(c, 1.0)) for c in chans}
    x0 = res0.initial_states if len(res0.initial_states) == len(runs) else None
    ws = Workspace(res0.model, spec.with_values({n: res0.params[n] for n in spec.names}),
                   [term_class(t)() for t in terms], runs, chans, scales, x0_train=x0, integrator=res0.integrator,
                   warmup=0.0, refits=True, max_iter=max_iter)
    names = list(ws.phi_names)
    eq = {t: term_class(t).equation for t in names}
    m = ws.train["batch"].n_residuals
    r0 = ws.residuals(ws.z0(), ws.selection([]), ws.phi_null)
    n_eff = max(m / inflation(r0, ws.train["batch"], len(chans)), 2.0)

    def crit(cost: float, k: int) -> float:
        return n_eff * math.log(max(2.0 * cost / m, 1e-300)) + k * math.log(n_eff)

    def order(s) -> tuple[str, ...]:
        return tuple(t for t in names if t in s)

    visited: dict[tuple[str, ...], tuple[float, float, dict[str, float], dict[str, float]]] = {}
    count = [0]

    def refit(struct: tuple[str, ...], vals: dict[str, float], base_vals: dict[str, float] | None) -> None:
        struct = order(struct)
        count[0] += 1
        try:
            rf = ws.refit(list(struct), [{t: vals.get(t, 0.0) for t in struct}], finish=True, base_start=base_vals)
        except DiffshipError as exc:
            say(f"  polish refit {' + '.join(struct)}: failed ({exc})")
            return
        if rf.ok and math.isfinite(rf.train_cost) and (struct not in visited or rf.train_cost < visited[struct][1]):
            visited[struct] = (crit(rf.train_cost, len(struct)), rf.train_cost, dict(rf.values), dict(rf.base_values))

    def linearised(S: tuple[str, ...]):
        """Residuals, base/initial-state columns and every term's column at S's optimum."""
        _, _, vals, base_vals = visited[S]
        r, J_th, cols = ws.columns(base_values=base_vals, values=vals)
        return r, J_th, np.stack([cols[n] for n in names], axis=1)

    S = order(start)
    if not S:
        raise DiffshipError("polish: give a structure with at least one term")
    refit(S, dict(start_values or {}), dict(start_base) if start_base else None)
    if S not in visited:
        raise DiffshipError(f"polish: the start structure {' + '.join(S)} could not be refitted")
    path: list[tuple[str, str, tuple[str, ...], float]] = []
    for _ in range(int(max_rounds)):
        r, J_th, G = linearised(S)
        vals, base_vals = visited[S][2], visited[S][3]
        moves: list[tuple[str, str, tuple[str, ...]]] = []
        for t in S:
            rest = tuple(x for x in S if x != t)
            if rest:
                moves.append(("remove", t, rest))
            i = names.index(t)
            r_out = r - G[:, i] * (vals[t] - ws.phi_null[i]) / ws.phi_scale[i]  # S without t, linearly
            gain = conditional_gains(r_out, J_th, G, [names.index(x) for x in rest])
            alts = [names[k] for k in np.argsort(-gain) if gain[k] > 0 and eq[names[k]] == eq[t]
                    and names[k] not in S][:k_swap]
            moves += [("swap", f"{t} → {a}", rest + (a,)) for a in alts]
        if len(S) < max_terms:
            gain = conditional_gains(r, J_th, G, [names.index(x) for x in S])
            moves += [("add", names[k], S + (names[k],)) for k in np.argsort(-gain)[:k_add] if gain[k] > 0]
        for _, _, T in moves:
            if order(T) not in visited:
                refit(T, vals, base_vals)
        scored = sorted((visited[order(T)][0], kind, what, order(T)) for kind, what, T in moves if order(T) in visited)
        if not scored:
            break
        c, kind, what, T = scored[0]
        here = visited[S][0]
        if not (c <= here if kind == "remove" else c <= here - margin):
            say(f"  polish: no move lowers the criterion (best: {kind} {what}, {c - here:+.1f})")
            break
        S = T
        path.append((kind, what, S, c))
        say(f"  polish: {kind} {what} → {' + '.join(S)} (criterion {c - here:+.1f})")
    return Polish(start=order(start), selected=S, path=tuple(path), values=dict(visited[S][2]),
                  base=dict(visited[S][3]), refits=count[0], seconds=time.perf_counter() - t0)
