"""Peer methods a user would pick today, in NumPy/SciPy (no JAX), shared by the suite's cases and
``fossen3_speed.py``.

What they measure against diffship: the same problem solved by another tool (speed at equal
final cost, accuracy on the same data).

* :class:`NomotoProblem`, :class:`Fossen3Problem` — diffship's output-error residual for the
  first-order Nomoto and the Fossen 3-DOF model, re-implemented in NumPy (fixed-step RK4, one step
  per sample, inputs linearly interpolated, heading wrapped, same channel scales, same scaled
  parameter space, same per-run initial-state offsets, diffship's penalty after a blow-up).
* :func:`scipy_fit` — :func:`scipy.optimize.least_squares` (``method="lm"``: MINPACK with 2-point
  finite differences) on such a residual, with a wall-clock guard and the time at which its best
  cost first came within 1 % of a target cost (for speed "at equal final cost").
* :func:`nomoto_ols`, :func:`fossen3_ols` — ordinary least squares (``numpy.linalg.lstsq``) on
  inverse-dynamics forces / the yaw equation (the seeds' way; statsmodels' OLS gives the same
  numbers and is not installed here).
* :func:`stlsq` — sequentially thresholded least squares (Brunton et al., PNAS 2016), the core
  of SINDy, in NumPy: pysindy itself needs scikit-learn, which is not installed in this
  environment, so the peer is this small re-implementation (pysindy's default optimiser).
"""

from __future__ import annotations

import math
import time

import numpy as np
from scipy.optimize import least_squares

from benchmarks.common.fitapi import PENALTY

MAX_ABS = 1e8  # diffship.simulate's blow-up threshold


class ScaledParams:
    """diffship's scaled parameter space (:mod:`diffship.params`) in NumPy."""

    def __init__(self, spec):
        self.spec = spec
        self.free = spec.free_names
        self.n_p = len(self.free)
        self.base = spec.values()
        free = [spec[n] for n in self.free]
        # kind: 0 linear, 1 lower, 2 upper, 3 both (diffship.params conventions)
        self.kind = np.array([p.kind for p in free])
        self.lo = np.array([p.lower if math.isfinite(p.lower) else 0.0 for p in free])
        self.hi = np.array([p.upper if math.isfinite(p.upper) else 0.0 for p in free])
        self.s = np.array([p.scale for p in free])

    def from_z(self, z):
        zc = np.clip(z, -50.0, 50.0)
        ez = np.exp(zc)
        sig = 1.0 / (1.0 + np.exp(-zc))
        k = self.kind
        return np.where(k == 0, self.s * z, np.where(k == 1, self.lo + self.s * ez,
                        np.where(k == 2, self.hi - self.s * ez, self.lo + (self.hi - self.lo) * sig)))

    def params(self, z):
        vals = dict(self.base)
        vals.update({n: float(v) for n, v in zip(self.free, self.from_z(np.asarray(z)[: self.n_p]))})
        return vals


class SimulationProblem(ScaledParams):
    """diffship's normalised output-error residual over a NumPy simulation (``self.simulate``):
    per-run initial-state offsets, wrapped angles, masked padding, ``PENALTY`` after a blow-up."""

    def residuals(self, z):
        self.nfev += 1
        z = np.asarray(z, dtype=np.float64)
        p = self.params(z)
        x0 = self.x0.copy()
        if self.x0_idx:
            x0[:, self.x0_idx] += z[self.n_p:].reshape(self.R, len(self.x0_idx)) * self.x0_scale
        out, valid = self.simulate(p, x0)
        pred = np.transpose(out, (2, 0, 1))[..., self.out_cols]
        valid = valid.T
        with np.errstate(all="ignore"):
            err = pred - self.ys
            err = np.where(self.angle, np.arctan2(np.sin(err), np.cos(err)), err)
            good = (valid & self.mask)[..., None]
            bad = ((~valid) & self.mask)[..., None]
            e = np.where(good, err / self.scales, 0.0) + np.where(bad, PENALTY, 0.0)
        return e.reshape(-1)


