r"""The output-error screen of structure discovery: greedy forward selection on the simulation Jacobian.

At the base model's output-error fit, with normalised simulation residuals :math:`e` (length m), the
Jacobian :math:`J_\theta` of the base parameters and initial states (orthonormal basis Q) and each
library term's fingerprint :math:`g_k = \partial e/\partial c_k` (the change of the *simulated*
outputs when the term is switched on; :meth:`diffship.diagnose.screen.Workspace.columns`, one compiled
all-terms model), the linearised refit with the terms S is the least squares

.. math:: \min_{\delta}\ \|e + J_\theta\delta_\theta + G_S\delta_S\|^2 .

Greedy forward selection adds, at each step, the term whose part orthogonal to the base columns and
to the terms already chosen, :math:`g_\perp`, removes most of the residual,
:math:`\Delta_k = (g_\perp^\top e_S)^2/\|g_\perp\|^2`, and its score statistic
:math:`T_k = \Delta_k/(\hat\sigma^2\kappa)` (Lagrange multiplier, χ²₁ under "no such term"; κ ≥ 1 the
variance inflation of autocorrelated residuals, :func:`diffship.diagnose.screen.inflation`).
The path continues to ``max_terms`` terms whatever :math:`T_k` (it only proposes structures, which are
refitted and ranked on output residuals, :mod:`.rank`); ``supported`` marks the steps with
:math:`T_k > \ln(m/\kappa)`, the BIC penalty of one parameter on the effective sample count.

Unlike the equation-error screen (:mod:`.screen`), the regressors here are simulated, not measured:
noise in the measured velocities and their numerical derivatives does not bias it (no errors in
variables), and a term is judged by what it does to the outputs being fitted (Söderström & Stoica,
*System identification*, Prentice Hall 1989, §7.6 on the bias of equation error; Rao, *Linear
statistical inference*, 1973, §6e for the score test).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from ..data import Run
from ..diagnose.screen import Workspace, inflation
from ..fit import FitResult
from ..fit.identifiability import per_scale_columns
from ..fit.kernel import PENALTY
from ..initial import start_request
from ..integrators import AbstractIntegrator
from ..metrics import start_channels
from ..models import AbstractModel
from ..models.terms import term_class, with_terms
from ..params import ParamSpec
from ..simulate import simulation_request

__all__ = ["term_workspace", "term_programs", "OEScreen", "Linearisation", "conditional_gains", "forward_path",
           "lowest_start", "oe_screen"]

#: The term workspace's refits: step cap per solve (``4·MAX_ITER``) and stall rule (a fall of less than ρ·cost
#: over W steps stops a solve): :class:`~diffship.diagnose.screen.Workspace`.
MAX_ITER, STALL = 60, (10, 1e-3)


@dataclasses.dataclass(frozen=True)
class OEScreen:
    """The forward path of the output-error screen.

    Attributes:
        path: terms in the order chosen.
        statistic: each step's score statistic :math:`T_k` (module docstring).
        supported: each step's :math:`T_k > \\ln(m/\\kappa)`.
        values: ``{term: linearised estimate}`` of the last step's least squares (model units).
        fraction: each step's share of the base fit's training cost removed (linearised).
        inflation: κ; seconds: wall time (compilation included).
        linearisation: the refits linearised at the base fit (:class:`Linearisation`: the structures' starts).
    """

    path: tuple[str, ...]
    statistic: tuple[float, ...]
    supported: tuple[bool, ...]
    values: dict[str, float]
    fraction: tuple[float, ...]
    inflation: float
    seconds: float
    linearisation: Linearisation | None = dataclasses.field(default=None, repr=False, compare=False)

    def candidates(self, max_terms: int) -> list[tuple[str, ...]]:
        """The path's prefixes, at most ``max_terms`` long."""
        return [tuple(self.path[:k]) for k in range(1, min(max_terms, len(self.path)) + 1)]


def span(A: np.ndarray) -> np.ndarray:
    """An orthonormal basis of the column space of ``A`` (its left singular vectors above 10⁻¹⁰ of the largest)."""
    u, sv, _ = np.linalg.svd(A, full_matrices=False)
    return u[:, sv > sv[0] * 1e-10] if sv.size else u[:, :0]


class Linearisation:
    r"""The workspace refits linearised at one structure's optimum ``S`` (or at the base fit, ``S`` empty).

    With the normalised residuals :math:`e`, the base and initial-state columns :math:`J_\theta` and every term's
    column :math:`g_k` there (:meth:`~diffship.diagnose.screen.Workspace.columns`), a structure :math:`T` is refitted
    linearly: the terms of S not in T taken out (:math:`e' = e - \sum g_k w_k`, :math:`w_k` a term's scaled value),
    then :math:`\min_\delta \|e' + J_\theta\delta_\theta + G_T\delta_T\|^2`, solved on the parts orthogonal to
    :math:`J_\theta` (its span Q computed once). :meth:`cost` is that least squares' cost; :meth:`start` its point, the
    Gauss–Newton step from S's optimum, where T's refit starts near its own optimum (from S's values with T's new
    terms at zero, a refit crawls along the valley of near-collinear terms: on the four-term truth of
    ``benchmarks/independent/discovery_truths.py`` the polish's 27 refits took 31 s from there, 21 s from here).
    """

    def __init__(self, ws: Workspace, S: Sequence[str] = (), values: dict[str, float] | None = None,
                 base_values: dict[str, float] | None = None):
        self.ws, self.S, self.values = ws, tuple(S), dict(values or {})
        self.base_values = base_values
        r, self.J_theta, cols = ws.columns(base_values=base_values, values=values)
        self.names = list(ws.phi_names)
        self.G = np.stack([cols[n] for n in self.names], axis=1)
        self.r = np.asarray(r)
        self.Q = span(self.J_theta)
        self._pinv = None
        self.z_theta = ws.z0(base_values=base_values)[:ws.n_theta]

    def scaled(self, t: str) -> float:
        """Term ``t``'s scaled value at S's optimum (0 for a term not in S)."""
        i = self.names.index(t)
        return (self.values[t] - self.ws.phi_null[i]) / self.ws.phi_scale[i] if t in self.S else 0.0

    def _solve(self, T: Sequence[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[int]]:
        """``(e', G_T, δ_T, indices)``: the residual with the terms of S not in T taken out, T's columns and the
        least-squares step of T's terms."""
        r = self.r.copy()
        for t in self.S:
            if t not in T:
                r -= self.G[:, self.names.index(t)] * self.scaled(t)
        idx = [self.names.index(x) for x in T]
        H, Q = self.G[:, idx], self.Q
        Hp, rp = H - Q @ (Q.T @ H), r - Q @ (Q.T @ r)
        d = -np.linalg.lstsq(Hp, rp, rcond=None)[0] if idx else np.zeros(0)
        return r, H, d, idx

    def cost(self, T: Sequence[str]) -> float:
        """T's cost by the linearised refit (class docstring)."""
        r, H, d, _ = self._solve(T)
        e = r + H @ d
        e = e - self.Q @ (self.Q.T @ e)
        return 0.5 * float(e @ e)

    def start(self, T: Sequence[str], step: float = 1.0) -> tuple[dict[str, float], dict[str, float], np.ndarray]:
        """T's start at the linearised refit's point: ``(term values, base values, initial-state offsets)`` (the
        offsets scaled, the tail of :meth:`~diffship.diagnose.screen.Workspace.z0`); ``step`` < 1: that fraction of the
        way from S's optimum (T's new terms at zero) to it."""
        ws, spec, n = self.ws, self.ws.spec, self.ws.n_theta
        r, H, d, idx = self._solve(T)
        if self._pinv is None:
            # the base parameters' step in θ/scale, not in the fit variables: a parameter near a log-mapped bound has a
            # vanishing column in z, where the pseudo-inverse's step is huge (a base fit's X_u at −0.08 against its
            # bound 0 moved to −10²³); in θ it is the step the linearisation means, then kept inside the bounds
            self._pinv = np.linalg.pinv(self.J_theta * per_scale_columns(spec, self.z_theta, self.J_theta.shape[1]))
        d_s = -self._pinv @ (r + H @ d) * step
        w = np.asarray([self.scaled(x) for x in T]) + d * step
        phi = np.clip(ws.phi_null[idx] + ws.phi_scale[idx] * w, ws.lo[idx], ws.hi[idx])
        th = (np.asarray([float(self.base_values[k]) for k in ws.base.param_names]) if self.base_values
              else np.array(ws.base.theta(), dtype=float))
        free = spec.free_index()
        for j, (i, name) in enumerate(zip(free, spec.free_names)):
            p = spec[name]
            th[i] = float(np.clip(th[i] + d_s[j] * p.scale, p.lower + 1e-3 * p.scale, p.upper - 1e-3 * p.scale))
        return ({x: float(v) for x, v in zip(T, phi)}, dict(zip(ws.base.param_names, map(float, th))), d_s[n:])


def lowest_start(ws: Workspace, structure: Sequence[str], starts: Sequence[tuple]) -> tuple:
    """Of the starts ``(term values, base values or None, initial-state offsets or None)`` of a refit of ``structure``
    on ``ws``, the one whose training cost is lowest (the first where none simulates); a single start as it is."""
    if len(starts) == 1:
        return starts[0]
    sel = ws.selection(list(structure))

    def cost(st) -> float:
        vals, base_vals, x0 = st
        z = ws.z0(base_values=base_vals, x0=x0)
        r = ws.residuals(z, sel, ws.phi_vector({t: vals.get(t, 0.0) for t in structure}))
        return 0.5 * float(r @ r) if np.all(np.isfinite(r)) and not np.any(np.abs(r) >= PENALTY) else math.inf
    costs = [cost(st) for st in starts]
    return starts[int(np.argmin(costs))] if np.any(np.isfinite(costs)) else starts[0]


def conditional_gains(r: np.ndarray, J_theta: np.ndarray, G: np.ndarray, chosen: Sequence[int]) -> np.ndarray:
    r"""Each column's linearised cost reduction given the base columns and the ``chosen`` ones:
    :math:`(h_k^\top e)^2/\|h_k\|^2`, with :math:`h_k` column k orthogonal to them and :math:`e` the residual
    orthogonal to them (0 for the chosen columns and for columns inside their span)."""
    Q = span(np.concatenate([J_theta, G[:, list(chosen)]], axis=1) if len(chosen) else J_theta)
    H = G - Q @ (Q.T @ G)
    e = r - Q @ (Q.T @ r)
    nn = np.sum(H * H, axis=0)
    ok = nn > 1e-12 * np.maximum(np.sum(G * G, axis=0), 1e-300)
    gain = np.where(ok, (H.T @ e) ** 2 / np.maximum(nn, 1e-300), 0.0)
    gain[list(chosen)] = 0.0
    return gain


def forward_path(r0: np.ndarray, J_theta: np.ndarray, G: np.ndarray, max_terms: int, s2: float, kappa: float):
    """``(order, T, fraction, delta)``: greedy forward selection of the columns of ``G`` (m × q) on the
    residual ``r0`` beyond the span of ``J_theta`` (module docstring), each step the largest
    :func:`conditional_gains` given the columns chosen before; ``delta`` the linearised least-squares
    coefficients of the chosen columns (the step that lowers ``‖r0 + J δ‖``)."""
    total = float(r0 @ r0)
    order: list[int] = []
    T: list[float] = []
    frac: list[float] = []
    for _ in range(min(max_terms, G.shape[1])):
        gain = conditional_gains(r0, J_theta, G, order)
        k = int(np.argmax(gain))
        if gain[k] <= 0:
            break
        order.append(k)
        T.append(float(gain[k]) / (s2 * kappa))
        frac.append(float(gain[k]) / max(total, 1e-300))
    delta = np.zeros(len(order))
    if order:
        A = np.concatenate([J_theta, G[:, order]], axis=1)
        sol, *_ = np.linalg.lstsq(A, -r0, rcond=None)
        delta = sol[J_theta.shape[1]:]
    return order, T, frac, delta


def term_workspace(res0: FitResult, spec: ParamSpec, runs: Sequence[Run], terms: Sequence[str], refits: bool = True,
                   max_iter: int = MAX_ITER, stall: tuple[int, float] | None = STALL,
                   phi_scales: dict[str, float] | None = None) -> Workspace:
    """The all-terms model of the base fit ``res0`` on ``runs`` (:class:`~diffship.diagnose.screen.Workspace`): a
    structure is switched on by data, so the screen, every candidate's refit and the polish run one compiled
    program. Refits start from the base fit's initial states and stop when the cost stalls (``stall``: a fall of
    less than ρ·cost over W steps); one that removes half the base fit's cost is finished without the rule.
    ``phi_scales``: the terms' scales (:func:`~.scaling.term_scales`; default: their declared placeholder)."""
    chans = tuple(res0.channels)
    scales = {c: res0.noise_std.get(c, res0.channel_scales.get(c, 1.0)) for c in chans}
    x0 = res0.initial_states if len(res0.initial_states) == len(runs) else None
    ws = Workspace(res0.model, spec.with_values({n: res0.params[n] for n in spec.names}),
                   [term_class(t)() for t in terms], runs, chans, scales, x0_train=x0, integrator=res0.integrator,
                   warmup=0.0, refits=refits, max_iter=max_iter, stall=stall, phi_scales=phi_scales)
    r0 = ws.residuals(ws.z0(), ws.selection([]), ws.phi_null)
    ws.base_cost = 0.5 * float(r0 @ r0)  # a refit that halves it is finished (:meth:`Workspace.refit`)
    return ws


def term_programs(base: AbstractModel, spec: ParamSpec, runs: Sequence[Run], validate: Sequence[Run],
                  terms: Sequence[str], chans: Sequence[str], integrator: AbstractIntegrator,
                  phi_scales: dict[str, float] | None = None) -> list:
    """The compiled programs a discovery runs after its base fit, from the base model *before* that fit (they depend
    on the structure, not on values, as the diagnosis's :func:`~diffship.diagnose.diagnosis.workspace_programs`): the
    all-terms :func:`term_workspace`'s residuals and solve (the output-error screen, every refit and the polish) and
    the all-terms model's simulations of the training and held-out runs and its initial-state estimates on them by
    the metrics' start rule (the ranking, and the judging of the base and the selected fit). ``chans`` and ``integrator``:
    the base fit's. Compiled in the background while the base fit runs (:func:`diffship.compiled.prefetch`), a cold
    discovery does not compile them after it."""
    start = spec.with_values(spec.nudged({p.name: p.value for p in spec.params})[0])  # inside the bounds
    ws = Workspace(base, start, [term_class(t)() for t in terms], runs, chans, {c: 1.0 for c in chans},
                   integrator=integrator, warmup=0.0, max_iter=MAX_ITER, stall=STALL, phi_scales=phi_scales)
    full = with_terms(base, terms)
    sims = [simulation_request(full, r, np.zeros(len(full.state_names)), integrator)
            for r in {r.n: r for r in (*runs, *validate)}.values()]
    starts = [q for rs in (runs, validate) if rs
              for q in start_request(full, list(rs), start_channels(full, rs, chans), integrator=integrator)]
    return ws.programs() + sims + starts


def oe_screen(res0: FitResult, spec: ParamSpec, runs: Sequence[Run], terms: Sequence[str], *,
              max_terms: int = 4, workspace: Workspace | None = None) -> OEScreen:
    """Screen the library ``terms`` at the base fit ``res0`` (its model, channels, noise scales and
    integrator; ``spec``: the base's free/fixed parameters) on the training ``runs``. ``workspace``: the all-terms
    :func:`term_workspace` of the same fit, when the refits that follow use it (one compiled program for both)."""
    import time

    t0 = time.perf_counter()
    chans = tuple(res0.channels)
    ws = workspace or term_workspace(res0, spec, runs, terms, refits=False)
    lin = Linearisation(ws)
    r0, J_theta, G = lin.r, lin.J_theta, lin.G
    names = lin.names  # one coefficient per term, in the workspace's order
    m = ws.train["batch"].n_residuals
    s2 = float(r0 @ r0) / max(m - J_theta.shape[1], 1)
    kappa = inflation(r0, ws.train["batch"], len(chans))
    order, T, frac, delta = forward_path(r0, J_theta, G, max_terms, s2, kappa)
    path = tuple(names[k] for k in order)
    values = {n: float(ws.phi_null[names.index(n)] + ws.phi_scale[names.index(n)] * d) for n, d in zip(path, delta)}
    cut = math.log(max(m / kappa, 2.0))
    return OEScreen(path=path, statistic=tuple(T), supported=tuple(t > cut for t in T), values=values,
                    fraction=tuple(frac), inflation=kappa, seconds=time.perf_counter() - t0, linearisation=lin)
