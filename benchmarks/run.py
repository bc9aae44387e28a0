"""diffship benchmark suite: output error vs equation error vs the tools users would pick instead.

One command (from the repository root)::

    PYTHONPATH=src .venv/bin/python benchmarks/run.py [--quick] [--out benchmarks/results]

writes ``OUT/report.md`` (headline table first), ``OUT/all_numbers.csv`` (every number, long
format: case, variant, method, metric, value, unit, note) and ``OUT/fig_*.png``. ``--quick``
(CI size, a few minutes) writes ``report_quick.md`` / ``all_numbers_quick.csv`` /
``fig_quick_*.png`` so that it never overwrites the full results. ``--cases`` runs a subset.
See ``benchmarks/README.md`` for what is measured and how.
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import platform
import resource
import sys
import time
import tracemalloc
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import scipy  # noqa: E402

import diffship  # noqa: E402,F401  (enables float64)
from diffship.fit import fit_equation_error, fit_output_error  # noqa: E402
from diffship.fit.output_error import _Problem, channel_spread  # noqa: E402
from diffship.fit.problem import make_batch  # noqa: E402
from diffship.metrics import evaluate  # noqa: E402
from diffship.models import Fossen3, Nomoto1  # noqa: E402
from diffship.preprocess import Filter, smooth_and_derivative  # noqa: E402

import _peers  # noqa: E402
from _cases import NomotoCubic, nomoto_case_runs  # noqa: E402

FLT_NONE = Filter("none")
NOMOTO_TRUTH = dict(K=0.2, T1=8.0, delta0=0.01)
CUBIC_TRUTH = dict(K=0.2, T1=8.0, a=50.0, delta0=0.01)
STLSQ_THRESHOLD = 0.02  # relative, on unit-RMS columns; 0.05 already drops the r³ and δ0 terms of the truth
#: identical methods overlap (OE = scipy at equal cost, EE = OLS for Nomoto): different line styles keep both visible
STYLE = {"diffship_oe": dict(marker="o", ls="-", ms=7), "scipy_lm_numpy_rk4": dict(marker="x", ls="--", ms=9),
         "diffship_ee": dict(marker="s", ls="-", ms=7, mfc="none"), "numpy_ols": dict(marker="+", ls=":", ms=10),
         "stlsq_sindy": dict(marker="^", ls="-.", ms=6)}
METHODS = ("diffship_oe", "diffship_ee", "scipy_lm_numpy_rk4", "numpy_ols", "stlsq_sindy")
LABEL = {"diffship_oe": "diffship output error", "diffship_ee": "diffship equation error",
         "scipy_lm_numpy_rk4": "scipy least_squares + NumPy RK4", "numpy_ols": "NumPy OLS (inverse dynamics)",
         "stlsq_sindy": "STLSQ sparse regression (SINDy)"}


# -- recording --------------------------------------------------------------------------------------------
class Recorder:
    def __init__(self):
        self.rows: list[dict] = []

    def add(self, case, variant, method, metric, value, unit="", note=""):
        if isinstance(value, (bool, np.bool_)):
            value = int(bool(value))
        self.rows.append(dict(case=case, variant=variant, method=method, metric=metric,
                              value=float(value) if value is not None else math.nan, unit=unit, note=note))

    def get(self, case, variant, method, metric, default=math.nan):
        for r in reversed(self.rows):
            if (r["case"], r["variant"], r["method"], r["metric"]) == (case, variant, method, metric):
                return r["value"]
        return default

    def write_csv(self, path):
        with open(path, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=["case", "variant", "method", "metric", "value", "unit", "note"])
            w.writeheader()
            for r in self.rows:
                w.writerow({**r, "value": f"{r['value']:.8g}"})


def maxrss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: kB


def say(msg):
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", flush=True)


def rel_errs(params, truth, names):
    return {n: abs(params[n] - truth[n]) / abs(truth[n]) for n in names if n in truth and truth[n] != 0}


def _zig_unit(key):
    return "deg" if key.startswith("err_overshoot") else ""


def record_common(rec, case, variant, method, model, val_runs, truth=None, names=(), zig=None):
    """Parameter error, validation NRMSE per channel, manoeuvre metric errors."""
    if truth is not None and names:
        errs = rel_errs(model.param_values(), truth, names)
        for n, e in errs.items():
            rec.add(case, variant, method, f"rel_err_{n}", e)
        rec.add(case, variant, method, "max_rel_param_err", max(errs.values()))
        rec.add(case, variant, method, "rms_rel_param_err", float(np.sqrt(np.mean(np.square(list(errs.values()))))))
    if val_runs:
        try:
            ev = evaluate(model, val_runs)
            for c in ev.channels:
                f = ev.fit_percent[c]
                rec.add(case, variant, method, f"val_nrmse_{c}", 1.0 - f / 100.0 if ev.ok else math.nan,
                        note="" if ev.ok else "validation simulation blew up")
        except Exception as exc:  # a peer's model may blow up on validation
            rec.add(case, variant, method, "val_nrmse_failed", 1.0, note=str(exc)[:120])
    if zig is not None:
        for key, val in zig(model).items():
            rec.add(case, variant, method, key, val, _zig_unit(key))


def nomoto_zigzag_errors(truth_model):
    """Errors of the 10/10 and 20/20 zigzag overshoots of a model against the truth's [deg]."""
    from diffship.manoeuvres import zigzag, zigzag_metrics

    def metrics(m):
        out = {}
        for a in (10.0, 20.0):
            run = zigzag(m, {"psi": 0.0, "r": 0.0}, rudder_deg=a, duration=150.0, dt=0.2, rudder_rate_deg_s=5.0)
            zm = zigzag_metrics(run)
            out[a] = (zm.first_overshoot, zm.second_overshoot)
        return out

    ref = metrics(truth_model)

    def errors(m):
        try:
            got = metrics(m)
        except Exception:
            return {"zigzag_failed": math.nan}
        out = {}
        for a in ref:
            out[f"err_overshoot1_{a:g}_{a:g}"] = got[a][0] - ref[a][0]
            out[f"err_overshoot2_{a:g}_{a:g}"] = got[a][1] - ref[a][1]
        return out

    return errors


# -- Nomoto family ---------------------------------------------------------------------------------------------
def _nomoto_spec(start):
    return Nomoto1().spec().with_values(start)