class NomotoProblem(SimulationProblem):
    r"""Output-error residual of :class:`diffship.models.Nomoto1` in NumPy.

    :math:`\dot\psi = r,\ T_1\dot r + r = K(\delta + \delta_0)`, RK4 with one step per sample,
    vectorised over runs; residual ``(sim_c − meas_c)/s_c`` for channels (psi, r), the
    heading error wrapped; per-run offsets of the initial psi and r (scaled by the spreads).
    """

    def __init__(self, spec, batch, scales, estimate_x0=("psi", "r")):
        super().__init__(spec)
        self.ys = batch.ys  # (R, N, C)
        self.mask = batch.mask
        self.x0 = batch.x0  # (R, 2): psi, r
        self.R, self.N = batch.ts.shape
        self.channels = batch.channels
        self.scales = np.asarray(scales, dtype=np.float64)
        self.angle = np.array([c == "psi" for c in batch.channels])
        self.x0_idx = [("psi", "r").index(s) for s in estimate_x0]
        self.x0_scale = np.array([self.scales[list(batch.channels).index(s)] for s in estimate_x0])
        us = batch.us[..., 0].T  # (N, R)
        self.ua, self.uc = us[:-1], us[1:]
        self.ub = 0.5 * (self.ua + self.uc)
        self.h = (batch.ts[:, 1:] - batch.ts[:, :-1]).T  # (N-1, R)
        self.out_cols = [("psi", "r").index(c) for c in batch.channels]
        self.nfev = 0

    def simulate(self, p, x0):
        K, T, d0 = p["K"], p["T1"], p["delta0"]
        psi, r = x0[:, 0].copy(), x0[:, 1].copy()
        out = np.empty((self.N, 2, self.R))
        out[0] = psi, r
        with np.errstate(all="ignore"):
            for k in range(self.N - 1):
                h = self.h[k]
                hh = 0.5 * h
                f1 = (K * (self.ua[k] + d0) - r) / T
                r2 = r + hh * f1
                f2 = (K * (self.ub[k] + d0) - r2) / T
                r3 = r + hh * f2
                f3 = (K * (self.ub[k] + d0) - r3) / T
                r4 = r + h * f3
                f4 = (K * (self.uc[k] + d0) - r4) / T
                psi = psi + h / 6.0 * (r + 2.0 * r2 + 2.0 * r3 + r4)
                r = r + h / 6.0 * (f1 + 2.0 * f2 + 2.0 * f3 + f4)
                out[k + 1, 0] = psi
                out[k + 1, 1] = r
            ok = np.all(np.isfinite(out) & (np.abs(out) < MAX_ABS), axis=1)
        return out, np.cumprod(ok, axis=0).astype(bool)


