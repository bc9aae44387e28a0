"""Case ``fossen3`` (``fossen3_usv`` in the CSV): the Fossen 3-DOF USV of ``diffship.synthetic.usv_truth``.

What is measured: 10 free parameters (added masses and damping; m, Iz, xg known), start ±50 %,
3 runs × 60 s at 10 Hz (quick: 2 × 40 s), channels psi, u, v, r. Per noise level (none /
realistic / 3× realistic; quick: realistic, high): parameter errors and validation NRMSE of
diffship output error (cold call, and a warm second call at realistic noise), diffship equation
error and NumPy OLS on the inverse-dynamics forces; at realistic noise also scipy
``least_squares`` over NumPy RK4 on the identical problem (:class:`benchmarks.peers.Fossen3Problem`,
wall-clock guard 300 s, quick 90 s; time to reach diffship's cost; tracemalloc peak) and output
error from N random starts. Then the max/RMS parameter error over extra noise seeds with
diffship's default noise weighting (the headline EE/OE ratio).
"""

from __future__ import annotations

import math
import time

import numpy as np

from benchmarks.common import peers
from benchmarks.common.fitapi import FLT_NONE, batch_of, fit_ee, fit_numbers, fit_oe, fitted_model, fitted_params, spread_of
from benchmarks.record import (EE_KEYS, convergence, log_uniform_starts, record_common, record_fit, rel_errs, say,
                               seed_summary, timed, traced_peak)
from diffship.models import Fossen3
from diffship.preprocess import Filter, smooth_and_derivative

CHANNELS = ("psi", "u", "v", "r")


def fit_fossen3_oe(spec, runs, weights="spread"):
    """diffship output error on the scipy peer's problem (raw initial states of psi, u, v, r estimated per run, free
    as in the peer's least squares: no prior holding them near the first samples)."""
    return fit_oe(Fossen3(), runs, spec=spec, estimate_x0=CHANNELS, weights=weights, flt=FLT_NONE, x0_prior=False)


def _ols(rec, case, variant, tr, va, truth, free):
    """NumPy OLS on inverse-dynamics forces (same Butterworth derivatives as diffship EE)."""
    from diffship.synthetic import usv_truth

    t = time.perf_counter()
    Z, ZD, TAU = [], [], []
    for run in tr:
        cols = [smooth_and_derivative(run.time, np.asarray(run[c]), Filter()) for c in ("u", "v", "r")]
        k = int(0.02 * run.n)
        sl = slice(k, run.n - k)
        Z.append(np.stack([c[0] for c in cols], 1)[sl]); ZD.append(np.stack([c[1] for c in cols], 1)[sl])
        TAU.append(np.stack([np.asarray(run[c]) for c in ("tau_x", "tau_y", "tau_z")], 1)[sl])
    with traced_peak() as mem:
        pv = peers.fossen3_ols(truth["m"], truth["Iz"], truth["xg"], np.concatenate(Z), np.concatenate(ZD),
                               np.concatenate(TAU))
    rec.add(case, variant, "numpy_ols", "tracemalloc_peak_mb", mem["mb"], "MB")
    rec.add(case, variant, "numpy_ols", "wall_s", time.perf_counter() - t, "s", "includes filtering/differentiation")
    rec.add(case, variant, "numpy_ols", "compile_s", 0.0, "s")
    record_common(rec, case, variant, "numpy_ols", usv_truth().with_params(pv), va, truth, free)