def nomoto_methods(rec, case, variant, train, val, truth, truth_model, *, start, methods=METHODS, guard=60.0,
                   zig=None, memory=False, oe_weights="spread"):
    """Fit the linear Nomoto model to ``train`` with every method; record everything."""
    names = ("K", "T1", "delta0")
    spec = _nomoto_spec(start)
    out = {}
    # diffship output error (same problem as the scipy peer: spread weights, raw initial states)
    t = time.perf_counter()
    oe = fit_output_error(Nomoto1(), train, spec=spec, estimate_x0=("psi", "r"), weights=oe_weights, flt=FLT_NONE)
    wall = time.perf_counter() - t
    out["diffship_oe"] = oe
    for k, v, u in (("wall_s", wall, "s"), ("compile_s", oe.compile_seconds, "s"), ("fit_s", oe.fit_seconds, "s"),
                    ("cost", oe.cost, ""), ("iterations", oe.iterations, ""), ("converged", oe.converged, ""),
                    ("process_max_rss_mb", maxrss_mb(), "MB")):
        rec.add(case, variant, "diffship_oe", k, v, u)
    record_common(rec, case, variant, "diffship_oe", oe.model, val, truth, names, zig)
    # diffship equation error
    if "diffship_ee" in methods:
        t = time.perf_counter()
        ee = fit_equation_error(Nomoto1(), train, spec=spec)
        wall = time.perf_counter() - t
        out["diffship_ee"] = ee
        for k, v, u in (("wall_s", wall, "s"), ("compile_s", ee.compile_seconds, "s"), ("fit_s", ee.fit_seconds, "s"),
                        ("process_max_rss_mb", maxrss_mb(), "MB")):
            rec.add(case, variant, "diffship_ee", k, v, u)
        record_common(rec, case, variant, "diffship_ee", ee.model, val, truth, names, zig)
    # scipy least_squares over a NumPy RK4 simulation
    if "scipy_lm_numpy_rk4" in methods:
        batch = make_batch(Nomoto1().with_params(spec.values()), train, ("psi", "r"), FLT_NONE)
        prob = _peers.NomotoProblem(spec, batch, channel_spread(batch))
        z0 = np.concatenate([spec.to_z(), np.zeros(2 * len(train))])
        sp = _peers.scipy_fit(prob.residuals, z0, guard_s=guard, target_cost=oe.cost)
        pv = prob.params(sp["z"])
        out["scipy_lm_numpy_rk4"] = (sp, pv)
        # consistency: NumPy residual at diffship's solution reproduces diffship's cost
        z_ds = np.concatenate([spec.to_z({n: oe.params[n] for n in names}),
                               ((np.stack(oe.initial_states) - batch.x0) / prob.x0_scale).reshape(-1)])
        c_chk = 0.5 * float(np.sum(prob.residuals(z_ds) ** 2))
        rec.add(case, variant, "scipy_lm_numpy_rk4", "cost_check_rel_diff", abs(c_chk - oe.cost) / max(oe.cost, 1e-300),
                note="NumPy residual at diffship's OE solution vs diffship's cost")
        for k, v, u in (("wall_s", sp["wall"], "s"), ("compile_s", 0.0, "s"), ("fit_s", sp["wall"], "s"),
                        ("cost", sp["cost"], ""), ("f_evals", sp["calls"], ""), ("converged", sp["finished"], ""),
                        ("time_to_oe_cost_s", sp["t_target"] if sp["t_target"] is not None else math.nan, "s")):
            rec.add(case, variant, "scipy_lm_numpy_rk4", k, v, u)
        if memory:
            tracemalloc.start()
            _peers.scipy_fit(prob.residuals, z0, guard_s=guard, max_nfev=1)
            rec.add(case, variant, "scipy_lm_numpy_rk4", "tracemalloc_peak_mb", tracemalloc.get_traced_memory()[1] / 2**20,
                    "MB", "tracemalloc, one LM iteration (one FD Jacobian): the peak working set")
            tracemalloc.stop()
        record_common(rec, case, variant, "scipy_lm_numpy_rk4", Nomoto1().with_params(pv), val, truth, names, zig)
    # NumPy OLS and STLSQ on the same filtered derivatives as diffship's equation error
    if "numpy_ols" in methods or "stlsq_sindy" in methods:
        t = time.perf_counter()
        R, RD, D = [], [], []
        for run in train:
            r, rd = smooth_and_derivative(run.time, np.asarray(run["r"]), Filter())
            k = int(0.02 * r.size)
            R.append(r[k:r.size - k]); RD.append(rd[k:r.size - k]); D.append(np.asarray(run["delta"])[k:r.size - k])
        R, RD, D = (np.concatenate(a) for a in (R, RD, D))
        t_deriv = time.perf_counter() - t
        if "numpy_ols" in methods:
            tracemalloc.start()
            t = time.perf_counter()
            pv = _peers.nomoto_ols(R, RD, D)
            wall = time.perf_counter() - t + t_deriv
            rec.add(case, variant, "numpy_ols", "tracemalloc_peak_mb", tracemalloc.get_traced_memory()[1] / 2**20, "MB",
                    "tracemalloc around the regression")
            tracemalloc.stop()
            out["numpy_ols"] = pv
            rec.add(case, variant, "numpy_ols", "wall_s", wall, "s", "includes filtering/differentiation")
            rec.add(case, variant, "numpy_ols", "compile_s", 0.0, "s")
            if pv["T1"] > 0:
                record_common(rec, case, variant, "numpy_ols", Nomoto1().with_params(pv), val, truth, names, zig)
        if "stlsq_sindy" in methods:
            t = time.perf_counter()
            lib = np.stack([R, R**3, D, np.ones_like(R)], 1)
            xi = _peers.stlsq(lib, RD, threshold=STLSQ_THRESHOLD)
            wall = time.perf_counter() - t + t_deriv
            a1, a3, b, c = xi
            rec.add(case, variant, "stlsq_sindy", "wall_s", wall, "s", "includes filtering/differentiation")
            rec.add(case, variant, "stlsq_sindy", "compile_s", 0.0, "s")
            rec.add(case, variant, "stlsq_sindy", "cubic_term_kept", a3 != 0.0, "", f"library r, r^3, delta, 1; threshold {STLSQ_THRESHOLD}")
            if a1 < 0 and b != 0:
                T = -1.0 / a1
                pv = {"K": b * T, "T1": T, "a": -a3 * T, "delta0": c / b}
                out["stlsq_sindy"] = pv
                mdl = NomotoCubic(**pv)
                record_common(rec, case, variant, "stlsq_sindy", mdl, val, truth, names, None)
                if zig is not None:
                    for key, v in zig(mdl).items():
                        rec.add(case, variant, "stlsq_sindy", key, v, _zig_unit(key))
    return out


def seed_summary(rec, case, variants, methods):
    """Mean and median over noise seeds of the max relative parameter error (variant ``noise=realistic``)."""
    for m in methods:
        v = np.array([rec.get(case, var, m, "max_rel_param_err") for var in variants])
        v = v[np.isfinite(v)]
        if v.size:
            rec.add(case, "noise=realistic", m, "seeds_mean_max_rel_param_err", float(np.mean(v)), "",
                    f"mean over {v.size} noise seeds")
            rec.add(case, "noise=realistic", m, "seeds_median_max_rel_param_err", float(np.median(v)), "",
                    f"median over {v.size} noise seeds")


def seed_stats(rec, case, method):
    """Mean over the ``seed=*`` variants of (max, RMS) relative parameter error; (nan, nan, 0) if none."""
    mx, rms = [], []
    for var in sorted({r["variant"] for r in rec.rows if r["case"] == case and r["variant"].startswith("seed=")}):
        m = rec.get(case, var, method, "max_rel_param_err")
        q = rec.get(case, var, method, "rms_rel_param_err")
        if not math.isfinite(q):
            e = [r["value"] for r in rec.rows if r["case"] == case and r["variant"] == var and r["method"] == method
                 and r["metric"].startswith("rel_err_")]
            q = float(np.sqrt(np.mean(np.square(e)))) if e else math.nan
        if math.isfinite(m) and math.isfinite(q):
            mx.append(m)
            rms.append(q)
    return (float(np.mean(mx)), float(np.mean(rms)), len(mx)) if mx else (math.nan, math.nan, 0)


def log_uniform_starts(truth, names, n, seed):
    rng = np.random.default_rng(seed)
    return [{k: truth[k] * float(np.exp(rng.uniform(np.log(0.3), np.log(3.0)))) for k in names} for _ in range(n)]


def convergence(rec, case, variant, fits: dict[str, list[tuple[float, float]]], best=math.inf):
    """``fits[method] = [(cost, seconds), ...]`` from the same N starts: rate within 1 % of the best cost."""
    best = min([best] + [c for v in fits.values() for c, _ in v if math.isfinite(c)])
    for m, v in fits.items():
        ok = [math.isfinite(c) and c <= 1.01 * best for c, _ in v]
        rec.add(case, variant, m, "convergence_rate", float(np.mean(ok)), "", f"{len(v)} log-uniform x0.3..x3 starts")
        rec.add(case, variant, m, "n_starts", len(v))
        rec.add(case, variant, m, "mean_time_per_start_s", float(np.mean([s for _, s in v])), "s")


