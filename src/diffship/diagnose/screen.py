r"""The all-effects workspace: score-test screen of every candidate, and warm-started refits.

All candidates live in **one** augmented model (every library effect at its null value), so
one compiled residual function and one compiled forward-mode Jacobian serve the screen, every
refit and every step of the greedy path (a candidate is selected by a dynamic selection matrix,
not by recompiling):

.. math::
    z = (z_\theta, w), \qquad \theta = \theta(z_\theta)\ \text{(the base fit's scaled space)},
    \qquad \varphi = \mathrm{clip}(\varphi_0 + S w,\ \varphi_{lo}, \varphi_{hi})

**Score test.** At the base fit, with normalised residuals :math:`e` (length m), base Jacobian
:math:`J_\theta` (orthonormal basis Q) and the candidate's fingerprint :math:`G_k = \partial e/
\partial\varphi_k` (forward mode for smooth nulls; a probe secant
:math:`e(\varphi_{probe}) - e(\varphi_0)` for non-smooth ones), the part the base parameters
cannot absorb is :math:`G_\perp = (I - QQ^\top)G_k` and

.. math::
    T_k = e^\top G_\perp (G_\perp^\top G_\perp)^{-1} G_\perp^\top e \,/\, (\hat\sigma^2\kappa)

is the Lagrange-multiplier statistic (χ² with dim φ_k degrees of freedom), with κ ≥ 1 a
variance inflation for autocorrelated residuals (1 + 2Σρ_l of the residual ACF). We also report
the predicted fraction of the training cost it removes, :math:`f_k = \hat\sigma^2\kappa T_k /
e^\top e`, and the orthogonal fraction :math:`o_k = \|G_\perp\|^2/\|G\|^2` (identifiability:
o_k ≈ 0 means the base parameters can mimic the effect to first order).

**Refit** (:meth:`Workspace.refit`): Levenberg–Marquardt with Marquardt scaling over the base
parameters, the chosen effects' parameters and the per-run initial states, warm-started at θ̂
from each given φ start; the start with the lowest cost wins. Which candidates are refitted,
from which starts, and how they are judged on the held-out runs is decided in :mod:`.which`
and :mod:`.shrink`.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from scipy import stats

from ..errors import FitError
from ..fit.problem import make_batch
from ..models import AbstractModel
from ..params import ParamSpec
from ..simulate import simulate
from .effects import Augmented, Effect

__all__ = ["Workspace", "ScreenResult", "RefitResult", "P_MAX"]

#: Largest number of effect parameters refitted at once (one or two effects).
P_MAX = 5
PENALTY = 1e3
_CACHE: dict = {}


def _wrap(e):
    return jnp.arctan2(jnp.sin(e), jnp.cos(e))


class _Kernel(eqx.Module):
    """Static structure shared by the compiled functions."""

    spec: ParamSpec = eqx.field(static=True)
    out_idx: tuple[int, ...] = eqx.field(static=True)
    angle: tuple[bool, ...] = eqx.field(static=True)
    substeps: int = eqx.field(static=True)

    def residuals(self, z, model, S, phi0, lo, hi, ts, us, ys, mask, x0, scales, idx, x0_scale):
        """z = (scaled base parameters, P_MAX effect coordinates, per-run initial-state offsets)."""
        n = len(self.spec.free_names)
        th = self.spec.full_values(z[:n], model.base.theta())
        phi = jnp.clip(phi0 + S @ z[n:n + P_MAX], lo, hi)
        mdl = model.with_params(jnp.concatenate([th, phi]))
        if idx.size:
            x0 = x0.at[:, idx].add(z[n + P_MAX:].reshape(x0.shape[0], idx.size) * x0_scale)
        sol = jax.vmap(lambda t, u, x: simulate(mdl, t, u, x, substeps=self.substeps))(ts, us, x0)
        err = sol.ys[..., jnp.asarray(self.out_idx)] - ys
        err = jnp.where(jnp.asarray(self.angle), _wrap(err), err)
        good = (sol.valid & mask)[..., None]
        bad = ((~sol.valid) & mask)[..., None]
        return (jnp.where(good, err / scales, 0.0) + jnp.where(bad, PENALTY, 0.0)).reshape(-1)

    def jacobian(self, z, *args):
        return jax.jacfwd(self.residuals)(z, *args)

    def jacobian_x0(self, z, *args):
        """Jacobian with respect to the initial-state offsets only."""
        k = len(self.spec.free_names) + P_MAX

        def f(d):
            return self.residuals(jnp.concatenate([z[:k], d]), *args)

        return jax.jacfwd(f)(z[k:])


def _compiled(kernel, name, args):
    leaves, treedef = jax.tree_util.tree_flatten(args)
    key = (kernel, name, treedef, tuple((np.shape(x), str(jnp.asarray(x).dtype)) for x in leaves))
    if key not in _CACHE:
        _CACHE[key] = jax.jit(getattr(kernel, name)).lower(*args).compile()
    return _CACHE[key]


@dataclasses.dataclass(frozen=True)
class ScreenResult:
    """Score-test screen of one candidate."""

    effect: str
    params: tuple[str, ...]
    statistic: float
    p_value: float
    predicted_fraction: float
    orthogonal_fraction: float
    secant: bool


@dataclasses.dataclass(frozen=True)
class RefitResult:
    """A warm-started refit with some effects switched on."""

    effects: tuple[str, ...]
    values: dict[str, float]
    stderr: dict[str, float]
    base_values: dict[str, float]
    train_cost: float
    iterations: int
    seconds: float
    ok: bool


class Workspace:
    """The all-effects model of a base fit, with compiled residual and Jacobian functions.

    Args:
        base: the fitted base model.
        spec: the base fit's spec (free flags, bounds, scales) with the fitted values.
        effects: candidate effects (at null).
        runs: training runs.
        channels: fitted channels; ``scales``: their normalisation (the base fit's noise σ).
    """

    def __init__(self, base: AbstractModel, spec: ParamSpec, effects: Sequence[Effect], runs, channels,
                 scales: dict[str, float], substeps: int = 1, x0_train: Sequence[np.ndarray] | None = None):
        self.base = base
        self.spec = spec
        self.effects = list(effects)
        self.model = Augmented(base, self.effects)
        self.effects = list(self.model.effects)  # canonical order
        self.phi_names = tuple(n for e in self.effects for n in e.param_names)
        self.owner = {n: e for e in self.effects for n in e.param_names}
        self.phi_null = np.array([self.owner[n].null()[n] for n in self.phi_names])
        lo, hi = [], []
        for e in self.effects:
            for p in e.PARAMS:
                lo.append(p.lower if math.isfinite(p.lower) else -1e12)
                hi.append(p.upper if math.isfinite(p.upper) else 1e12)
        self.lo, self.hi = np.asarray(lo), np.asarray(hi)
        self.channels = tuple(channels)
        self.scales = np.asarray([scales[c] for c in self.channels])
        # the compiled functions only need the spec's structure: drop the values so that fits
        # of other data share them
        shape_spec = ParamSpec(tuple(dataclasses.replace(p, value=0.0) for p in spec.params))
        self.kernel = _Kernel(spec=shape_spec, out_idx=tuple(self.model.output_names.index(c) for c in self.channels),
                              angle=tuple(c in self.model.angle_outputs for c in self.channels), substeps=int(substeps))
        self.n_theta = len(spec.free_names)
        self.z_theta = spec.to_z()
        states = base.states_for_channels(self.channels)
        self.x0_idx = np.asarray([i for i, s in enumerate(base.state_names) if s in states], dtype=np.int64)
        self.train = self._data(runs, x0_train)
        b = self.train["batch"]
        spread = [float(np.std(b.ys[..., j][b.mask])) or 1.0 for j in range(len(self.channels))]
        sc = getattr(base, "STATE_CHANNEL", {})

        def _scale(st):
            c = st if st in self.channels else sc.get(st)
            return spread[self.channels.index(c)] if c in self.channels else 1.0

        self.x0_scale = np.asarray([_scale(base.state_names[i]) for i in self.x0_idx], dtype=np.float64)

    def _data(self, runs, x0_base=None):
        b = make_batch(self.model, runs, self.channels)
        x0 = np.asarray(b.x0).copy()
        if x0_base is not None:
            x0[:, :len(self.base.state_names)] = np.stack([np.asarray(v)[:len(self.base.state_names)] for v in x0_base])
        return dict(batch=b, x0=x0, arrays=tuple(jnp.asarray(a) for a in (b.ts, b.us, b.ys, b.mask, x0)))

    def data(self, runs):
        """Arrays for other runs (e.g. validation), initial states from the data."""
        return self._data(runs)

    def fitted_x0(self, data, values: dict[str, float], base_values: dict[str, float] | None = None,
                  iters: int = 6) -> list[np.ndarray]:
        """Initial states of the fitted channels' states estimated per run by Gauss–Newton with
        the model fixed (as MATLAB ``compare`` does), so validation errors do not depend on the
        noise of the first samples. The same procedure is used for every compared model."""
        z = self.z0(data, base_values)
        S, phi0 = self.selection([]), self.phi_vector(dict(values))
        R, k = data["x0"].shape[0], self.x0_idx.size
        if k == 0:
            return list(data["x0"])
        nk = self.n_theta + P_MAX
        r = self.residuals(z, S, phi0, data)
        cost = float(r @ r)
        for _ in range(iters):
            J = self.jacobian_x0(z, S, phi0, data)
            H = J.T @ J
            step = np.linalg.solve(H + 1e-6 * np.diag(np.maximum(np.diag(H), 1e-12)), -J.T @ r)
            zn = z.copy()
            zn[nk:] += step
            rn = self.residuals(zn, S, phi0, data)
            cn = float(rn @ rn)
            if not math.isfinite(cn) or cn >= cost:
                break
            rel = (cost - cn) / cost
            z, r, cost = zn, rn, cn
            if rel < 1e-8:
                break
        x0 = data["x0"].copy()
        x0[:, self.x0_idx] += z[nk:].reshape(R, k) * self.x0_scale
        return list(x0)

    # -- evaluation helpers ------------------------------------------------------------
    def _args(self, data, S, phi0, model=None):
        return ((model or self.model), jnp.asarray(S), jnp.asarray(phi0), jnp.asarray(self.lo), jnp.asarray(self.hi),
                *data["arrays"], jnp.asarray(self.scales), jnp.asarray(self.x0_idx), jnp.asarray(self.x0_scale))

    def n_x0(self, data=None) -> int:
        return (data or self.train)["x0"].shape[0] * self.x0_idx.size

    def z0(self, data=None, base_values=None) -> np.ndarray:
        zt = self.z_theta if not base_values else self.spec.with_values(
            {n: base_values[n] for n in self.spec.names}).to_z()
        return np.concatenate([zt, np.zeros(P_MAX), np.zeros(self.n_x0(data))])

    def residuals(self, z, S, phi0, data=None, model=None):
        args = self._args(data or self.train, S, phi0, model)
        fn = _compiled(self.kernel, "residuals", (jnp.asarray(z),) + args)
        return np.asarray(fn(jnp.asarray(z), *args))

    def jacobian(self, z, S, phi0, data=None, model=None):
        args = self._args(data or self.train, S, phi0, model)
        fn = _compiled(self.kernel, "jacobian", (jnp.asarray(z),) + args)
        return np.asarray(fn(jnp.asarray(z), *args))

    def jacobian_x0(self, z, S, phi0, data=None, model=None):
        args = self._args(data or self.train, S, phi0, model)
        fn = _compiled(self.kernel, "jacobian_x0", (jnp.asarray(z),) + args)
        return np.asarray(fn(jnp.asarray(z), *args))

    def selection(self, names: Sequence[str]) -> np.ndarray:
        S = np.zeros((len(self.phi_names), P_MAX))
        for j, n in enumerate(names):
            S[self.phi_names.index(n), j] = 1.0
        return S

    def phi_vector(self, values: dict[str, float]) -> np.ndarray:
        phi = self.phi_null.copy()
        for n, v in values.items():
            phi[self.phi_names.index(n)] = v
        return phi

    def model_with(self, values: dict[str, float], base_values: dict[str, float] | None = None) -> Augmented:
        m = self.model
        if base_values:
            m = m.with_params(base_values)
        return m.with_params({n: float(v) for n, v in values.items()})

    # -- screen ----------------------------------------------------------------------------
    def screen(self) -> tuple[list[ScreenResult], dict]:
        """Score test of every candidate at the base fit (one Jacobian pass per 5 columns)."""
        t0 = time.perf_counter()
        z0 = self.z0()
        phi0 = self.phi_null
        r0 = self.residuals(z0, self.selection([]), phi0)
        nk = self.n_theta + P_MAX
        smooth = [n for n in self.phi_names if self.owner[n].smooth_null]
        cols: dict[str, np.ndarray] = {}
        J_theta = None
        for k in range(0, max(len(smooth), 1), P_MAX):
            chunk = smooth[k:k + P_MAX]
            J = self.jacobian(z0, self.selection(chunk), phi0)
            J_theta = np.concatenate([J[:, :self.n_theta], J[:, nk:]], axis=1) if J_theta is None else J_theta
            for j, n in enumerate(chunk):
                cols[n] = J[:, self.n_theta + j]
        for n in self.phi_names:
            if n in cols:
                continue
            probe = self.owner[n].PROBE[n]
            r1 = self.residuals(z0, self.selection([]), self.phi_vector({n: probe}))
            cols[n] = np.where(np.abs(r1) >= PENALTY, 0.0, r1 - r0)
        u, sv, _ = np.linalg.svd(J_theta, full_matrices=False)
        Q = u[:, sv > sv[0] * 1e-10] if sv.size else u[:, :0]
        m = r0.size
        s2 = float(r0 @ r0) / max(m - J_theta.shape[1], 1)
        kappa = _inflation(r0, self.train["batch"], len(self.channels))
        out = []
        for e in self.effects:
            G = np.stack([cols[n] for n in e.param_names], axis=1)
            Gp = G - Q @ (Q.T @ G)
            g2 = float(np.sum(G * G))
            o = float(np.sum(Gp * Gp)) / g2 if g2 > 0 else 0.0
            gtr = Gp.T @ r0
            A = Gp.T @ Gp
            if g2 == 0 or o < 1e-12:
                ss = 0.0
            else:
                ss = float(gtr @ np.linalg.lstsq(A, gtr, rcond=1e-12)[0])
            T = ss / (s2 * kappa)
            out.append(ScreenResult(e.name, e.param_names, T, float(stats.chi2.sf(T, len(e.param_names))),
                                    ss / float(r0 @ r0), o, not e.smooth_null))
        out.sort(key=lambda s: -s.predicted_fraction)
        info = {"seconds": time.perf_counter() - t0, "inflation": kappa, "train_cost": 0.5 * float(r0 @ r0),
                "residual_variance": s2, "n_residuals": m}
        return out, info

    # -- refit -----------------------------------------------------------------------------
    def _lm(self, S, phi0, active, max_iter):
        z = self.z0()
        r = self.residuals(z, S, phi0)
        cost = 0.5 * float(r @ r)
        if not math.isfinite(cost) or np.any(np.abs(r) >= PENALTY):
            return z, r, math.inf, 0
        lam, it = 1e-3, 0
        for it in range(1, max_iter + 1):
            J = self.jacobian(z, S, phi0)[:, active]
            g = J.T @ r
            H = J.T @ J
            d = np.maximum(np.diag(H), 1e-12 * max(np.max(np.diag(H)), 1e-300))
            improved, rel = False, 0.0
            for _ in range(12):
                try:
                    step = np.linalg.solve(H + lam * np.diag(d), -g)
                except np.linalg.LinAlgError:
                    lam *= 10
                    continue
                zn = z.copy()
                zn[active] += step
                rn = self.residuals(zn, S, phi0)
                cn = 0.5 * float(rn @ rn)
                if math.isfinite(cn) and cn < cost:
                    improved = True
                    rel = (cost - cn) / max(cost, 1e-300)
                    z, r, cost = zn, rn, cn
                    lam = max(lam / 5, 1e-9)
                    break
                lam *= 6
            if not improved or rel < 1e-9:
                break
        return z, r, cost, it

    def refit(self, names: Sequence[str], starts: Sequence[dict[str, float]], fixed: dict[str, float] | None = None,
              max_iter: int = 60, progress: Callable[[str], None] | None = None) -> RefitResult:
        """Refit base parameters + the parameters of effects ``names`` (``fixed``: other effect
        values held, e.g. already accepted effects that are refitted jointly are in ``names``)."""
        t0 = time.perf_counter()
        pn = [n for e in self.effects if e.name in names for n in e.param_names]
        if len(pn) > P_MAX:
            raise FitError(f"too many effect parameters at once ({len(pn)} > {P_MAX})")
        S = self.selection(pn)
        base_phi = self.phi_vector(fixed or {})
        nk = self.n_theta + P_MAX
        active = list(range(self.n_theta)) + [self.n_theta + j for j in range(len(pn))] + \
            list(range(nk, nk + self.n_x0()))
        best = None
        for st in starts:  # LM from every start (non-smooth effects have flat regions)
            phi0 = base_phi.copy()
            for n in pn:
                phi0[self.phi_names.index(n)] = st.get(n, self.owner[n].PROBE[n])
            z, r, cost, it = self._lm(S, phi0, active, max_iter)
            if math.isfinite(cost) and (best is None or cost < best[2]):
                best = (z, r, cost, it, phi0)
        if best is None:
            raise FitError(f"refit with {names}: every start blows up")
        z, r, cost, it, phi0 = best
        J = self.jacobian(z, S, phi0)[:, active]
        s2 = float(r @ r) / max(r.size - len(active), 1)
        try:
            cov = s2 * np.linalg.pinv(J.T @ J)
        except np.linalg.LinAlgError:
            cov = np.full((len(active), len(active)), np.inf)
        phi = np.clip(phi0 + self.selection(pn) @ z[self.n_theta:nk], self.lo, self.hi)
        values = {n: float(phi[self.phi_names.index(n)]) for n in pn}
        stderr = {n: float(math.sqrt(max(cov[self.n_theta + j, self.n_theta + j], 0.0))) for j, n in enumerate(pn)}
        th = np.asarray(self.spec.full_values(jnp.asarray(z[:self.n_theta]), self.base.theta()))
        base_values = {n: float(th[i]) for i, n in enumerate(self.base.param_names)}
        fixed_out = {n: float(base_phi[self.phi_names.index(n)]) for n in (fixed or {}) if n not in pn}
        ok = bool(np.all(np.abs(r) < PENALTY))
        if progress:
            progress(f"  refit {'+'.join(names)}: {it} iterations, cost {cost:.6g}, "
                     + ", ".join(f"{n}={v:.4g}±{stderr[n]:.2g}" for n, v in values.items()))
        return RefitResult(tuple(names), {**fixed_out, **values}, stderr, base_values, cost, it,
                           time.perf_counter() - t0, ok)


def _inflation(r: np.ndarray, batch, n_ch: int, max_lag: int = 50) -> float:
    """1 + 2 Σ ρ_l (Bartlett-weighted) of the residuals, averaged over channels; ≥ 1."""
    e = r.reshape(batch.mask.shape + (n_ch,))
    vals = []
    for j in range(n_ch):
        for i in range(e.shape[0]):
            x = e[i, batch.mask[i], j]
            x = x - x.mean()
            if x.size < 10 or not np.any(x):
                continue
            L = min(max_lag, x.size // 4)
            c0 = float(x @ x)
            rho = np.array([float(x[:-k] @ x[k:]) / c0 for k in range(1, L + 1)])
            w = 1.0 - np.arange(1, L + 1) / (L + 1)
            vals.append(1.0 + 2.0 * float(np.sum(w * rho)))
    return float(max(np.mean(vals) if vals else 1.0, 1.0))