class Fossen3Problem(SimulationProblem):
    """Output-error residual of :class:`diffship.models.Fossen3` in NumPy (``fossen3_speed.py``'s problem).

    Integrates only (psi, u, v, r): the positions x0, y0 feed nothing back and are not fitted, so
    dropping them changes no residual (diffship integrates all six states).
    """

    def __init__(self, spec, model, batch, x0_idx, x0_scale, scales):
        super().__init__(spec)
        self.ts = batch.ts
        self.ys = batch.ys  # (R, N, C), heading unwrapped
        self.mask = batch.mask
        self.x0 = batch.x0  # (R, n_x)
        self.R, self.N = batch.ts.shape
        self.x0_idx = list(x0_idx)
        self.x0_scale = np.asarray(x0_scale, dtype=np.float64)
        self.scales = np.asarray(scales, dtype=np.float64)
        self.angle = np.array([c in model.angle_outputs for c in batch.channels])
        sn = model.state_names
        self.i_psi, self.i_u, self.i_v, self.i_r = (sn.index(c) for c in ("psi", "u", "v", "r"))
        self.out_cols = [("psi", "u", "v", "r").index(c) for c in batch.channels]
        # inputs per step: (N-1, 3, R) at the start, middle and end of every interval
        us = np.transpose(batch.us, (1, 2, 0))  # (N, 3, R)
        self.u_a = us[:-1]
        self.u_c = us[1:]
        self.u_b = 0.5 * (self.u_a + self.u_c)
        self.h = self.ts[:, 1:] - self.ts[:, :-1]  # (R, N-1)
        self.h_uniform = float(self.h[0, 0]) if np.allclose(self.h, self.h[0, 0], rtol=0, atol=1e-12) else None
        self.nfev = 0

    # simulation ---------------------------------------------------------------------------
    def simulate(self, p, x0):
        """RK4, one step per sample; returns (psi, u, v, r) each (N, R) and a validity mask (N, R)."""
        m, xg = p["m"], p["xg"]
        Xudot, Yvdot, Yrdot, Nvdot, Nrdot = p["Xudot"], p["Yvdot"], p["Yrdot"], p["Nvdot"], p["Nrdot"]
        Xu, Yv, Yr, Nv, Nr, Xuu, Yvv, Nrr = p["Xu"], p["Yv"], p["Yr"], p["Nv"], p["Nr"], p["Xuu"], p["Yvv"], p["Nrr"]
        ca = m * xg
        cy = m - Yvdot
        cr = 0.5 * (Nvdot + Yrdot)
        mu = m - Xudot  # M[0,0] and the Coriolis coefficient b/u
        Mb, Mc = m - Yvdot, m * xg - Yrdot
        Md, Me = m * xg - Nvdot, p["Iz"] - Nrdot
        det = Mb * Me - Mc * Md
        i_mu, i_e, i_c, i_b, i_d = 1.0 / mu, Me / det, Mc / det, Mb / det, Md / det
        absf = np.abs

        def f(u, v, r, tau):
            a = ca * r + cy * v - cr * r
            b = mu * u
            # rhs = tau - C(nu)nu - D(nu)nu  (component forms of diffship's Fossen3)
            r0 = tau[0] + a * r + (Xu + Xuu * absf(u)) * u
            r1 = tau[1] - b * r + (Yv + Yvv * absf(v)) * v + Yr * r
            r2 = tau[2] - (a * u - b * v) + Nv * v + (Nr + Nrr * absf(r)) * r
            return r0 * i_mu, i_e * r1 - i_c * r2, i_b * r2 - i_d * r1

        psi, u, v, r = (x0[:, i].copy() for i in (self.i_psi, self.i_u, self.i_v, self.i_r))
        N = self.N
        out = np.empty((N, 4, self.R))
        out[0] = psi, u, v, r
        ua, ub, uc = self.u_a, self.u_b, self.u_c
        hs = self.h_uniform
        with np.errstate(all="ignore"):
            for k in range(N - 1):
                h = hs if hs is not None else self.h[:, k]
                hh = 0.5 * h
                du1, dv1, dr1 = f(u, v, r, ua[k])
                u2, v2, r2 = u + hh * du1, v + hh * dv1, r + hh * dr1
                du2, dv2, dr2 = f(u2, v2, r2, ub[k])
                u3, v3, r3 = u + hh * du2, v + hh * dv2, r + hh * dr2
                du3, dv3, dr3 = f(u3, v3, r3, ub[k])
                u4, v4, r4 = u + h * du3, v + h * dv3, r + h * dr3
                du4, dv4, dr4 = f(u4, v4, r4, uc[k])
                h6 = h / 6.0
                psi = psi + h6 * (r + 2.0 * r2 + 2.0 * r3 + r4)  # psi_dot = r
                u = u + h6 * (du1 + 2.0 * du2 + 2.0 * du3 + du4)
                v = v + h6 * (dv1 + 2.0 * dv2 + 2.0 * dv3 + dv4)
                r = r + h6 * (dr1 + 2.0 * dr2 + 2.0 * dr3 + dr4)
                out[k + 1, 0] = psi
                out[k + 1, 1] = u
                out[k + 1, 2] = v
                out[k + 1, 3] = r
            ok = np.all(np.isfinite(out) & (np.abs(out) < MAX_ABS), axis=1)  # (N, R)
        # diffship freezes the state at the first blow-up and marks every later sample invalid
        valid = np.cumprod(ok, axis=0).astype(bool)
        return out, valid


class _TimeUp(Exception):
    pass


def scipy_fit(residuals, z0, *, guard_s: float, max_nfev: int = 200, target_cost: float | None = None):
    """``least_squares(method="lm")`` with a wall-clock guard.

    Returns a dict: z, cost, wall, calls (every residual evaluation, finite differences
    included), finished, status, t_target (seconds until the best cost seen first came within
    1 % of ``target_cost``; None if never).
    """
    best = {"cost": math.inf, "z": np.array(z0, dtype=np.float64)}
    info = {"calls": 0, "t_target": None}
    t0 = time.perf_counter()

    def fun(z):
        if time.perf_counter() - t0 > guard_s:
            raise _TimeUp
        r = residuals(z)
        info["calls"] += 1
        c = 0.5 * float(r @ r)
        if c < best["cost"]:
            best.update(cost=c, z=np.array(z, copy=True))
            if target_cost is not None and info["t_target"] is None and c <= 1.01 * target_cost:
                info["t_target"] = time.perf_counter() - t0
        return r

    try:
        res = least_squares(fun, z0, method="lm", max_nfev=max_nfev)
        z, cost, finished = res.x, float(res.cost), res.status > 0
        status = res.message if finished else f"max_nfev={max_nfev} reached"
    except _TimeUp:
        z, cost, finished = best["z"], best["cost"], False
        status = f"stopped by the {guard_s:.0f} s wall-clock guard (best cost seen)"
    return dict(z=z, cost=cost, wall=time.perf_counter() - t0, calls=info["calls"], finished=finished,
                status=status, t_target=info["t_target"])