def case_nomoto(rec, quick, figs):
    case = "nomoto_linear"
    truth_model = Nomoto1(**NOMOTO_TRUTH)
    zig = nomoto_zigzag_errors(truth_model)
    start = {"K": 0.5 * NOMOTO_TRUTH["K"], "T1": 1.5 * NOMOTO_TRUTH["T1"], "delta0": 0.0}
    dur = 60.0
    # noise sweep (first variant also pays the compilation)
    for noise in ("none", "realistic", "high"):
        say(f"{case}: noise {noise}")
        tr = nomoto_case_runs(truth_model, which="train", duration=dur, noise=noise, seed=1)
        va = nomoto_case_runs(truth_model, which="val", duration=dur, noise=noise, seed=1)
        nomoto_methods(rec, case, f"noise={noise}", tr, va, NOMOTO_TRUTH, truth_model, start=start, zig=zig,
                       memory=(noise == "realistic"))
        if noise == "none":  # warm repeat: compiled already
            t = time.perf_counter()
            res = fit_output_error(Nomoto1(), tr, spec=_nomoto_spec(start), estimate_x0=("psi", "r"), weights="spread",
                                   flt=FLT_NONE)
            rec.add(case, "noise=none", "diffship_oe", "warm_wall_s", time.perf_counter() - t, "s", "2nd call")
    # parameter error over several noise seeds (the single-seed numbers above are one draw)
    seeds = range(10, 13) if quick else range(10, 18)
    say(f"{case}: realistic noise, {len(seeds)} seeds")
    for sd in seeds:
        tr = nomoto_case_runs(truth_model, which="train", duration=dur, noise="realistic", seed=sd)
        nomoto_methods(rec, case, f"seed={sd}", tr, [], NOMOTO_TRUTH, truth_model, start=start,
                       methods=("diffship_oe", "diffship_ee"), oe_weights="noise")
    seed_summary(rec, case, [f"seed={sd}" for sd in seeds], ("diffship_oe", "diffship_ee"))
    # sweeps (every new sample interval or run length is a new shape: diffship recompiles; quick: delay only)
    sweeps = {
        "dt": [] if quick else [0.05, 0.1, 0.5],
        "duration": [] if quick else [30.0, 60.0, 180.0],
        "delay": [0.0, 0.5] if quick else [0.0, 0.25, 0.5, 1.0],
    }
    for kind, values in sweeps.items():
        for v in values:
            kw = dict(duration=dur, dt=0.1, delay=0.0)
            kw[kind] = v
            say(f"{case}: {kind}={v:g}")
            tr = nomoto_case_runs(truth_model, which="train", noise="realistic", seed=2, **kw)
            va = nomoto_case_runs(truth_model, which="val", noise="realistic", seed=2,
                                  **{**kw, "duration": 60.0, "dt": kw["dt"]})
            nomoto_methods(rec, case, f"{kind}={v:g}", tr, va, NOMOTO_TRUTH, truth_model, start=start,
                           zig=zig if kind == "delay" else None)
    # convergence from N random starts (OE loop of warm fits vs scipy)
    n = 4 if quick else 16
    say(f"{case}: convergence from {n} random starts")
    tr = nomoto_case_runs(truth_model, which="train", duration=dur, noise="realistic", seed=1)
    starts = log_uniform_starts(NOMOTO_TRUTH, ("K", "T1", "delta0"), n, seed=3)
    fits = {"diffship_oe": [], "scipy_lm_numpy_rk4": []}
    batch = make_batch(Nomoto1(), tr, ("psi", "r"), FLT_NONE)
    for s in starts:
        spec = _nomoto_spec(s)
        t = time.perf_counter()
        try:
            r = fit_output_error(Nomoto1(), tr, spec=spec, estimate_x0=("psi", "r"), weights="spread", flt=FLT_NONE)
            fits["diffship_oe"].append((r.cost, time.perf_counter() - t))
        except Exception:
            fits["diffship_oe"].append((math.inf, time.perf_counter() - t))
        prob = _peers.NomotoProblem(spec, batch, channel_spread(batch))
        z0 = np.concatenate([spec.to_z(), np.zeros(2 * len(tr))])
        sp = _peers.scipy_fit(prob.residuals, z0, guard_s=60.0)
        fits["scipy_lm_numpy_rk4"].append((sp["cost"], sp["wall"]))
    convergence(rec, case, "noise=realistic", fits)
    batched(rec, case, tr, starts, fits["diffship_oe"], quick)


def case_nomoto_cubic(rec, quick, figs):
    case = "nomoto_cubic_truth"
    truth_model = NomotoCubic(**CUBIC_TRUTH)
    zig = nomoto_zigzag_errors(truth_model)
    start = {"K": 0.5 * CUBIC_TRUTH["K"], "T1": 1.5 * CUBIC_TRUTH["T1"], "delta0": 0.0}
    for noise in ("none", "realistic") if quick else ("none", "realistic", "high"):
        say(f"{case}: noise {noise}")
        tr = nomoto_case_runs(truth_model, which="train", duration=60.0, noise=noise, seed=4)
        va = nomoto_case_runs(truth_model, which="val", duration=60.0, noise=noise, seed=4)
        out = nomoto_methods(rec, case, f"noise={noise}", tr, va, CUBIC_TRUTH, truth_model, start=start, zig=zig)
        if "stlsq_sindy" in out:
            rec.add(case, f"noise={noise}", "stlsq_sindy", "rel_err_a", abs(out["stlsq_sindy"]["a"] - 50.0) / 50.0)


# -- vmapped batches -------------------------------------------------------------------------------------------
def _lm_fixed(problem, iters):
    """Fixed-iteration Levenberg–Marquardt (forward-mode Jacobian, Marquardt scaling) as one jittable function."""

    def solve(z0, args):
        res = lambda z: problem.residuals(z, args)  # noqa: E731
        r0 = res(z0)

        def body(carry, _):
            z, lam, c = carry
            r = res(z)
            J = jax.jacfwd(res)(z)
            H = J.T @ J
            g = J.T @ r
            A = H + lam * jnp.diag(jnp.diag(H) + 1e-12)
            dz = jnp.linalg.solve(A, -g)
            zn = z + dz
            rn = res(zn)
            cn = 0.5 * jnp.sum(rn * rn)
            ok = jnp.isfinite(cn) & (cn < c)
            return (jnp.where(ok, zn, z), jnp.where(ok, lam * 0.3, lam * 4.0), jnp.where(ok, cn, c)), None

        init = (z0, jnp.asarray(1e-3, dtype=jnp.float64), 0.5 * jnp.sum(r0 * r0))
        (z, _, c), _ = jax.lax.scan(body, init, None, length=iters)
        return z, c

    return solve


def batched(rec, case, train, starts, loop_fits, quick):
    """vmap of a fixed-iteration LM over starts vs a loop of single fits; vmap of bootstrap EE vs a loop."""
    say(f"{case}: vmapped batches")
    variant = "batch"
    spec0 = _nomoto_spec(starts[0])
    model = Nomoto1().with_params(spec0.values())
    batch = make_batch(model, train, ("psi", "r"), FLT_NONE)
    scales = channel_spread(batch)
    problem = _Problem(spec=spec0.structural(), out_idx=(0, 1), angle=(True, False), x0_idx=(0, 1), solver="rk4",
                       substeps=1)
    args = (model, jnp.asarray(batch.ts), jnp.asarray(batch.us), jnp.asarray(batch.ys), jnp.asarray(batch.mask),
            jnp.asarray(batch.x0), jnp.asarray(scales), jnp.asarray(scales))
    iters = 30
    Z0 = jnp.asarray(np.stack([np.concatenate([spec0.to_z(s), np.zeros(2 * len(train))]) for s in starts]))
    solve = _lm_fixed(problem, iters)
    vm = jax.jit(jax.vmap(solve, in_axes=(0, None)))
    one = jax.jit(solve)
    t = time.perf_counter()
    vm_c = vm.lower(Z0, args).compile()
    c_vm = time.perf_counter() - t
    t = time.perf_counter()
    one_c = one.lower(Z0[0], args).compile()
    c_one = time.perf_counter() - t
    jax.block_until_ready(vm_c(Z0, args))  # warm-up run
    t = time.perf_counter()
    _, costs_vm = jax.block_until_ready(vm_c(Z0, args))
    t_vm = time.perf_counter() - t
    t = time.perf_counter()
    costs_one = [float(one_c(z, args)[1]) for z in Z0]
    t_one = time.perf_counter() - t
    n = len(starts)
    best = min(min(float(jnp.min(costs_vm)), min(costs_one)), min(c for c, _ in loop_fits))
    rec.add(case, variant, "diffship_oe", "loop_fit_output_error_time_per_fit_s", float(np.mean([s for _, s in loop_fits])),
            "s", f"{n} starts, warm diffship fits (adaptive LM, up to 200 steps) in a Python loop")
    rec.add(case, variant, "diffship_oe", "vmap_lm_time_per_fit_s", t_vm / n, "s",
            f"jax.vmap of a {iters}-iteration LM over {n} starts, one compiled call")
    rec.add(case, variant, "diffship_oe", "jit_lm_loop_time_per_fit_s", t_one / n, "s",
            f"the same {iters}-iteration LM, jitted, unbatched, Python loop over {n} starts")
    rec.add(case, variant, "diffship_oe", "vmap_lm_compile_s", c_vm, "s")
    rec.add(case, variant, "diffship_oe", "jit_lm_compile_s", c_one, "s")
    rec.add(case, variant, "diffship_oe", "vmap_lm_converged_rate",
            float(np.mean(np.asarray(costs_vm) <= 1.01 * best)), "", "within 1 % of the best cost")
    rec.add(case, variant, "diffship_oe", "n_batch", n)
    # equation error bootstrap: weighted normal equations of the Nomoto regression
    B = 64 if quick else 256
    R, RD, D = [], [], []
    for run in train:
        r, rd = smooth_and_derivative(run.time, np.asarray(run["r"]), Filter())
        R.append(r); RD.append(rd); D.append(np.asarray(run["delta"]))
    A = np.stack([np.concatenate(R), np.concatenate(D), np.ones(sum(x.size for x in R))], 1)
    y = np.concatenate(RD)
    rng = np.random.default_rng(0)
    W = rng.multinomial(A.shape[0], np.full(A.shape[0], 1.0 / A.shape[0]), size=B).astype(np.float64)

    def wls(w, A, y):
        Aw = A * w[:, None]
        return jnp.linalg.solve(Aw.T @ A, Aw.T @ y)

    f = jax.jit(jax.vmap(wls, in_axes=(0, None, None)))
    Aj, yj, Wj = jnp.asarray(A), jnp.asarray(y), jnp.asarray(W)
    t = time.perf_counter()
    f_c = f.lower(Wj, Aj, yj).compile()
    c_b = time.perf_counter() - t
    jax.block_until_ready(f_c(Wj, Aj, yj))
    t = time.perf_counter()
    jax.block_until_ready(f_c(Wj, Aj, yj))
    t_b = time.perf_counter() - t
    t = time.perf_counter()
    for w in W:
        idx = np.repeat(np.arange(A.shape[0]), w.astype(int))
        np.linalg.lstsq(A[idx], y[idx], rcond=None)
    t_np = time.perf_counter() - t
    t = time.perf_counter()
    n_ee = 3 if quick else 10
    for _ in range(n_ee):
        fit_equation_error(Nomoto1(), train)
    t_ee = (time.perf_counter() - t) / n_ee
    rec.add(case, variant, "diffship_ee", "vmap_bootstrap_time_per_fit_s", t_b / B, "s", f"jax.vmap weighted LS, {B} resamples")
    rec.add(case, variant, "diffship_ee", "vmap_bootstrap_compile_s", c_b, "s")
    rec.add(case, variant, "numpy_ols", "loop_bootstrap_time_per_fit_s", t_np / B, "s", f"NumPy lstsq loop, {B} resamples")
    rec.add(case, variant, "diffship_ee", "loop_fit_equation_error_time_per_fit_s", t_ee, "s",
            "whole fit_equation_error call (filtering + GN + weighting pass)")


