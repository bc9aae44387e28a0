"""The CasADi peer: diffship's Fossen 3-DOF output-error problem written with CasADi, solved by MINPACK.

This is what a speed-minded user would write without diffship: the model with CasADi symbols,
RK4 on the sample grid chained with ``mapaccum``, the residual and its exact Jacobian from
CasADi (compiled to C by CasADi's JIT, or interpreted by CasADi's virtual machine), handed to
:func:`scipy.optimize.least_squares` with ``method="lm"`` (MINPACK ``lmder``).

It solves **diffship's residual exactly** (``benchmarks/timing/cold.py`` checks it against
``Kernel.residuals``):

* model: :class:`diffship.models.Fossen3` — ``M ν̇ = τ − C(ν)ν − D(ν)ν`` in the component forms
  of ``Fossen3.coriolis_vector`` / ``damping_vector``, the closed-form 3×3 mass solve, and the
  kinematics ``ẋ0 = u cosψ − v sinψ, ẏ0 = u sinψ + v cosψ, ψ̇ = r`` (all six states);
* RK4 with one step per sample and first-order-hold inputs (diffship's ``RK4(substeps=1)``):
  k1 at ``(t, x, u_k)``, k2, k3 at the midpoint with ``(u_k + u_{k+1})/2``, k4 at ``t + h`` with
  ``u_{k+1}``;
* residual ``e_ikc = (ŷ_c(t_ik) − y_ikc)/s_c`` flattened in (run, sample, channel) order,
  heading error wrapped with ``atan2(sin, cos)``, ``s_c`` the channel spread (diffship's
  ``weights="spread"``), heading measurements unwrapped; after a blow-up (a state non-finite or
  beyond 1e8) every later sample gets diffship's penalty 1e3 (Jacobian row 0);
* unknowns ``z = (z_θ, d)``: the free parameters in diffship's scaled space
  (``θ = upper − s·exp(z)`` for the parameters bounded above by 0, ``θ = s·z`` for ``Nv``;
  ``exp`` argument clipped to ±50 as ``ParamSpec.from_z``), then per-run offsets of the initial
  ψ, u, v, r in units of the channel spreads (``x0 = first samples + s·d``);
* the problem is read from the same CSV files the diffship CLI reads (``Run.to_dataframe().to_csv``),
  with pandas, as a user would; the parameter declarations below mirror ``Fossen3.spec()``
  (checked by ``timing/cold.py``).

Tolerances (the same for every MINPACK peer of ``benchmarks/timing``): ``ftol=1e-9`` (diffship's
stall test: relative cost decrease), ``xtol=1e-6`` (diffship's ``rtol`` on the scaled unknowns),
``gtol=1e-8`` (scipy's default), ``max_nfev=200`` (diffship's ``max_steps``).

Command line (the whole-process measurements of ``benchmarks/timing``)::

    python benchmarks/common/casadi_peer.py RUN1.csv RUN2.csv --init Xudot=-200 ... [--mode jit|nojit|cache] [--json OUT]

It needs only numpy, scipy, pandas and casadi (``pip install -e ".[bench]"``), not diffship.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

T_START = time.perf_counter()

import casadi as ca  # noqa: E402
import pandas as pd  # noqa: E402
from scipy.optimize import least_squares  # noqa: E402

__all__ = ["MODES", "PARAMS", "STATES", "INPUTS", "CHANNELS", "TOL", "Problem", "CasadiFossen3", "load_problem",
           "solve_lm", "main"]

# kind of a parameter's scaled space (diffship.params): 0 linear, 1 lower bound, 2 upper bound
LINEAR, LOWER, UPPER = 0, 1, 2
# name: (default value, free, kind, bound, scale) -- the Fossen3 declarations (seed-002 USV standard model)
PARAMS: dict[str, tuple[float, bool, int, float, float]] = {
    "m": (4935.14, False, LOWER, 0.0, 5e3),
    "Iz": (20928.0, False, LOWER, 0.0, 2e4),
    "xg": (0.0, False, LINEAR, 0.0, 1.0),
    "Xudot": (0.0, True, UPPER, 0.0, 500.0),
    "Yvdot": (0.0, True, UPPER, 0.0, 2e3),
    "Yrdot": (0.0, False, LINEAR, 0.0, 2e3),
    "Nvdot": (0.0, False, LINEAR, 0.0, 2e3),
    "Nrdot": (0.0, True, UPPER, 0.0, 1e4),
    "Xu": (-50.0, True, UPPER, 0.0, 50.0),
    "Yv": (-200.0, True, UPPER, 0.0, 200.0),
    "Yr": (0.0, False, LINEAR, 0.0, 500.0),
    "Nv": (1281.0, True, LINEAR, 0.0, 1e3),
    "Nr": (-1281.0, True, UPPER, 0.0, 1e3),
    "Xuu": (-243.0, True, UPPER, 0.0, 200.0),
    "Yvv": (-2000.0, True, UPPER, 0.0, 2e3),
    "Nrr": (-3594.38, True, UPPER, 0.0, 3e3),
}
PARAM_NAMES = tuple(PARAMS)
FREE = tuple(n for n, p in PARAMS.items() if p[1])
STATES = ("x0", "y0", "psi", "u", "v", "r")
INPUTS = ("tau_x", "tau_y", "tau_z")
CHANNELS = ("psi", "u", "v", "r")
PENALTY = 1e3  # diffship.fit.kernel.PENALTY
MAX_ABS = 1e8  # diffship.simulate.MAX_ABS
TOL = dict(ftol=1e-9, xtol=1e-6, gtol=1e-8, max_nfev=200)


# -- the problem, from CSV files --------------------------------------------------------------------
class Problem:
    """Stacked runs (equal lengths): ``ts (R, N)``, ``us (R, N, 3)``, ``ys (R, N, C)``, ``x0 (R, 6)``,
    channel spreads ``scales (C,)``, offset scales ``x0_scale (C,)``, base parameter values."""

    def __init__(self, ts, us, ys, x0, scales, theta0):
        self.ts, self.us, self.ys, self.x0 = ts, us, ys, x0
        self.scales = np.asarray(scales, dtype=np.float64)
        self.x0_scale = self.scales.copy()  # the estimated states are the fitted channels
        self.theta0 = np.asarray(theta0, dtype=np.float64)
        self.R, self.N = ts.shape
        self.x0_idx = [STATES.index(c) for c in CHANNELS]
        self.n_theta = len(FREE)
        self.n_z = self.n_theta + self.R * len(CHANNELS)

    def to_z(self, values: dict) -> np.ndarray:
        """Scaled vector of the free parameters (as ``ParamSpec.to_z``), offsets zero."""
        out = []
        for n in FREE:
            _, _, kind, bound, s = PARAMS[n]
            v = float(values[n])
            out.append(v / s if kind == LINEAR else math.log((v - bound) / s) if kind == LOWER
                       else math.log((bound - v) / s))
        return np.concatenate([out, np.zeros(self.n_z - self.n_theta)])

    def params(self, z) -> dict:
        """All parameter values at ``z`` (NumPy version of the CasADi transform)."""
        vals = dict(zip(PARAM_NAMES, self.theta0))
        for n, zi in zip(FREE, np.asarray(z)[: self.n_theta]):
            _, _, kind, bound, s = PARAMS[n]
            e = math.exp(min(max(zi, -50.0), 50.0))
            vals[n] = s * zi if kind == LINEAR else bound + s * e if kind == LOWER else bound - s * e
        return vals

    def initial_states(self, z) -> np.ndarray:
        x0 = self.x0.copy()
        x0[:, self.x0_idx] += np.asarray(z)[self.n_theta:].reshape(self.R, -1) * self.x0_scale
        return x0


def channel_spread(ys: np.ndarray) -> np.ndarray:
    """Standard deviation of each channel over all samples, floored (diffship's ``channel_spread``)."""
    out = []
    for j in range(ys.shape[-1]):
        v = ys[..., j].reshape(-1)
        out.append(max(float(np.std(v)), 1e-3 * float(np.max(np.abs(v)) + 1e-12), 1e-9))
    return np.asarray(out)


def load_problem(paths, init: dict | None = None) -> Problem:
    """Read the runs (CSV with columns time, x0, y0, psi, u, v, r, tau_x, tau_y, tau_z)."""
    frames = [pd.read_csv(p) for p in paths]
    n = {len(f) for f in frames}
    if len(n) != 1:
        raise ValueError("this peer stacks runs of equal length only")
    ts = np.stack([f["time"].to_numpy(np.float64) for f in frames])
    us = np.stack([f[list(INPUTS)].to_numpy(np.float64) for f in frames])
    ys = []
    for f in frames:
        cols = [np.unwrap(f[c].to_numpy(np.float64)) if c == "psi" else f[c].to_numpy(np.float64) for c in CHANNELS]
        ys.append(np.stack(cols, axis=1))
    ys = np.stack(ys)
    x0 = np.stack([[np.unwrap(f[s].to_numpy(np.float64))[0] if s == "psi" else float(f[s].iloc[0]) for s in STATES]
                   for f in frames])
    theta0 = np.array([PARAMS[k][0] for k in PARAM_NAMES])
    for k, v in (init or {}).items():
        theta0[PARAM_NAMES.index(k)] = v
    return Problem(ts, us, ys, x0, channel_spread(ys), theta0)


# -- the model and the residual in CasADi ---------------------------------------------------------------
def vector_field(x, tau, th):
    """Fossen3.vector_field with CasADi symbols: x = (x0, y0, psi, u, v, r), tau = (τx, τy, τz)."""
    p = dict(zip(PARAM_NAMES, [th[i] for i in range(len(PARAM_NAMES))]))
    psi, u, v, r = x[2], x[3], x[4], x[5]
    m, xg = p["m"], p["xg"]
    # C(ν)ν and D(ν)ν, component forms (Fossen3.coriolis_vector, Fossen3.damping_vector)
    a = m * (xg * r + v) - p["Yvdot"] * v - 0.5 * (p["Nvdot"] + p["Yrdot"]) * r
    b = (m - p["Xudot"]) * u
    c0, c1, c2 = -a * r, b * r, a * u - b * v
    d0 = -((p["Xu"] + p["Xuu"] * ca.fabs(u)) * u)
    d1 = -((p["Yv"] + p["Yvv"] * ca.fabs(v)) * v + p["Yr"] * r)
    d2 = -(p["Nv"] * v + (p["Nr"] + p["Nrr"] * ca.fabs(r)) * r)
    rhs0, rhs1, rhs2 = tau[0] - c0 - d0, tau[1] - c1 - d1, tau[2] - c2 - d2
    # M⁻¹ rhs in closed form (diffship.models._rigid3.solve_mass3)
    mx = m * xg
    Ma, Mb, Mc, Md, Me = m - p["Xudot"], m - p["Yvdot"], mx - p["Yrdot"], mx - p["Nvdot"], p["Iz"] - p["Nrdot"]
    det = Mb * Me - Mc * Md
    cs, sn = ca.cos(psi), ca.sin(psi)
    return ca.vertcat(cs * u - sn * v, sn * u + cs * v, r, rhs0 / Ma, (Me * rhs1 - Mc * rhs2) / det,
                      (Mb * rhs2 - Md * rhs1) / det)


def rk4_step() -> ca.Function:
    """One RK4 step over a sample interval with first-order-hold inputs (diffship's RK4())."""
    x = ca.SX.sym("x", len(STATES))
    ua, uc = ca.SX.sym("ua", 3), ca.SX.sym("uc", 3)
    th = ca.SX.sym("th", len(PARAM_NAMES))
    h = ca.SX.sym("h")
    ub = 0.5 * (ua + uc)
    k1 = vector_field(x, ua, th)
    k2 = vector_field(x + 0.5 * h * k1, ub, th)
    k3 = vector_field(x + 0.5 * h * k2, ub, th)
    k4 = vector_field(x + h * k3, uc, th)
    xn = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return ca.Function("rk4", [x, ua, uc, th, h], [xn])


MODES = ("jit", "nojit", "cache")


class CasadiFossen3:
    """Residual and exact Jacobian of the output-error problem as CasADi functions.

    ``mode``:

    * ``"jit"`` — CasADi's JIT: C code generated and compiled by gcc (``flags``) in every process;
    * ``"nojit"`` — CasADi's virtual machine (no compiler);
    * ``"cache"`` — the same C code generated once, compiled by gcc into ``cache_dir`` and loaded
      with :func:`casadi.external`; a later process with the same shapes only loads the library
      (CasADi's counterpart of diffship's persistent compilation cache; not part of CasADi's
      JIT, a user writes these few lines).

    The functions take the data as inputs (nothing is baked into the code), so one build serves
    any runs of the same shape, as diffship's compiled programs do.
    """

    def __init__(self, prob: Problem, mode: str = "jit", flags=("-O2",), cache_dir=None):
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}")
        t0 = time.perf_counter()
        self.prob, self.mode = prob, mode
        self.loaded_from_cache = False
        R, N = prob.R, prob.N
        key = f"casadi_fossen3_R{R}_N{N}_{ca.__version__.replace('.', '_')}_{'_'.join(f.strip('-') for f in flags)}"
        so = None if cache_dir is None else os.path.join(cache_dir, key + ".so")
        if mode == "cache" and so is not None and os.path.isfile(so):
            self.f_res, self.f_jac = ca.external("res", so), ca.external("res_jac", so)
            self.loaded_from_cache = True
        else:
            inputs, names, e, X, J = self._graph()
            opts = {}
            if mode == "jit":
                opts = {"jit": True, "compiler": "shell", "jit_cleanup": True,
                        "jit_options": {"flags": list(flags), "verbose": False}}
            self.f_res = ca.Function("res", inputs, [e, X], names, ["e", "X"], opts)
            self.f_jac = ca.Function("res_jac", inputs, [e, X, J], names, ["e", "X", "J"], opts)
            if mode == "cache":
                if cache_dir is None:
                    raise ValueError("mode 'cache' needs cache_dir")
                os.makedirs(cache_dir, exist_ok=True)
                tmp = tempfile.mkdtemp(dir=cache_dir)
                cg = ca.CodeGenerator(key + ".c", {"with_header": False})
                cg.add(self.f_res)
                cg.add(self.f_jac)
                cg.generate(tmp + os.sep)
                subprocess.run(["gcc", *flags, "-fPIC", "-shared", os.path.join(tmp, key + ".c"), "-o",
                                os.path.join(tmp, key + ".so"), "-lm"], check=True)
                os.replace(os.path.join(tmp, key + ".so"), so)
                shutil.rmtree(tmp, ignore_errors=True)
                self.f_res, self.f_jac = ca.external("res", so), ca.external("res_jac", so)
        self.data = [prob.theta0, prob.x0.T, prob.scales, *[prob.us[i].T for i in range(R)],
                     *[prob.ys[i].T for i in range(R)], *[np.diff(prob.ts[i])[None, :] for i in range(R)]]
        self.build_seconds = time.perf_counter() - t0
        # the first evaluations load / finish the compiled code: part of setup
        t1 = time.perf_counter()
        z0 = np.zeros(prob.n_z)
        self.f_res(z0, *self.data)
        self.f_jac(z0, *self.data)
        self.first_call_seconds = time.perf_counter() - t1
        self.setup_seconds = time.perf_counter() - t0
        self.n_res = self.n_jac = 0

    @property
    def jit(self) -> bool:
        return self.mode != "nojit"

    def _graph(self):
        """The MX graph: inputs, their names, residuals e, states X and the Jacobian de/dz."""
        prob = self.prob
        R, N, C = prob.R, prob.N, len(CHANNELS)
        sim = rk4_step().mapaccum("sim", N - 1)
        z = ca.MX.sym("z", prob.n_z)
        theta0 = ca.MX.sym("theta0", len(PARAM_NAMES))
        U = [ca.MX.sym(f"U{i}", 3, N) for i in range(R)]  # inputs (rows τ), columns samples
        Y = [ca.MX.sym(f"Y{i}", C, N) for i in range(R)]  # measured channels
        H = [ca.MX.sym(f"H{i}", 1, N - 1) for i in range(R)]  # step lengths
        X0 = ca.MX.sym("X0", len(STATES), R)  # initial states before the offsets
        scales = ca.MX.sym("scales", C)
        # θ(z): fixed entries from theta0, free entries through diffship's scaled transform
        zc = ca.fmin(ca.fmax(z, -50.0), 50.0)
        entries = []
        for name in PARAM_NAMES:
            _, free, kind, bound, s = PARAMS[name]
            if not free:
                entries.append(theta0[PARAM_NAMES.index(name)])
                continue
            i = FREE.index(name)
            entries.append(s * z[i] if kind == LINEAR else bound + s * ca.exp(zc[i]) if kind == LOWER
                           else bound - s * ca.exp(zc[i]))
        theta = ca.vertcat(*entries)
        out_rows = [STATES.index(c) for c in CHANNELS]
        i_psi = CHANNELS.index("psi")
        es, xs = [], []
        for i in range(R):
            d = z[prob.n_theta + i * C: prob.n_theta + (i + 1) * C]
            x0_parts = [X0[k, i] for k in range(len(STATES))]
            for j, k in enumerate(prob.x0_idx):
                x0_parts[k] = x0_parts[k] + d[j] * scales[j]  # x0_scale = the channel spreads
            x0 = ca.vertcat(*x0_parts)
            X = ca.horzcat(x0, sim(x0, U[i][:, :-1], U[i][:, 1:], theta, H[i]))  # (6, N)
            err = X[out_rows, :] - Y[i]
            rows = [err[j, :] for j in range(C)]
            rows[i_psi] = ca.atan2(ca.sin(rows[i_psi]), ca.cos(rows[i_psi]))
            e = ca.vertcat(*[rows[j] / scales[j] for j in range(C)])  # (C, N)
            es.append(ca.vec(e))  # column-major: channel fastest, then sample
            xs.append(X)
        e = ca.vertcat(*es)
        X = ca.horzcat(*xs)  # (6, R*N)
        J = ca.jacobian(e, z)
        inputs = [z, theta0, X0, scales, *U, *Y, *H]
        names = ["z", "theta0", "X0", "scales", *[f"U{i}" for i in range(R)], *[f"Y{i}" for i in range(R)],
                 *[f"H{i}" for i in range(R)]]
        return inputs, names, e, X, J

    # -- NumPy in, NumPy out, with diffship's blow-up penalty --------------------------------------
    def _valid(self, X):
        """(R·N,) flags: False from the first sample at which a state is non-finite or beyond 1e8."""
        R, N = self.prob.R, self.prob.N
        ok = np.all(np.isfinite(X) & (np.abs(X) < MAX_ABS), axis=0).reshape(R, N)
        return np.cumprod(ok, axis=1).astype(bool).reshape(-1)

    def residuals(self, z) -> np.ndarray:
        self.n_res += 1
        e, X = self.f_res(z, *self.data)
        e, X = np.asarray(e).reshape(-1), np.asarray(X)
        valid = self._valid(X)
        if not valid.all():
            e = np.where(np.repeat(valid, len(CHANNELS)), e, PENALTY)
        return e

    def residuals_and_jacobian(self, z):
        self.n_jac += 1
        e, X, J = self.f_jac(z, *self.data)
        e, X, J = np.asarray(e).reshape(-1), np.asarray(X), np.asarray(J)
        valid = self._valid(X)
        if not valid.all():
            bad = ~np.repeat(valid, len(CHANNELS))
            e = np.where(bad, PENALTY, e)
            J = np.where(bad[:, None], 0.0, J)
        return e, J

    def jacobian(self, z) -> np.ndarray:
        return self.residuals_and_jacobian(z)[1]