def _scipy(rec, case, variant, tr, va, truth, free, spec, oe_cost, guard):
    """scipy peer on the identical problem."""
    say(f"{case}: scipy least_squares (guard {guard:.0f} s)")
    model = Fossen3()
    batch = batch_of(model.with_params(spec.values()), tr, CHANNELS, FLT_NONE)
    spread = spread_of(batch)
    x0_idx = tuple(model.state_names.index(s) for s in CHANNELS)
    prob = peers.Fossen3Problem(spec, model, batch, x0_idx, spread, spread)
    z0 = np.concatenate([spec.to_z(), np.zeros(len(tr) * 4)])
    sp = peers.scipy_fit(prob.residuals, z0, guard_s=guard, target_cost=oe_cost)
    for key, v, u in (("wall_s", sp["wall"], "s"), ("compile_s", 0.0, "s"), ("fit_s", sp["wall"], "s"),
                      ("cost", sp["cost"], ""), ("f_evals", sp["calls"], ""), ("converged", sp["finished"], ""),
                      ("time_to_oe_cost_s", sp["t_target"] if sp["t_target"] is not None else math.nan, "s"),
                      ("guard_s", guard, "s")):
        rec.add(case, variant, "scipy_lm_numpy_rk4", key, v, u)
    with traced_peak() as mem:
        peers.scipy_fit(prob.residuals, z0, guard_s=guard, max_nfev=1)
    rec.add(case, variant, "scipy_lm_numpy_rk4", "tracemalloc_peak_mb", mem["mb"], "MB",
            "tracemalloc, one LM iteration (one FD Jacobian)")
    record_common(rec, case, variant, "scipy_lm_numpy_rk4", Fossen3().with_params(prob.params(sp["z"])), va, truth, free)


def run(rec, quick, figs=None):
    from diffship.synthetic import usv_runs, usv_truth

    case = "fossen3_usv"
    n_runs, dur = (2, 40.0) if quick else (3, 60.0)
    guard = 90.0 if quick else 300.0
    truth = usv_truth().param_values()
    base = Fossen3().spec()
    free = base.free_names
    start = {n: truth[n] * (1.5 if i % 2 else 0.5) for i, n in enumerate(free)}
    spec = base.with_values({**{n: truth[n] for n in base.fixed_names}, **start})
    levels = ("none", "realistic", "high") if not quick else ("realistic", "high")
    for noise in levels:
        variant = f"noise={noise}"
        say(f"{case}: noise {noise}")
        tr = usv_runs(n_runs, dur, 0.1, noise=noise, seed=0)
        va = usv_runs(2, dur, 0.1, noise=noise, seed=7)
        calls = 2 if noise == "realistic" else 1
        for k in range(calls):
            oe, wall = timed(fit_fossen3_oe, spec, tr)
            if k == 0:
                record_fit(rec, case, variant, "diffship_oe", oe, wall)
            else:
                rec.add(case, variant, "diffship_oe", "warm_wall_s", wall, "s", "2nd call (compiled)")
        record_common(rec, case, variant, "diffship_oe", fitted_model(oe), va, truth, free)
        ee, wall = timed(fit_ee, Fossen3(), tr, spec=spec)
        record_fit(rec, case, variant, "diffship_ee", ee, wall, EE_KEYS)
        record_common(rec, case, variant, "diffship_ee", fitted_model(ee), va, truth, free)
        _ols(rec, case, variant, tr, va, truth, free)
        if noise != "realistic":
            continue
        oe_cost = fit_numbers(oe)["cost"]
        _scipy(rec, case, variant, tr, va, truth, free, spec, oe_cost, guard)
        # convergence of diffship OE from N random starts (scipy: too slow here, not run)
        n = 3 if quick else 5
        say(f"{case}: OE from {n} random starts")
        fits = {"diffship_oe": []}
        for s in log_uniform_starts(truth, free, n, seed=5):
            t = time.perf_counter()
            try:
                r = fit_fossen3_oe(spec.with_values(s), tr)
                fits["diffship_oe"].append((fit_numbers(r)["cost"], time.perf_counter() - t))
            except Exception:
                fits["diffship_oe"].append((math.inf, time.perf_counter() - t))
        convergence(rec, case, variant, fits, best=oe_cost)
    seeds = range(20, 22) if quick else range(20, 23)
    for sd in seeds:
        say(f"{case}: realistic noise, seed {sd}")
        tr = usv_runs(n_runs, dur, 0.1, noise="realistic", seed=sd)
        oe = fit_fossen3_oe(spec, tr, weights="noise")
        ee = fit_ee(Fossen3(), tr, spec=spec)
        for m, res in (("diffship_oe", oe), ("diffship_ee", ee)):
            errs = rel_errs(fitted_params(res), truth, free)
            rec.add(case, f"seed={sd}", m, "max_rel_param_err", max(errs.values()))
            rec.add(case, f"seed={sd}", m, "rms_rel_param_err", float(np.sqrt(np.mean(np.square(list(errs.values()))))))
    seed_summary(rec, case, [f"seed={sd}" for sd in seeds], ("diffship_oe", "diffship_ee"))


CASES = {"fossen3": run}