# -- Fossen 3-DOF USV --------------------------------------------------------------------------------------------
def case_fossen3(rec, quick, figs):
    from diffship.synthetic import usv_runs, usv_truth
    from fossen3_speed import NumpyProblem

    case = "fossen3_usv"
    n_runs, dur = (2, 40.0) if quick else (3, 60.0)
    guard = 90.0 if quick else 300.0
    truth = usv_truth().param_values()
    base = Fossen3().spec()
    free = base.free_names
    start = {n: truth[n] * (1.5 if i % 2 else 0.5) for i, n in enumerate(free)}
    spec = base.with_values({**{n: truth[n] for n in base.fixed_names}, **start})
    ch = ("psi", "u", "v", "r")
    levels = ("none", "realistic", "high") if not quick else ("realistic", "high")
    for noise in levels:
        variant = f"noise={noise}"
        say(f"{case}: noise {noise}")
        tr = usv_runs(n_runs, dur, 0.1, noise=noise, seed=0)
        va = usv_runs(2, dur, 0.1, noise=noise, seed=7)
        calls = 2 if noise == "realistic" else 1
        for k in range(calls):
            t = time.perf_counter()
            oe = fit_output_error(Fossen3(), tr, spec=spec, estimate_x0=ch, weights="spread", flt=FLT_NONE)
            wall = time.perf_counter() - t
            if k == 0:
                for key, v, u in (("wall_s", wall, "s"), ("compile_s", oe.compile_seconds, "s"), ("fit_s", oe.fit_seconds, "s"),
                                  ("cost", oe.cost, ""), ("iterations", oe.iterations, ""), ("converged", oe.converged, ""),
                                  ("process_max_rss_mb", maxrss_mb(), "MB")):
                    rec.add(case, variant, "diffship_oe", key, v, u)
            else:
                rec.add(case, variant, "diffship_oe", "warm_wall_s", wall, "s", "2nd call (compiled)")
        record_common(rec, case, variant, "diffship_oe", oe.model, va, truth, free)
        t = time.perf_counter()
        ee = fit_equation_error(Fossen3(), tr, spec=spec)
        wall = time.perf_counter() - t
        for key, v, u in (("wall_s", wall, "s"), ("compile_s", ee.compile_seconds, "s"), ("fit_s", ee.fit_seconds, "s"),
                          ("process_max_rss_mb", maxrss_mb(), "MB")):
            rec.add(case, variant, "diffship_ee", key, v, u)
        record_common(rec, case, variant, "diffship_ee", ee.model, va, truth, free)
        # NumPy OLS on inverse-dynamics forces (same Butterworth derivatives as diffship EE)
        t = time.perf_counter()
        Z, ZD, TAU = [], [], []
        for run in tr:
            cols = [smooth_and_derivative(run.time, np.asarray(run[c]), Filter()) for c in ("u", "v", "r")]
            k = int(0.02 * run.n)
            sl = slice(k, run.n - k)
            Z.append(np.stack([c[0] for c in cols], 1)[sl]); ZD.append(np.stack([c[1] for c in cols], 1)[sl])
            TAU.append(np.stack([np.asarray(run[c]) for c in ("tau_x", "tau_y", "tau_z")], 1)[sl])
        tracemalloc.start()
        pv = _peers.fossen3_ols(truth["m"], truth["Iz"], truth["xg"], np.concatenate(Z), np.concatenate(ZD),
                                np.concatenate(TAU))
        rec.add(case, variant, "numpy_ols", "tracemalloc_peak_mb", tracemalloc.get_traced_memory()[1] / 2**20, "MB")
        tracemalloc.stop()
        rec.add(case, variant, "numpy_ols", "wall_s", time.perf_counter() - t, "s", "includes filtering/differentiation")
        rec.add(case, variant, "numpy_ols", "compile_s", 0.0, "s")
        ols_model = usv_truth().with_params(pv)
        record_common(rec, case, variant, "numpy_ols", ols_model, va, truth, free)
        if noise != "realistic":
            continue
        # scipy peer on the identical problem (fossen3_speed.NumpyProblem)
        say(f"{case}: scipy least_squares (guard {guard:.0f} s)")
        model = Fossen3()
        batch = make_batch(model.with_params(spec.values()), tr, ch, FLT_NONE)
        spread = channel_spread(batch)
        x0_idx = tuple(model.state_names.index(s) for s in ch)
        prob = NumpyProblem(spec, model, batch, x0_idx, spread, spread)
        z0 = np.concatenate([spec.to_z(), np.zeros(len(tr) * 4)])
        sp = _peers.scipy_fit(prob.residuals, z0, guard_s=guard, target_cost=oe.cost)
        for key, v, u in (("wall_s", sp["wall"], "s"), ("compile_s", 0.0, "s"), ("fit_s", sp["wall"], "s"),
                          ("cost", sp["cost"], ""), ("f_evals", sp["calls"], ""), ("converged", sp["finished"], ""),
                          ("time_to_oe_cost_s", sp["t_target"] if sp["t_target"] is not None else math.nan, "s"),
                          ("guard_s", guard, "s")):
            rec.add(case, variant, "scipy_lm_numpy_rk4", key, v, u)
        tracemalloc.start()
        _peers.scipy_fit(prob.residuals, z0, guard_s=guard, max_nfev=1)
        rec.add(case, variant, "scipy_lm_numpy_rk4", "tracemalloc_peak_mb", tracemalloc.get_traced_memory()[1] / 2**20, "MB",
                "tracemalloc, one LM iteration (one FD Jacobian)")
        tracemalloc.stop()
        record_common(rec, case, variant, "scipy_lm_numpy_rk4", Fossen3().with_params(prob.params(sp["z"])), va, truth, free)
        # convergence of diffship OE from N random starts (scipy: too slow here, not run)
        n = 3 if quick else 5
        say(f"{case}: OE from {n} random starts")
        fits = {"diffship_oe": []}
        for s in log_uniform_starts(truth, free, n, seed=5):
            t = time.perf_counter()
            try:
                r = fit_output_error(Fossen3(), tr, spec=spec.with_values(s), estimate_x0=ch, weights="spread", flt=FLT_NONE)
                fits["diffship_oe"].append((r.cost, time.perf_counter() - t))
            except Exception:
                fits["diffship_oe"].append((math.inf, time.perf_counter() - t))
        convergence(rec, case, variant, fits, best=oe.cost)
    seeds = range(20, 22) if quick else range(20, 23)
    for sd in seeds:
        say(f"{case}: realistic noise, seed {sd}")
        tr = usv_runs(n_runs, dur, 0.1, noise="realistic", seed=sd)
        oe = fit_output_error(Fossen3(), tr, spec=spec, estimate_x0=ch, weights="noise", flt=FLT_NONE)
        ee = fit_equation_error(Fossen3(), tr, spec=spec)
        for m, res in (("diffship_oe", oe), ("diffship_ee", ee)):
            errs = rel_errs(res.params, truth, free)
            rec.add(case, f"seed={sd}", m, "max_rel_param_err", max(errs.values()))
            rec.add(case, f"seed={sd}", m, "rms_rel_param_err", float(np.sqrt(np.mean(np.square(list(errs.values()))))))
    seed_summary(rec, case, [f"seed={sd}" for sd in seeds], ("diffship_oe", "diffship_ee"))


