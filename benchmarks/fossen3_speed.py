"""Speed and accuracy of diffship's output-error fit against a SciPy/MINPACK peer (Fossen 3-DOF).

What is measured
----------------
One process, one data set, one start, one residual definition, two solvers:

1. **diffship** — :func:`diffship.fit.output_error.fit_output_error` (JAX, forward-mode
   Jacobian materialised once per step, optimistix Levenberg–Marquardt, ``jax.vmap`` over runs).
   The first call includes compilation (``compile_seconds`` from the result, plus the total wall
   time of the call); the second call is warm (the compiled fit is reused from diffship's cache,
   so ``compile_seconds`` should be 0).
2. **scipy** — :func:`scipy.optimize.least_squares` with ``method="lm"`` (MINPACK LM; since
   SciPy 1.16 ``lmder`` fed by SciPy's 2-point forward-difference Jacobian) over a vectorised NumPy fixed-step RK4 simulation of the
   same model: one RK4 step per sample (dt = 0.1 s), inputs linearly interpolated (the midpoint
   input is the average of the neighbouring samples), vectorised over the runs. It is bounded by
   ``max_nfev`` and a wall-clock guard (600 s, or 120 s with ``--quick``); a run stopped by the
   guard is reported as "did not finish" with the best cost it had seen.

The problem (identical for both; the script checks this by evaluating the NumPy residual at
diffship's solution and comparing with diffship's reported cost):

* data: ``diffship.synthetic.usv_runs(3, 300 s, dt=0.1, noise="realistic", seed=0)``
  (``--quick``: 3 × 60 s); model :class:`diffship.models.Fossen3`, truth ``usv_truth()``;
* m, Iz, xg (and the other non-free parameters) fixed at truth; the 10 free parameters
  ``Xudot, Yvdot, Nrdot, Xu, Yv, Nv, Nr, Xuu, Yvv, Nrr`` start at ±50 % of truth
  (×0.5, ×1.5 alternately);
* fitted channels psi, u, v, r; residual ``(sim_c − meas_c)/s_c`` with ``s_c`` the channel
  spread (``channel_spread(make_batch(...))``), heading errors wrapped to (−π, π]; samples after a
  simulation blow-up get diffship's penalty residual;
* initial states: the raw first samples (``Filter("none")``) plus per-run offsets of psi, u, v, r
  (scaled by the channel spread) estimated with the parameters: 10 + 12 = 22 unknowns;
* parameters in diffship's scaled space ``z`` (``θ = upper − s·exp(z)`` for the sign-bounded
  ones, ``θ = s·z`` for the unbounded ``Nv``), reproduced in NumPy from the public ``Param``
  fields and checked against ``ParamSpec.from_z``;
* diffship: ``weights="spread"`` (one pass), default tolerances (rtol 1e-6, atol 1e-6,
  200 steps); scipy: default tolerances (ftol = xtol = gtol = 1e-8), ``max_nfev=200``;
* the same objective: the channels named (no positions refit, ``diffship.fit.positions``), and diffship's
  reference priors, initial-state prior and effective-sample weighting off (``reference_priors=False``,
  ``x0_prior=False``, ``effective_samples=False``), since the NumPy problem has none of them (with its
  defaults diffship minimises another objective: the positions join the fit where they agree, the priors
  pull the coefficients towards a reference set and the offsets towards the first samples, and each
  channel's rows are weighted by its effective sample size).

The NumPy simulator integrates only (psi, u, v, r): the positions x0, y0 feed nothing back and
are not fitted, so dropping them changes no residual (diffship integrates all six states).

Reported for both: final cost ½‖r‖², iterations / function evaluations, wall seconds, the largest
|relative error| of the 10 free parameters against truth, and speed ratios scipy/diffship (warm,
and with diffship's compilation included); whether both reached the same cost (within 1 %).

Run (from the repository root)::

    python -m benchmarks fossen3_speed [--quick] [--out benchmarks/results]

Writes ``OUT/fossen3_speed.md`` and ``OUT/fossen3_speed.csv`` (``--quick`` writes
``fossen3_speed_quick.*``) and prints the Markdown table.
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import platform
import time
from pathlib import Path

import numpy as np

import jax
import scipy
from scipy.optimize import least_squares


from benchmarks.common.fitapi import FLT_NONE, batch_of, fit_oe, initial_states, spread_of  # noqa: E402
from benchmarks.common.peers import Fossen3Problem as NumpyProblem  # noqa: E402  (the problem, in NumPy)
from diffship.models import Fossen3  # noqa: E402
from diffship.synthetic import usv_runs, usv_truth  # noqa: E402

CHANNELS = ("psi", "u", "v", "r")


# -- scipy with a wall-clock guard -----------------------------------------------------------------
class _TimeUp(Exception):
    pass


def run_scipy(prob: NumpyProblem, z0: np.ndarray, guard_s: float, max_nfev: int):
    """MINPACK LM with a wall-clock guard; returns a dict of results."""
    n = z0.size
    best = {"cost": math.inf, "z": z0.copy()}
    counts = {"calls": 0, "fd": 0}
    last_base = [None]
    last_print = [0.0]
    t0 = time.perf_counter()

    def fun(z):
        if time.perf_counter() - t0 > guard_s:
            raise _TimeUp
        r = prob.residuals(z)
        counts["calls"] += 1
        # 2-point forward differences perturb one coordinate of the current point at a time
        base = last_base[0]
        if base is not None and np.count_nonzero(z != base) == 1:
            counts["fd"] += 1
        else:
            last_base[0] = np.array(z, copy=True)
            c0 = 0.5 * float(r @ r)
            now = time.perf_counter() - t0
            if now - last_print[0] >= 60.0:
                last_print[0] = now
                print(f"  scipy lm: {now:5.0f} s, {counts['calls']} evaluations, trial cost {c0:.6g}, "
                      f"best {min(c0, best['cost']):.6g}", flush=True)
        c = 0.5 * float(r @ r)
        if c < best["cost"]:
            best.update(cost=c, z=np.array(z, copy=True))
        return r

    finished, status, nfev = True, "", None
    try:
        res = least_squares(fun, z0, method="lm", max_nfev=max_nfev)
        z, cost, nfev, status = res.x, float(res.cost), int(res.nfev), f"{res.message} (status {res.status})"
        finished = res.status > 0
        if res.status == 0:
            status = f"did not finish: max_nfev={max_nfev} reached"
    except _TimeUp:
        z, cost = best["z"], best["cost"]
        finished, status = False, f"did not finish: wall-clock guard {guard_s:.0f} s (best cost seen reported)"
    wall = time.perf_counter() - t0
    # calls: every residual evaluation (simulation), finite-difference ones included;
    # nfev: scipy's count (MINPACK lmder's calls, finite differences excluded)
    return dict(z=z, cost=cost, nfev=nfev, calls=counts["calls"], fd_calls=counts["fd"],
                jac_evals=counts["fd"] / n, wall=wall, finished=finished, status=status)


def max_rel_err(values: dict, truth: dict, names) -> float:
    return max(abs(values[n] - truth[n]) / abs(truth[n]) for n in names)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="3 runs x 60 s, scipy guard 120 s")
    ap.add_argument("--out", default="benchmarks/results", help="output folder")
    args = ap.parse_args(argv)
    duration = 60.0 if args.quick else 300.0
    guard = 120.0 if args.quick else 600.0
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    stem = "fossen3_speed_quick" if args.quick else "fossen3_speed"

    # -- the problem ---------------------------------------------------------------------------
    runs = usv_runs(3, duration, 0.1, noise="realistic", seed=0)
    truth = usv_truth().param_values()
    base_spec = Fossen3().spec()
    free = base_spec.free_names
    start = {n: truth[n] * 1.5 if i % 2 else truth[n] * 0.5 for i, n in enumerate(free)}
    spec = base_spec.with_values({**{n: truth[n] for n in base_spec.fixed_names}, **start})
    flt = FLT_NONE
    model = Fossen3()
    batch = batch_of(model.with_params(spec.values()), runs, CHANNELS, flt)
    spread = spread_of(batch)
    x0_idx = tuple(model.state_names.index(s) for s in CHANNELS)
    x0_scale = np.array([spread[batch.channels.index(s)] for s in CHANNELS])
    prob = NumpyProblem(spec, model, batch, x0_idx, x0_scale, spread)
    z0 = np.concatenate([spec.to_z(), np.zeros(len(runs) * len(x0_idx))])
    # the NumPy transform is diffship's
    zt = np.linspace(-2.0, 2.0, len(free))
    assert np.allclose(prob.from_z(zt), np.asarray(spec.from_z(jax.numpy.asarray(zt))), rtol=1e-14, atol=0)
    print(f"fossen3 speed benchmark ({'quick' if args.quick else 'full'}): {len(runs)} runs x {duration:g} s, "
          f"{batch.n_residuals} residuals, {z0.size} unknowns; start cost {0.5 * float(np.sum(prob.residuals(z0) ** 2)):.6g}",
          flush=True)

    def fit():
        t = time.perf_counter()
        res = fit_oe(Fossen3(), runs, spec=spec, estimate_x0=CHANNELS, weights="spread", flt=flt,
                     channels=CHANNELS, reference_priors=False, x0_prior=False, effective_samples=False)
        return res, time.perf_counter() - t

    # -- diffship: cold, then warm ------------------------------------------------------------------
    cold, cold_wall = fit()
    print(f"diffship cold: cost {cold.cost:.6g}, {cold.iterations} steps, wall {cold_wall:.2f} s "
          f"(compile {cold.compile_seconds:.2f} s, fit {cold.fit_seconds:.2f} s): {cold.status}", flush=True)
    warm, warm_wall = fit()
    print(f"diffship warm: cost {warm.cost:.6g}, {warm.iterations} steps, wall {warm_wall:.2f} s "
          f"(compile {warm.compile_seconds:.2f} s, fit {warm.fit_seconds:.2f} s)", flush=True)

    # the NumPy residual at diffship's solution must reproduce diffship's cost
    z_ds = np.concatenate([spec.to_z({n: warm.params[n] for n in free}),
                           ((initial_states(warm) - batch.x0)[:, list(x0_idx)] / x0_scale).reshape(-1)])
    cost_check = 0.5 * float(np.sum(prob.residuals(z_ds) ** 2))
    rel_check = abs(cost_check - warm.cost) / max(warm.cost, 1e-300)
    print(f"check: NumPy residual at diffship's solution gives cost {cost_check:.6g} "
          f"(diffship {warm.cost:.6g}, rel. diff {rel_check:.1e})", flush=True)

    # -- scipy / MINPACK ------------------------------------------------------------------------------
    t = time.perf_counter()
    prob.residuals(z0)
    t_sim = time.perf_counter() - t
    # scipy >= 1.16 runs 'lm' as MINPACK lmder with scipy's own 2-point differences, and
    # max_nfev counts lmder's calls only (not the finite differences): 200 ~ diffship's max_steps
    max_nfev = 200
    print(f"scipy lm: one NumPy simulation + residual {t_sim * 1e3:.0f} ms; running (guard {guard:.0f} s, "
          f"max_nfev {max_nfev})...", flush=True)
    sp = run_scipy(prob, z0, guard, max_nfev)
    sp_params = prob.params(sp["z"])
    print(f"scipy lm: cost {sp['cost']:.6g}, {sp['calls']} residual evaluations ({sp['fd_calls']} for finite "
          f"differences; scipy nfev {sp['nfev']}), wall {sp['wall']:.1f} s: {sp['status']}", flush=True)

    # -- tables ---------------------------------------------------------------------------------------
    err_cold = max_rel_err(cold.params, truth, free)
    err_warm = max_rel_err(warm.params, truth, free)
    err_sp = max_rel_err(sp_params, truth, free)
    same_cost = abs(sp["cost"] - warm.cost) <= 0.01 * min(sp["cost"], warm.cost)
    cold_total = cold_wall
    rows = [
        dict(method="diffship output_error (1st call, cold)", cost=cold.cost, iterations=cold.iterations,
             nfev="", wall_s=cold_wall, fit_s=cold.fit_seconds, compile_s=cold.compile_seconds,
             max_rel_param_err=err_cold, finished=cold.converged, status=cold.status),
        dict(method="diffship output_error (2nd call, warm)", cost=warm.cost, iterations=warm.iterations,
             nfev="", wall_s=warm_wall, fit_s=warm.fit_seconds, compile_s=warm.compile_seconds,
             max_rel_param_err=err_warm, finished=warm.converged, status=warm.status),
        dict(method="scipy least_squares lm (MINPACK, FD) + NumPy RK4", cost=sp["cost"],
             iterations=f"~{sp['jac_evals']:.0f}", nfev=sp["calls"], wall_s=sp["wall"], fit_s=sp["wall"], compile_s=0.0,
             max_rel_param_err=err_sp, finished=sp["finished"], status=sp["status"]),
    ]
    ratio_warm = sp["wall"] / warm_wall
    ratio_cold = sp["wall"] / cold_total
    cpu_model = ""
    try:
        cpu_model = next(ln.split(":", 1)[1].strip() for ln in open("/proc/cpuinfo") if ln.startswith("model name"))
    except (OSError, StopIteration):
        pass
    env = dict(processor=platform.processor() or platform.machine(), cpu_model=cpu_model, platform=platform.platform(),
               cpu_count=os.cpu_count(), python=platform.python_version(), jax=jax.__version__,
               jax_backend=jax.default_backend(), numpy=np.__version__, scipy=scipy.__version__)

    lines = [
        f"## fossen3 output-error fit: diffship vs scipy ({'quick' if args.quick else 'full'} mode)",
        "",
        f"Problem: {len(runs)} runs x {duration:g} s at 10 Hz (realistic noise, seed 0), channels "
        f"{', '.join(CHANNELS)}, {batch.n_residuals} residuals; {len(free)} free parameters (start ±50 %) + "
        f"{len(runs) * len(x0_idx)} initial-state offsets; weights = channel spread, no filter.",
        "",
        "| method | final cost | iterations | f-evals | wall [s] | fit [s] | compile [s] | max rel. param err | finished | status |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['method']} | {r['cost']:.6g} | {r['iterations']} | {r['nfev'] if r['nfev'] != '' else '–'} | "
            f"{r['wall_s']:.2f} | {r['fit_s']:.2f} | {r['compile_s']:.2f} | {r['max_rel_param_err']:.2e} | "
            f"{'yes' if r['finished'] else 'no'} | {r['status']} |"
        )
    lines += [
        "",
        f"* Speed ratio scipy / diffship: **{ratio_warm:.1f}x** warm (vs 2nd-call wall), "
        f"**{ratio_cold:.1f}x** including compilation (vs 1st-call wall)"
        + ("" if sp["finished"] else " — scipy was stopped by the time guard before reaching diffship's cost: "
           "lower bounds on the time it needs to get there (if it does)") + ".",
        f"* Same final cost (within 1 %): **{'yes' if same_cost else 'no'}** "
        f"(scipy {sp['cost']:.6g} vs diffship {warm.cost:.6g}, rel. diff "
        f"{abs(sp['cost'] - warm.cost) / warm.cost:.2e}).",
        f"* Consistency: the NumPy residual evaluated at diffship's solution gives cost {cost_check:.6g} "
        f"(rel. diff {rel_check:.1e} from diffship's).",
        f"* One NumPy simulation + residual: {t_sim * 1e3:.0f} ms. scipy f-evals = every residual evaluation "
        f"(one simulation each), {sp['fd_calls']} of them for 2-point finite differences; scipy's own nfev "
        f"(lmder calls, differences excluded) = {sp['nfev'] if sp['nfev'] is not None else 'n/a (stopped)'}; scipy iterations ≈ Jacobian evaluations = "
        f"finite-difference calls / {z0.size} (the last one is the Jacobian scipy forms at the solution). "
        f"diffship iterations = optimistix LM steps (accepted and rejected); its Jacobians are forward-mode "
        f"(no f-eval count). scipy tolerances: ftol = xtol = gtol = 1e-8, max_nfev = {max_nfev}, "
        f"x_scale = 'jac' (scipy's default, MINPACK's internal column scaling).",
        f"* Machine: platform.processor() `{env['processor']}` ({env['cpu_model'] or 'model unknown'}), {env['cpu_count']} CPUs, {env['platform']}; Python "
        f"{env['python']}, JAX {env['jax']} ({env['jax_backend']}), NumPy {env['numpy']}, SciPy {env['scipy']}.",
    ]
    md = "\n".join(lines) + "\n"
    print()
    print(md)
    (out_dir / f"{stem}.md").write_text(md)
    with open(out_dir / f"{stem}.csv", "w", newline="") as fh:
        keys = ["mode", "method", "cost", "iterations", "nfev", "wall_s", "fit_s", "compile_s",
                "max_rel_param_err", "finished", "status", "n_runs", "duration_s", "n_residuals", "n_unknowns",
                "ratio_scipy_over_diffship_warm", "ratio_scipy_over_diffship_cold", "same_cost_1pct",
                "processor", "cpu_model", "cpu_count", "jax", "numpy", "scipy"]
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        for r in rows:
            w.writerow({**r, "mode": "quick" if args.quick else "full", "n_runs": len(runs), "duration_s": duration,
                        "n_residuals": batch.n_residuals, "n_unknowns": z0.size,
                        "ratio_scipy_over_diffship_warm": f"{ratio_warm:.4g}",
                        "ratio_scipy_over_diffship_cold": f"{ratio_cold:.4g}", "same_cost_1pct": same_cost,
                        "processor": env["processor"], "cpu_model": env["cpu_model"], "cpu_count": env["cpu_count"], "jax": env["jax"],
                        "numpy": env["numpy"], "scipy": env["scipy"]})
    print(f"wrote {out_dir / (stem + '.md')} and {out_dir / (stem + '.csv')}")
    return 0