def solve_lm(peer: CasadiFossen3, z0, **tol):
    """MINPACK LM (``least_squares(method="lm")``) with CasADi's residual and exact Jacobian."""
    kw = {**TOL, **tol}
    peer.n_res = peer.n_jac = 0
    t0 = time.perf_counter()
    res = least_squares(peer.residuals, np.asarray(z0, dtype=np.float64), jac=peer.jacobian, method="lm", **kw)
    wall = time.perf_counter() - t0
    return dict(z=res.x, cost=float(res.cost), nfev=int(res.nfev), njev=int(res.njev or 0), status=int(res.status),
                message=res.message, wall=wall, converged=res.status > 0)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", metavar="RUN.csv")
    ap.add_argument("--init", nargs="*", default=[], metavar="NAME=VALUE", help="start values (and fixed values)")
    ap.add_argument("--mode", default="jit", choices=MODES,
                    help="jit: CasADi JIT (gcc) in this process; nojit: CasADi's virtual machine; cache: C code "
                         "compiled once into --cache-dir and loaded with casadi.external")
    ap.add_argument("--cache-dir", default=None, metavar="DIR", help="folder of the compiled code (--mode cache)")
    ap.add_argument("--json", default=None, metavar="FILE", help="write the results as JSON")
    ap.add_argument("--starts", default=None, metavar="FILE.npy",
                    help="solve from each row of this (B, n_z) array of scaled starts instead of --init's start, "
                         "and write the final costs to --costs (a batch of fits, looped)")
    ap.add_argument("--costs", default=None, metavar="FILE.npy", help="where --starts writes the final costs")
    args = ap.parse_args(argv)
    t_import = time.perf_counter() - T_START
    init = {k: float(v) for k, v in (a.split("=", 1) for a in args.init)}
    t = time.perf_counter()
    prob = load_problem(args.runs, init)
    t_load = time.perf_counter() - t
    peer = CasadiFossen3(prob, mode=args.mode, cache_dir=args.cache_dir)
    if args.starts:
        costs = np.array([solve_lm(peer, z)["cost"] for z in np.load(args.starts)])
        np.save(args.costs, costs)
        return 0
    z0 = prob.to_z(dict(zip(PARAM_NAMES, prob.theta0)))  # the spec's values with --init
    sol = solve_lm(peer, z0)
    params = prob.params(sol["z"])
    doc = dict(mode=peer.mode, loaded_from_cache=peer.loaded_from_cache, import_s=t_import, load_s=t_load,
               build_s=peer.build_seconds, first_call_s=peer.first_call_seconds, setup_s=peer.setup_seconds,
               solve_s=sol["wall"],
               cost=sol["cost"], nfev=sol["nfev"], njev=sol["njev"], status=sol["status"], message=sol["message"],
               params={n: params[n] for n in FREE}, z=list(map(float, sol["z"])),
               in_process_s=time.perf_counter() - T_START)
    print(f"casadi ({peer.mode}{', loaded' if peer.loaded_from_cache else ''}): setup {peer.setup_seconds:.2f} s, "
          f"solve {sol['wall']:.2f} s, "
          f"cost {sol['cost']:.10g}, {sol['nfev']} f-evals, {sol['njev']} Jacobians: {sol['message']}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(doc, fh, indent=2)
    return 0 if sol["converged"] else 1


if __name__ == "__main__":
    sys.exit(main())