# -- VMM ship and 6-DOF ROV (full mode) ----------------------------------------------------------------------------
def case_vmm(rec, quick, figs):
    from diffship.manoeuvres import turning_circle, turning_metrics, zigzag, zigzag_metrics
    from diffship.models import VMMLinear
    from _cases import vmm_case_runs

    case = "vmm_linear_ship"
    truth_model = VMMLinear()
    truth = truth_model.param_values()
    dur = 200.0 if quick else 300.0
    tr, T0 = vmm_case_runs(truth_model, n_runs=2, duration=dur, noise="realistic", seed=0)
    va, _ = vmm_case_runs(truth_model, n_runs=2, duration=dur, noise="realistic", seed=1, first=2)
    spec = truth_model.spec()
    free = spec.free_names
    start = {n: truth[n] * (1.3 if i % 2 else 0.7) for i, n in enumerate(free)}
    spec = spec.with_values(start)
    init = {"u": float(truth_model.U0)}

    def zig(m):
        out = {}
        try:
            for a in (10.0, 20.0):
                zr = zigzag_metrics(zigzag(m, init, inputs={"thrust": T0}, rudder_deg=a, duration=300.0, dt=0.5))
                zt = zigzag_metrics(zigzag(truth_model, init, inputs={"thrust": T0}, rudder_deg=a, duration=300.0, dt=0.5))
                out[f"err_overshoot1_{a:g}_{a:g}"] = zr.first_overshoot - zt.first_overshoot
                out[f"err_overshoot2_{a:g}_{a:g}"] = zr.second_overshoot - zt.second_overshoot
            tm = turning_metrics(turning_circle(m, init, inputs={"thrust": T0}, duration=400.0, dt=0.5))
            tt = turning_metrics(turning_circle(truth_model, init, inputs={"thrust": T0}, duration=400.0, dt=0.5))
            out["rel_err_tactical_diameter"] = (tm.tactical_diameter - tt.tactical_diameter) / tt.tactical_diameter
            out["rel_err_advance"] = (tm.advance - tt.advance) / tt.advance
        except Exception as exc:
            say(f"  manoeuvre metrics failed: {exc}")
        return out

    say(f"{case}: output error")
    t = time.perf_counter()
    oe = fit_output_error(truth_model, tr, spec=spec, estimate_x0=("u", "v", "r"), weights="spread")
    wall = time.perf_counter() - t
    for key, v, u in (("wall_s", wall, "s"), ("compile_s", oe.compile_seconds, "s"), ("fit_s", oe.fit_seconds, "s"),
                      ("converged", oe.converged, ""), ("process_max_rss_mb", maxrss_mb(), "MB")):
        rec.add(case, "noise=realistic", "diffship_oe", key, v, u)
    record_common(rec, case, "noise=realistic", "diffship_oe", oe.model, va, truth, free, zig)
    say(f"{case}: equation error (= per-DOF OLS of inverse-dynamics forces, seed 000's way)")
    t = time.perf_counter()
    ee = fit_equation_error(truth_model, tr, spec=spec)
    wall = time.perf_counter() - t
    for key, v, u in (("wall_s", wall, "s"), ("compile_s", ee.compile_seconds, "s"), ("fit_s", ee.fit_seconds, "s"),
                      ("process_max_rss_mb", maxrss_mb(), "MB")):
        rec.add(case, "noise=realistic", "diffship_ee", key, v, u)
    record_common(rec, case, "noise=realistic", "diffship_ee", ee.model, va, truth, free, zig)


def case_rov(rec, quick, figs):
    from diffship.models import Fossen6
    from _cases import rov_case_runs

    case = "fossen6_rov"
    truth_model = Fossen6()
    truth = truth_model.param_values()
    tr = rov_case_runs(truth_model, n_runs=2, duration=30.0, dt=0.05, seed=0)
    va = rov_case_runs(truth_model, n_runs=1, duration=30.0, dt=0.05, seed=1)
    spec = truth_model.spec()
    free = spec.free_names
    spec = spec.with_values({n: truth[n] * (1.3 if i % 2 else 0.7) for i, n in enumerate(free)})
    chans = ("phi", "theta", "psi", "u", "v", "w", "p", "q", "r")
    say(f"{case}: equation error")
    t = time.perf_counter()
    ee = fit_equation_error(truth_model, tr, spec=spec)
    wall = time.perf_counter() - t
    for key, v, u in (("wall_s", wall, "s"), ("compile_s", ee.compile_seconds, "s"), ("fit_s", ee.fit_seconds, "s"),
                      ("process_max_rss_mb", maxrss_mb(), "MB")):
        rec.add(case, "noise=realistic", "diffship_ee", key, v, u)
    record_common(rec, case, "noise=realistic", "diffship_ee", ee.model, va, truth, free)
    say(f"{case}: output error ({len(free)} parameters)")
    t = time.perf_counter()
    oe = fit_output_error(truth_model, tr, spec=spec, channels=chans, starts=[{n: ee.params[n] for n in free}],
                          weights="spread", max_steps=60)
    wall = time.perf_counter() - t
    for key, v, u in (("wall_s", wall, "s"), ("compile_s", oe.compile_seconds, "s"), ("fit_s", oe.fit_seconds, "s"),
                      ("converged", oe.converged, ""), ("process_max_rss_mb", maxrss_mb(), "MB")):
        rec.add(case, "noise=realistic", "diffship_oe", key, v, u)
    record_common(rec, case, "noise=realistic", "diffship_oe", oe.model, va, truth, free)


# -- real data -------------------------------------------------------------------------------------------------
def case_sspa(rec, quick, figs):
    from diffship.data import example_runs
    from diffship.manoeuvres import zigzag_metrics

    case = "sspa_zigzag_real"
    run = example_runs("sspa_zigzag")[0].resample(0.1)
    t_split = run.time[0] + 25.0
    train = [run.slice(None, t_split)]
    val = [run]

    def zig(m):
        ev = evaluate(m, [run])
        sim = run.with_channels(psi=ev.simulated[run.name]["psi"], r=ev.simulated[run.name]["r"])
        try:
            zm, zs = zigzag_metrics(run, switch_deg=20.0, rudder_deg=20.0), zigzag_metrics(sim, switch_deg=20.0, rudder_deg=20.0)
            return {"err_overshoot1_20_20": zs.first_overshoot - zm.first_overshoot}
        except Exception as exc:
            say(f"  zigzag metrics failed: {exc}")
            return {}

    say(f"{case}: train on the first 25 s, validate on the whole run (open loop, measured rudder)")
    start = {"K": 0.3, "T1": 3.0, "delta0": 0.0}
    nomoto_methods(rec, case, "train=first25s", train, val, None, None, start=start, zig=zig)