# -- equation error peers (NumPy OLS / STLSQ) ----------------------------------------------------------
def nomoto_ols(r, rdot, delta):
    r"""Seed 001's regression :math:`\dot r = a r + b\delta + c` by ``lstsq``; returns K, T1, delta0."""
    A = np.stack([r, delta, np.ones_like(r)], 1)
    (a, b, c), *_ = np.linalg.lstsq(A, rdot, rcond=None)
    T = -1.0 / a
    return {"K": b * T, "T1": T, "delta0": c / b}


def stlsq(theta: np.ndarray, y: np.ndarray, threshold: float, max_iter: int = 10, normalize: bool = True):
    """Sequentially thresholded least squares: ``y ≈ theta @ xi`` with small coefficients zeroed.

    Columns are normalised to unit RMS before thresholding (so ``threshold`` is relative to the
    size of each term's contribution), as pysindy does with ``normalize_columns=True``.
    """
    norms = np.sqrt(np.mean(theta**2, axis=0)) if normalize else np.ones(theta.shape[1])
    norms = np.where(norms > 0, norms, 1.0)
    th = theta / norms
    xi, *_ = np.linalg.lstsq(th, y, rcond=None)
    for _ in range(max_iter):
        small = np.abs(xi) < threshold * np.max(np.abs(xi))
        if not np.any(small):
            break
        xi[small] = 0.0
        big = ~small
        xi[big], *_ = np.linalg.lstsq(th[:, big], y, rcond=None)
    return xi / norms


def fossen3_design(m, Iz, xg, z, zd, tau):
    r"""Inverse dynamics of :class:`diffship.models.Fossen3` as ``e = A θ + b`` (3 equations per sample).

    θ = (Xudot, Yvdot, Nrdot, Xu, Yv, Nv, Nr, Xuu, Yvv, Nrr) with Yrdot = Nvdot = Yr = 0:

    * X: :math:`m\dot u - m(x_g r + v)r - \tau_X - X_{\dot u}\dot u + Y_{\dot v} vr - X_u u - X_{|u|u}|u|u`
    * Y: :math:`m\dot v + m x_g\dot r + m u r - \tau_Y - Y_{\dot v}\dot v - X_{\dot u} u r - Y_v v - Y_{|v|v}|v|v`
    * N: :math:`m x_g\dot v + I_z\dot r + m x_g u r - \tau_N - N_{\dot r}\dot r + (X_{\dot u} - Y_{\dot v}) uv
      - N_v v - N_r r - N_{|r|r}|r|r`
    """
    u, v, r = z.T
    ud, vd, rd = zd.T
    n = u.size
    o = np.zeros(n)
    AX = np.stack([-ud, v * r, o, -u, o, o, o, -np.abs(u) * u, o, o], 1)
    AY = np.stack([-u * r, -vd, o, o, -v, o, o, o, -np.abs(v) * v, o], 1)
    AN = np.stack([u * v, -u * v, -rd, o, o, -v, -r, o, o, -np.abs(r) * r], 1)
    bX = m * ud - m * (xg * r + v) * r - tau[:, 0]
    bY = m * vd + m * xg * rd + m * u * r - tau[:, 1]
    bN = m * xg * vd + Iz * rd + m * xg * u * r - tau[:, 2]
    return (AX, AY, AN), (bX, bY, bN)


FOSSEN3_THETA = ("Xudot", "Yvdot", "Nrdot", "Xu", "Yv", "Nv", "Nr", "Xuu", "Yvv", "Nrr")


def fossen3_ols(m, Iz, xg, z, zd, tau):
    """Unweighted OLS on the stacked inverse-dynamics equations, each divided by the RMS of its
    known side (so N and N·m rows are comparable): ``lstsq`` once, no iteration."""
    (AX, AY, AN), (bX, bY, bN) = fossen3_design(m, Iz, xg, z, zd, tau)
    rows, rhs = [], []
    for A, b in ((AX, bX), (AY, bY), (AN, bN)):
        s = np.sqrt(np.mean(b**2)) or 1.0
        rows.append(A / s)
        rhs.append(-b / s)
    theta, *_ = np.linalg.lstsq(np.concatenate(rows), np.concatenate(rhs), rcond=None)
    return dict(zip(FOSSEN3_THETA, map(float, theta)))