def case_kvlcc2(rec, quick, figs):
    from diffship.data import shared_data_dir

    case = "kvlcc2_hsva_real"
    d = shared_data_dir()
    if d is None or not (d / "kvlcc2_hsva").is_dir():
        msg = "skipped: ../shared/data/kvlcc2_hsva not found (set DIFFSHIP_SHARED_DATA)"
        say(f"{case}: {msg}")
        rec.add(case, "-", "-", "skipped", 1.0, "", msg)
        return
    if quick:
        from diffship.data import kvlcc2_runs

        n = len(kvlcc2_runs())
        rec.add(case, "-", "-", "skipped", 1.0, "", f"data found ({n} runs); the MMG study runs in full mode only (minutes)")
        return
    try:
        from diffship.studies.kvlcc2 import kvlcc2_study
    except ImportError as exc:
        rec.add(case, "-", "-", "skipped", 1.0, "", f"diffship.studies.kvlcc2 not importable: {exc}")
        return
    say(f"{case}: MMG output error on 4 training zigzags, prediction of the other 9 (diffship.studies.kvlcc2)")
    t = time.perf_counter()
    st = kvlcc2_study()
    wall = time.perf_counter() - t
    variant = "train=" + "+".join(st.train)
    rec.add(case, variant, "diffship_oe", "wall_s", wall, "s", "whole study: fit + 13 closed/open-loop predictions")
    rec.add(case, variant, "diffship_oe", "compile_s", st.fit.compile_seconds, "s")
    rec.add(case, variant, "diffship_oe", "fit_s", st.fit.fit_seconds, "s")
    rec.add(case, variant, "diffship_oe", "converged", st.fit.converged)
    rec.add(case, variant, "diffship_oe", "max_abs_err_overshoot1_validation_closed_loop", st.max_first_overshoot_error("cl"), "deg")
    rec.add(case, variant, "diffship_oe", "max_abs_err_overshoot1_validation_open_loop", st.max_first_overshoot_error("ol"), "deg")
    v = st.table[st.table.role == "validate"]
    rec.add(case, variant, "diffship_oe", "rms_err_overshoot1_validation_closed_loop",
            float(np.sqrt(np.mean(np.square(v.err_first_cl)))), "deg")
    rec.add(case, variant, "diffship_oe", "process_max_rss_mb", maxrss_mb(), "MB")
    rec.add(case, variant, "diffship_ee", "not_available", 1.0, "", "no equation-error baseline for the MMG model")


CASES = {"nomoto": case_nomoto, "nomoto_cubic": case_nomoto_cubic, "fossen3": case_fossen3, "sspa": case_sspa,
         "kvlcc2": case_kvlcc2, "vmm": case_vmm, "rov": case_rov}
QUICK_CASES = ("nomoto", "nomoto_cubic", "sspa", "kvlcc2")


# -- report ----------------------------------------------------------------------------------------------------
def headline(rec):
    """Headline rows: (quantity, value, how)."""
    rows = []
    for case, variant in (("fossen3_usv", "noise=realistic"), ("nomoto_linear", "noise=realistic")):
        # warm: the 2nd call on these data (or the 1st, if compilation was paid on an earlier variant);
        # cold: the case's first call, the one that paid the compilation (same shapes, same problem size)
        oe_w = rec.get(case, variant, "diffship_oe", "warm_wall_s")
        if not math.isfinite(oe_w) and rec.get(case, variant, "diffship_oe", "compile_s") == 0.0:
            oe_w = rec.get(case, variant, "diffship_oe", "wall_s")
        firsts = [(r["value"], r["variant"]) for r in rec.rows if r["case"] == case and r["method"] == "diffship_oe"
                  and r["metric"] == "compile_s" and r["variant"].startswith("noise=")]
        oe_c = rec.get(case, max(firsts)[1], "diffship_oe", "wall_s") if firsts else math.nan
        sp_t = rec.get(case, variant, "scipy_lm_numpy_rk4", "time_to_oe_cost_s")
        sp_wall = rec.get(case, variant, "scipy_lm_numpy_rk4", "wall_s")
        if not math.isfinite(oe_c):
            continue
        lower = not math.isfinite(sp_t)
        ref = sp_wall if lower else sp_t
        if not math.isfinite(ref):
            continue
        tag = "≥ " if lower else ""
        rows.append((f"Speed ratio scipy/diffship OE at equal final cost, warm ({case})", f"{tag}{ref / oe_w:.3g}×",
                     f"scipy time to reach within 1 % of diffship's cost {ref:.2f} s / diffship warm fit {oe_w:.2f} s"
                     + (" (scipy never got there: lower bound)" if lower else "")))
        rows.append((f"Speed ratio scipy/diffship OE at equal final cost, incl. compilation ({case})",
                     f"{tag}{ref / oe_c:.3g}×", f"{ref:.2f} s / diffship first call {oe_c:.2f} s"))
    for case in ("fossen3_usv", "nomoto_linear"):
        st = {m: seed_stats(rec, case, m) for m in ("diffship_ee", "diffship_oe")}
        if all(v[2] for v in st.values()):
            (mx_ee, rms_ee, n), (mx_oe, rms_oe, _) = st["diffship_ee"], st["diffship_oe"]
            rows.append((f"Parameter-error ratio EE/OE at realistic noise ({case})",
                         f"{rms_ee / rms_oe:.1f}× (RMS), {mx_ee / mx_oe:.1f}× (max)",
                         f"relative parameter errors, mean over {n} noise seeds: RMS over parameters EE {rms_ee:.1%} vs "
                         f"OE {rms_oe:.1%}; worst parameter EE {mx_ee:.1%} vs OE {mx_oe:.1%}"))
    ref = Path(__file__).resolve().parent / "results" / "fossen3_speed.csv"
    if ref.exists():
        with open(ref) as fh:
            rr = list(csv.DictReader(fh))
        try:
            same = str(rr[0].get("same_cost_1pct", "")).lower() in ("true", "1", "yes")
            bound = "" if same else "≥ "
            rows.append(("Reference: fossen3 3 runs × 300 s (benchmarks/fossen3_speed.py, not rerun here)",
                         f"{bound}{float(rr[0]['ratio_scipy_over_diffship_warm']):.0f}× warm, "
                         f"{bound}{float(rr[0]['ratio_scipy_over_diffship_cold']):.1f}× incl. compilation",
                         "same final cost reached by both" if same else
                         "scipy stopped by its 600 s guard far above diffship's cost: lower bounds"))
        except (KeyError, ValueError, IndexError):
            pass
    case = "nomoto_linear"
    lp = rec.get(case, "batch", "diffship_oe", "loop_fit_output_error_time_per_fit_s")
    vm = rec.get(case, "batch", "diffship_oe", "vmap_lm_time_per_fit_s")
    jl = rec.get(case, "batch", "diffship_oe", "jit_lm_loop_time_per_fit_s")
    n = rec.get(case, "batch", "diffship_oe", "n_batch")
    if math.isfinite(vm):
        rows.append(("Batched OE time per fit (vmap over starts, Nomoto)", f"{vm * 1e3:.1f} ms",
                     f"{n:.0f} starts in one vmapped fixed-iteration LM; same LM looped: {jl * 1e3:.1f} ms/fit; "
                     f"diffship fit_output_error looped: {lp * 1e3:.1f} ms/fit"))
        bb = rec.get(case, "batch", "diffship_ee", "vmap_bootstrap_time_per_fit_s")
        bn = rec.get(case, "batch", "numpy_ols", "loop_bootstrap_time_per_fit_s")
        rows.append(("Batched EE bootstrap time per fit (vmap, Nomoto)", f"{bb * 1e6:.1f} µs",
                     f"NumPy lstsq loop: {bn * 1e6:.1f} µs/fit"))
    rows.append(("GPU run", "not run", "no GPU is available in this session (CPU only, jax backend "
                 f"'{jax.default_backend()}')"))
    return rows


def method_table(rec, case, variant, metrics):
    methods = [m for m in METHODS if any(r["case"] == case and r["variant"] == variant and r["method"] == m
                                         for r in rec.rows)]
    if not methods:
        return []
    out = ["| method | " + " | ".join(metrics) + " |", "|---|" + "---:|" * len(metrics)]
    for m in methods:
        cells = []
        for k in metrics:
            v = rec.get(case, variant, m, k)
            cells.append("–" if not math.isfinite(v) else (f"{v:.3g}" if abs(v) < 1e4 else f"{v:.3e}"))
        out.append(f"| {LABEL[m]} | " + " | ".join(cells) + " |")
    return out


def _first_call_variant(rec, case, default):
    """The variant whose diffship OE call paid the compilation (the case's first call)."""
    firsts = [(r["value"], r["variant"]) for r in rec.rows if r["case"] == case and r["method"] == "diffship_oe"
              and r["metric"] == "compile_s"]
    return max(firsts)[1] if firsts else default


def figures(rec, out_dir, prefix):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    made = []
    # 1. parameter error vs noise
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    for ax, case in zip(axes, ("nomoto_linear", "nomoto_cubic_truth", "fossen3_usv")):
        for m in METHODS:
            xs, ys = [], []
            for i, lv in enumerate(("none", "realistic", "high")):
                v = rec.get(case, f"noise={lv}", m, "max_rel_param_err")
                if math.isfinite(v):
                    xs.append(i); ys.append(max(v, 1e-6))
            if xs:
                ax.semilogy(xs, ys, label=LABEL[m], **STYLE[m])
        ax.set_xticks([0, 1, 2], ["none", "realistic", "3× realistic"])
        ax.set_xlabel("measurement noise")
        ax.set_ylabel("max |relative parameter error|")
        ax.set_title(case)
        ax.grid(True, which="both", alpha=0.3)
    if axes[0].get_legend_handles_labels()[0]:
        axes[0].legend(fontsize=7)
    fig.tight_layout()
    p = out_dir / f"{prefix}param_error_vs_noise.png"
    fig.savefig(p, dpi=110); plt.close(fig); made.append(p)
    # 2. sweeps: parameter error and validation NRMSE of r
    fig, axes = plt.subplots(2, 3, figsize=(13, 7), sharex="col")
    for j, (kind, xl) in enumerate((("dt", "sample interval [s]"), ("duration", "run length [s]"),
                                    ("delay", "unmodelled input delay [s]"))):
        vals = sorted({float(r["variant"].split("=")[1]) for r in rec.rows
                       if r["case"] == "nomoto_linear" and r["variant"].startswith(kind + "=")})
        for i, (metric, yl) in enumerate((("max_rel_param_err", "max |relative parameter error|"),
                                          ("val_nrmse_r", "validation NRMSE of r [-]"))):
            ax = axes[i, j]
            for m in METHODS:
                ys = [rec.get("nomoto_linear", f"{kind}={v:g}", m, metric) for v in vals]
                if any(math.isfinite(y) for y in ys):
                    (ax.semilogy if i == 0 else ax.plot)(vals, ys, label=LABEL[m], **STYLE[m])
            ax.set_ylabel(yl)
            ax.grid(True, which="both", alpha=0.3)
            if i == 0:
                ax.set_title(f"Nomoto, realistic noise: {kind} sweep")
            else:
                ax.set_xlabel(xl)
    if axes[0, 0].get_legend_handles_labels()[0]:
        axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    p = out_dir / f"{prefix}sweeps.png"
    fig.savefig(p, dpi=110); plt.close(fig); made.append(p)
    # 3. wall times
    fig, ax = plt.subplots(figsize=(9, 4))
    cases = [("nomoto_linear", "noise=realistic"), ("fossen3_usv", "noise=realistic"), ("sspa_zigzag_real", "train=first25s")]
    w = 0.15
    for j, m in enumerate(METHODS):
        vv = [_first_call_variant(rec, c, v) if m == "diffship_oe" else v for c, v in cases]
        comp = [rec.get(c, v, m, "compile_s") for (c, _), v in zip(cases, vv)]
        tot = [rec.get(c, v, m, "wall_s") for (c, _), v in zip(cases, vv)]
        x = np.arange(len(cases)) + (j - 2) * w
        fitp = [t - c if math.isfinite(t) and math.isfinite(c) else t for t, c in zip(tot, comp)]
        ax.bar(x, np.nan_to_num(fitp), w, label=f"{LABEL[m]} (fit)")
        ax.bar(x, np.nan_to_num(comp), w, bottom=np.nan_to_num(fitp), color="0.7", edgecolor="k", linewidth=0.3)
    ax.set_yscale("log")
    ax.set_xticks(range(len(cases)), [c for c, _ in cases])
    ax.set_ylabel("wall time [s] (grey: compilation)")
    ax.set_ylim(bottom=1e-3)
    ax.set_title("Wall time per fit, realistic noise (diffship OE: the case's first call; grey: compilation)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    p = out_dir / f"{prefix}wall_time.png"
    fig.savefig(p, dpi=110); plt.close(fig); made.append(p)
    # 4. batch
    keys = [("diffship_oe", "loop_fit_output_error_time_per_fit_s", "fit_output_error loop"),
            ("diffship_oe", "jit_lm_loop_time_per_fit_s", "jitted LM, loop"),
            ("diffship_oe", "vmap_lm_time_per_fit_s", "jitted LM, vmap"),
            ("diffship_ee", "loop_fit_equation_error_time_per_fit_s", "fit_equation_error loop"),
            ("numpy_ols", "loop_bootstrap_time_per_fit_s", "EE bootstrap, NumPy loop"),
            ("diffship_ee", "vmap_bootstrap_time_per_fit_s", "EE bootstrap, vmap")]
    vals = [rec.get("nomoto_linear", "batch", m, k) for m, k, _ in keys]
    if any(math.isfinite(v) for v in vals):
        fig, ax = plt.subplots(figsize=(8, 3.8))
        ax.barh([lbl for *_, lbl in keys], np.nan_to_num(vals))
        ax.set_xscale("log")
        ax.set_xlabel("time per fit [s]")
        ax.set_title("Nomoto: batched (vmap) vs looped fits, CPU")
        fig.tight_layout()
        p = out_dir / f"{prefix}batch_time_per_fit.png"
        fig.savefig(p, dpi=110); plt.close(fig); made.append(p)
    return made


def write_report(rec, out_dir, stem, quick, cases_run, total_s, figs, env):
    L = [f"# diffship benchmark report ({'quick' if quick else 'full'} mode)", "",
         f"Regenerate: `PYTHONPATH=src .venv/bin/python benchmarks/run.py{' --quick' if quick else ''}` "
         f"(total {total_s / 60:.1f} min on this machine). Every number below is also in `{stem.replace('report', 'all_numbers')}.csv`.",
         "", "## Headline", "", "| quantity | value | how |", "|---|---:|---|"]
    for q, v, how in headline(rec):
        L.append(f"| {q} | {v} | {how} |")
    L += ["", "How to read it: speed ratios compare diffship output error and scipy `least_squares` on the "
          "*identical* problem (same data, start, scaled parameters, channel-spread weights, estimated initial "
          "states; the NumPy residual at diffship's solution reproduces diffship's cost), timing scipy until its "
          "best cost first came within 1 % of diffship's final cost. Warm = diffship already compiled for this "
          "problem size; incl. compilation = the first call of the case. Parameter-error ratios are means over "
          "noise seeds with diffship's default noise weighting for output error; the per-case tables below are "
          "single draws.", ""]
    L += ["**Timing caveat:** measured on a shared 2-core machine with other jobs running (load average "
          f"{os.getloadavg()[0]:.1f} at the end); wall times are noisy, ratios more robust than absolute seconds.", ""]
    common = ["max_rel_param_err", "val_nrmse_psi", "val_nrmse_r", "err_overshoot1_10_10", "err_overshoot1_20_20",
              "compile_s", "wall_s", "cost"]
    sections = [
        ("nomoto_linear", ["noise=none", "noise=realistic", "noise=high"], "Nomoto (linear truth K=0.2/s, T=8 s, δ0=0.01)"),
        ("nomoto_cubic_truth", ["noise=none", "noise=realistic", "noise=high"],
         "Nonlinear Nomoto truth (T ṙ + r + a r³ = Kδ, a = 50 s²) fitted with the linear Nomoto model"),
        ("fossen3_usv", ["noise=none", "noise=realistic", "noise=high"], "Fossen 3-DOF USV (10 free parameters)"),
        ("vmm_linear_ship", ["noise=realistic"], "VMM linear ship (prime system), zigzags with thrust steps"),
        ("fossen6_rov", ["noise=realistic"], "Fossen 6-DOF ROV (BlueROV2 Heavy)"),
        ("sspa_zigzag_real", ["train=first25s"], "Real: SSPA 20/20 zigzag (train on the first 25 s, validate on the whole run)"),
    ]
    for case, variants, title in sections:
        if not any(r["case"] == case for r in rec.rows):
            continue
        L += [f"## {title}", ""]
        for v in variants:
            extra = ["time_to_oe_cost_s"] if case in ("fossen3_usv", "nomoto_linear") and v == "noise=realistic" else []
            if case == "vmm_linear_ship":
                extra = ["err_overshoot2_10_10", "err_overshoot2_20_20", "rel_err_tactical_diameter", "rel_err_advance",
                         "val_nrmse_u", "val_nrmse_v"]
            if case == "fossen3_usv":
                extra = ["val_nrmse_u", "val_nrmse_v"] + extra
            if case == "nomoto_cubic_truth":
                extra = ["rel_err_a", "cubic_term_kept"]
            t = method_table(rec, case, v, common + extra)
            if t:
                L += [f"**{v}**", ""] + t + [""]
        conv = [r for r in rec.rows if r["case"] == case and r["metric"] == "convergence_rate" and r["method"] in METHODS]
        if conv:
            L += ["Convergence from N random starts (log-uniform ×0.3…×3 of the truth; converged = final cost within "
                  "1 % of the best cost any start reached):", ""]
            for r in conv:
                tps = rec.get(case, r["variant"], r["method"], "mean_time_per_start_s")
                L.append(f"* {LABEL[r['method']]}: {r['value']:.0%} of {rec.get(case, r['variant'], r['method'], 'n_starts'):.0f} "
                         f"starts, {tps:.2f} s per start")
            L.append("")
    # sweeps
    sw = sorted({r["variant"] for r in rec.rows if r["case"] == "nomoto_linear"
                 and r["variant"].split("=")[0] in ("dt", "duration", "delay")},
                key=lambda s: (s.split("=")[0], float(s.split("=")[1])))
    if sw:
        L += ["## Sweeps (Nomoto, realistic noise): sample interval, run length, unmodelled input delay", "",
              "Max relative parameter error / validation NRMSE of r (whole-run simulation of held-out manoeuvres):", "",
              "| variant | " + " | ".join(LABEL[m] for m in METHODS) + " |", "|---|" + "---:|" * len(METHODS)]
        for v in sw:
            cells = []
            for m in METHODS:
                a = rec.get("nomoto_linear", v, m, "max_rel_param_err")
                b = rec.get("nomoto_linear", v, m, "val_nrmse_r")
                cells.append(f"{a:.3g} / {b:.3g}" if math.isfinite(a) else "–")
            L.append(f"| {v} | " + " | ".join(cells) + " |")
        L.append("")
    # kvlcc2
    kv = [r for r in rec.rows if r["case"] == "kvlcc2_hsva_real"]
    if kv:
        L += ["## Real: KVLCC2 HSVA zigzags (MMG, diffship.studies.kvlcc2)", ""]
        for r in kv:
            L.append(f"* {r['method']} {r['metric']}: {r['value']:.4g} {r['unit']} {r['note']}")
        L.append("")
    # batch
    b = [r for r in rec.rows if r["variant"] == "batch"]
    if b:
        L += ["## Scale: vmapped batches vs loops (Nomoto, CPU)", "", "| method | quantity | value | note |", "|---|---|---:|---|"]
        for r in b:
            L.append(f"| {r['method']} | {r['metric']} | {r['value']:.4g} {r['unit']} | {r['note']} |")
        L += ["", "On CPU, vmapping whole LM fits batches the small linear solves but every start runs the full "
              "fixed number of iterations (no early exit per start), so time per fit can be worse than a loop of "
              "adaptive fits; the numbers above are measured, not assumed. No GPU run: no GPU is available in "
              "this session.", ""]
    # memory
    L += ["## Memory", "",
          "* `process_max_rss_mb`: `resource.getrusage(RUSAGE_SELF).ru_maxrss` after the method — the whole "
          "process's high-water mark (monotone: includes JAX/XLA and everything run before), so it is an upper bound.",
          "* `tracemalloc_peak_mb`: Python/NumPy allocations traced by `tracemalloc` for the NumPy peers only "
          "(scipy: one LM iteration incl. one finite-difference Jacobian, which is the peak working set; OLS: the "
          "regression). tracemalloc does not see XLA buffers, so it is not used for the JAX methods.", ""]
    for case in ("nomoto_linear", "fossen3_usv"):
        for m in METHODS:
            for k in ("tracemalloc_peak_mb", "process_max_rss_mb"):
                v = rec.get(case, "noise=realistic", m, k)
                if math.isfinite(v):
                    L.append(f"* {case} / {LABEL[m]}: {k} = {v:.1f} MB")
    L += ["", "## Figures", ""] + [f"![{p.stem}]({p.name})" for p in figs]
    L += ["", "## Environment", "", f"* cases run: {', '.join(cases_run)}",
          f"* {env}", "* methods: see `benchmarks/README.md`. STLSQ is a NumPy re-implementation of SINDy's "
          "sequentially thresholded least squares (pysindy needs scikit-learn, not installed here); statsmodels "
          "is not installed, NumPy `lstsq` gives the same OLS estimates."]
    (out_dir / f"{stem}.md").write_text("\n".join(L) + "\n")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="CI size (a few minutes)")
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent / "results"))
    ap.add_argument("--cases", default=None, help=f"comma-separated subset of {','.join(CASES)}")
    ap.add_argument("--report-only", action="store_true",
                    help="rewrite the report and figures from the existing all_numbers CSV (no fitting)")
    args = ap.parse_args(argv)
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    cases = args.cases.split(",") if args.cases else (list(QUICK_CASES) if args.quick else list(CASES))
    unknown = [c for c in cases if c not in CASES]
    if unknown:
        ap.error(f"unknown case(s) {unknown}; choose from {', '.join(CASES)}")
    stem = "report_quick" if args.quick else "report"
    prefix = "fig_quick_" if args.quick else "fig_"
    rec = Recorder()
    t0 = time.perf_counter()
    cpu = ""
    try:
        cpu = next(ln.split(":", 1)[1].strip() for ln in open("/proc/cpuinfo") if ln.startswith("model name"))
    except (OSError, StopIteration):
        pass
    env = (f"machine: {cpu or platform.machine()}, {os.cpu_count()} CPUs, {platform.platform()}; Python "
           f"{platform.python_version()}, JAX {jax.__version__} ({jax.default_backend()}), NumPy {np.__version__}, "
           f"SciPy {scipy.__version__}")

    def write(done, final):
        total = time.perf_counter() - t0
        rec.write_csv(out_dir / f"{stem.replace('report', 'all_numbers')}.csv")
        figs = figures(rec, out_dir, prefix)
        write_report(rec, out_dir, stem, args.quick, done if final else done + ["(incomplete: still running)"],
                     total, figs, env)
        return total

    if args.report_only:
        with open(out_dir / f"{stem.replace('report', 'all_numbers')}.csv") as fh:
            for r in csv.DictReader(fh):
                if r["metric"] == "note_open_loop":  # written by an earlier version
                    continue
                rec.rows.append({**r, "value": float(r["value"]), "unit": _zig_unit(r["metric"]) if
                                 r["unit"] == "deg" and r["metric"].startswith("rel_err") else r["unit"]})
        rec.write_csv(out_dir / f"{stem.replace('report', 'all_numbers')}.csv")
        done = sorted({r["case"] for r in rec.rows if r["metric"] == "case_wall_s"})
        tot = rec.get("all", "-", "-", "total_wall_s")
        figs = figures(rec, out_dir, prefix)
        write_report(rec, out_dir, stem, args.quick, done, tot if math.isfinite(tot) else 0.0, figs,
                     env + " (report rewritten from the CSV)")
        print("\n".join(f"{q}: {v} ({h})" for q, v, h in headline(rec)))
        return 0
    done = []
    for c in cases:
        tc = time.perf_counter()
        try:
            CASES[c](rec, args.quick, None)
        except Exception as exc:  # one broken case must not hide the others
            import traceback

            traceback.print_exc()
            rec.add(c, "-", "-", "failed", 1.0, "", f"{type(exc).__name__}: {str(exc)[:200]}")
        rec.add(c, "-", "-", "case_wall_s", time.perf_counter() - tc, "s")
        say(f"case {c} done in {time.perf_counter() - tc:.1f} s")
        done.append(c)
        if c != cases[-1]:
            write(done, False)
    total = time.perf_counter() - t0
    rec.add("all", "-", "-", "total_wall_s", total, "s")
    write(done, True)
    say(f"wrote {out_dir / (stem + '.md')} ({total / 60:.1f} min)")
    print("\n".join(f"{q}: {v} ({h})" for q, v, h in headline(rec)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
