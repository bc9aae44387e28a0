"""Estimators for sea data: output error (single and multiple shooting), prediction error (EKF),
equation error (Butterworth and EKF + RTS smoother), on runs with coloured process noise.

**Truth (written apart from the fitter)**: :mod:`benchmarks.estimators_truth` (plain NumPy models and
integrator, Ornstein–Uhlenbeck disturbances, white sensor noise). diffship only fits and judges.

**USV cases.** ``--runs`` training runs (default 2) of ``--duration`` s (default 300;
``--quick``: 120) at 10 Hz, random surge-thrust steps (``--design``: ``base`` 1500–6000 N held
40 s; ``rich`` 150–6000 N held 20 s, so that the linear surge damping X_u is seen at low speed;
``fast`` the same held 8 s — :data:`THRUST`; the experiment, not the estimator) and nozzle
zigzags, 10 free parameters, fitted channels u, v, r, start: the model
defaults (30–50 % off) and the equation-error estimate, reference priors off (they are the
defaults, 30–50 % off, and would judge the priors, not the estimators). Disturbance levels
(``--levels``): none, and 30 N / 12 N / 40 N·m sd with 8 s time constant (full run:
also ×2); data seeds ``--seeds``; estimators ``--methods``. Each estimator reports the worst and
median parameter error, each parameter's error in its own reported standard errors, how many
lie within 3, the held-out RMSE of u, v, r (a further run, same excitation kind, simulated
without disturbance or noise, from its true initial state) and the wall time.

**KVLCC2 convergence.** Zigzags (``--k-amps``, default 10/10 and 20/20; closed-loop rudder at
15.8°/s, 10 Hz, 10.23 rps) of ``--k-duration`` s (default 90), sensor noise only, the MMG
model's 10 default free parameters; ``--starts`` random starts (default 50; ``--quick``: 6),
each parameter uniform within ±50 % of the truth (``--spread``; of its scale where the truth is 0);
``--variants``: single shooting with the growing horizon (``single``), plain single shooting
(``plain``, whole runs at once: the usual baseline) and multiple shooting
(``multiple``, ``--segment`` s segments + polish). A start reached "the right optimum" when every
parameter is within 1 standard error of the plain fit started from the truth (:func:`judge`: costs
are not compared, each fit's noise weights being its own). ``--k-free study``: the KVLCC2 study's 33
coefficients; ``--k-dt``: sample interval of the fitted data; ``--k-dist``: OU disturbance level;
``--only-starts``: fit only some start numbers; ``--from-json``: table from a (partial) JSON.

Run::

    python -m benchmarks estimators [--quick] [--starts N] [--out benchmarks/results]

Writes ``OUT/estimators.md`` (``--quick``: ``estimators_quick.md``) and the JSON beside it.
Times are wall-clock on a shared machine (see the header of the results).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import time
from pathlib import Path

import numpy as np

import diffship  # noqa: F401  (float64)
from diffship.fit import (
    KalmanSmoother,
    OutputErrorOptions,
    PredictionErrorOptions,
    ShootingOptions,
    fit_equation_error,
    fit_multiple_shooting,
    fit_output_error,
    fit_prediction_error,
)
from diffship.metrics import evaluate
from diffship.models import MMG, Fossen3
from diffship.preprocess import Filter

from benchmarks.estimators_truth import (  # noqa: E402  (the NumPy truths)
    DEG, K2, K2_FREE, K2_NAMES, THRUST, USV, kvlcc2_runs, mmg_rhs, simulate_truth, usv_case,
)


# -- fits and judging ----------------------------------------------------------------------------
def _errors(res, truth):
    rel = {n: abs(res.params[n] - truth[n]) / abs(truth[n]) for n in res.free}
    in3 = sum(abs(res.params[n] - truth[n]) <= 3 * res.stderr[n] for n in res.free)
    return rel, in3


USV_METHODS = ("EE (Butterworth)", "EE (EKF + RTS smoother)", "OE single shooting", "OE multiple shooting (20 s)",
               "PEM (EKF, OU disturbance)")


def usv_estimators(train, methods=USV_METHODS):
    """The chosen estimators on the same runs, from the same candidate starts (the model defaults and
    the Butterworth equation-error estimate, always computed); ``{label: (FitResult, seconds)}``."""
    model = Fossen3()
    o = OutputErrorOptions(estimate_x0=("u", "v", "r"), reference_priors=False)
    ch = ("u", "v", "r")
    out = {}
    t0 = time.perf_counter()
    ee = fit_equation_error(model, train)
    out["EE (Butterworth)"] = (ee, time.perf_counter() - t0)
    starts = {"the equation-error estimate": {n: ee.params[n] for n in ee.free}}
    todo = {
        "EE (EKF + RTS smoother)": lambda: fit_equation_error(
            model, KalmanSmoother(channels=ch).apply(model, train)[0], flt=Filter("none")),
        "OE single shooting": lambda: fit_output_error(model, train, starts=starts, channels=ch, options=o),
        "OE multiple shooting (20 s)": lambda: fit_multiple_shooting(
            model, train, starts=starts, channels=ch, options=o, shooting=ShootingOptions(20.0)),
        "PEM (EKF, OU disturbance)": lambda: fit_prediction_error(
            model, train, starts=starts, channels=ch, options=o, noise=PredictionErrorOptions())}
    for label in methods:
        if label in todo:
            t0 = time.perf_counter()
            out[label] = (todo[label](), time.perf_counter() - t0)
    return {k: out[k] for k in methods if k in out}


def usv_rows(duration, levels, seed=0, design="base", n_runs=2, methods=USV_METHODS):
    """One row per estimator and level; each row also says how far the estimate is from single-shooting
    OE's, in OE's standard errors (the agreement check without disturbance)."""
    rows = []
    for scale in levels:
        train, held, x_held = usv_case(duration, scale, seed, design, n_runs)
        truth = {n: USV[n] for n in Fossen3().spec().free_names}
        fits = usv_estimators(train, methods)
        oe = fits.get("OE single shooting", (None,))[0]
        for label, (res, secs) in fits.items():
            rel, in3 = _errors(res, truth)
            ev = evaluate(res.model, [held], [x_held], channels=("u", "v", "r"), integrator=res.integrator)
            worst = max(rel, key=rel.get)
            in_se = {n: abs(res.params[n] - truth[n]) / res.stderr[n] for n in res.free}
            vs_oe = (max(abs(res.params[n] - oe.params[n]) / oe.stderr[n] for n in res.free) if oe is not None
                     else math.nan)
            rows.append({"case": f"USV {n_runs} × {duration:g} s ({design}), disturbance ×{scale:g}, seed {seed}",
                         "method": label, "converged": res.converged, "status": res.status,
                         "worst_param": worst, "worst_err_pct": 100 * rel[worst],
                         "worst_in_se": in_se[worst], "max_in_se": max(in_se.values()),
                         "median_err_pct": 100 * float(np.median(list(rel.values()))), "within_3se": in3,
                         "n_free": len(res.free), "held_rmse": {c: ev.rmse[c] for c in ("u", "v", "r")},
                         "seconds": secs, "noise": res.info.get("measurement_sd"),
                         "disturbance": res.info.get("process_sd"), "tau": res.info.get("disturbance_tau"),
                         "params": {n: res.params[n] for n in res.free}, "stderr": dict(res.stderr),
                         "rel_err": rel, "vs_oe_in_oe_se": vs_oe})
            print(f"{rows[-1]['case']:<26} {label:<28} worst {rel[worst] * 100:7.2f} % ({worst}, "
                  f"{in_se[worst]:.1f} se; max {max(in_se.values()):.1f} se) median {rows[-1]['median_err_pct']:6.2f} %"
                  f"  in 3 se {in3}/{len(res.free)}  held-out rmse u {ev.rmse['u']:.3g} v {ev.rmse['v']:.3g} "
                  f"r {ev.rmse['r']:.3g}  {secs:.1f} s  |Δ vs OE|/se_OE ≤ {vs_oe:.2f}  {res.status[:40]}", flush=True)
            print("    errors %: " + ", ".join(f"{n} {100 * rel[n]:.1f} ({in_se[n]:.1f} se)" for n in res.free),
                  flush=True)
    return rows


def start_departure(runs, start):
    """How far a start's model departs from the data: the largest |ψ_start − ψ_measured| [deg] over the runs,
    the NumPy truth model with the start's coefficients (δ0 added to the measured rudder) flown open loop on
    the measured rudder from the true initial state (RK4, 0.05 s steps). Context for a failed start."""
    p = {**K2, **{K2_NAMES.get(n, n): v for n, v in start.items() if n != "delta0"}}
    d0 = start.get("delta0", 0.0)
    worst = 0.0
    for run in runs:
        t = run.time
        inputs = np.stack([np.asarray(run.channels["delta"]) + d0, np.asarray(run.channels["n"])], 1)
        with np.errstate(all="ignore"):
            xs, _ = simulate_truth(lambda x, u, d: mmg_rhs(x, u, d, p), [0, 0, 0, 1.179, 0, 0], t, inputs,
                                   None, None, 8.0, substeps=max(1, round((t[1] - t[0]) / 0.05)))
        dev = np.abs(xs[:, 2] - np.asarray(run.channels["psi"]))
        worst = max(worst, float(np.nanmax(dev)) / DEG if np.all(np.isfinite(dev)) else math.inf)
    return worst


def kvlcc2_convergence(n_starts, seed=0, start_seed=None, variants=("single", "multiple"), duration=90.0,
                       amps=(10.0, 20.0), segment_s=10.0, spread=0.5, free_set="ten", dt=0.1, dist_level=0.0,
                       on_start=None, only=None, max_steps=None, gntol=None):
    """Single vs multiple shooting from random starts on the MMG KVLCC2 zigzags (sensor noise only).

    "Right optimum": every free parameter within one standard error (of the fit started from the
    truth, the reference) of the reference estimate (:func:`judge`; costs are not compared).
    ``only``: 1-based start numbers to fit (the others are drawn and skipped, so start *k* is the
    same start in every run with the same start seed).
    ``free_set``: a key of :data:`K2_FREE`; ``on_start(out)`` is called after every start (partial
    results survive a stopped run). ``max_steps``, ``gntol``: Levenberg–Marquardt steps per pass and the
    Gauss–Newton-step stopping tolerance (:class:`~diffship.fit.OutputErrorOptions`; default: its defaults)."""
    runs = kvlcc2_runs(seed, duration, amps, dt, dist_level)
    model = MMG()
    spec0 = model.spec() if K2_FREE[free_set] is None else model.spec().only_free(list(K2_FREE[free_set]))
    free = spec0.free_names
    truth = {n: K2.get(K2_NAMES.get(n, n), 0.0) for n in free}
    truth["delta0"] = 0.0
    lm = {k: v for k, v in (("max_steps", max_steps), ("gntol", gntol)) if v is not None}
    o = OutputErrorOptions(reference_priors=False, estimate_x0=("psi", "u", "v", "r"), **lm)
    plain = dataclasses.replace(o, warmup=0.0)
    ref = fit_output_error(model, runs, spec=spec0.with_values(truth), options=plain)
    print(f"reference fit from the truth: {ref.status}, cost {ref.cost:.6g}; "
          + ", ".join(f"{n} {ref.params[n]:.4g} ± {ref.stderr[n]:.2g}" for n in free), flush=True)
    rng = np.random.default_rng(seed + 1 if start_seed is None else start_seed)
    out = {"reference": {"converged": ref.converged, "params": ref.params, "stderr": ref.stderr, "cost": ref.cost},
           "setting": {"duration": duration, "amps": list(amps), "segment_s": segment_s, "spread": spread,
                       "free": list(free), "dt": dt, "disturbance_level": dist_level,
                       "max_steps": o.max_steps, "gntol": o.gntol},
           **{v: [] for v in variants}}
    for i in range(n_starts):
        start = {n: truth[n] + rng.uniform(-spread, spread) * (abs(truth[n]) if truth[n] else spec0[n].scale)
                 for n in free}
        if only is not None and i + 1 not in only:
            continue
        spec = spec0.with_values(spec0.nudged(start)[0])
        dep = start_departure(runs, start)
        todo = {"single": lambda s=spec: fit_output_error(model, runs, spec=s, options=o),
                "plain": lambda s=spec: fit_output_error(model, runs, spec=s, options=plain),
                "multiple": lambda s=spec: fit_multiple_shooting(model, runs, spec=s, options=plain,
                                                                 shooting=ShootingOptions(segment_s))}
        for key, fn in ((v, todo[v]) for v in variants):
            t0 = time.perf_counter()
            try:
                res = fn()
                in_se = max(abs(res.params[n] - ref.params[n]) / ref.stderr[n] for n in free)
                worst = max(abs(res.params[n] / truth[n] - 1) if truth[n] else 0.0 for n in free)
                status, cost, conv = res.status, res.cost, res.converged
                params, steps = {n: res.params[n] for n in free}, res.iterations
            except diffship.errors.DiffshipError as exc:
                in_se, worst, status, cost, conv = math.inf, math.inf, f"error: {exc}", math.inf, False
                params, steps = {}, 0
            out[key].append({"number": i + 1, "start": start, "start_psi_departure_deg": dep, "max_dev_in_ref_se": in_se, "worst_err": worst, "status": status,
                             "cost": cost, "converged": conv, "seconds": time.perf_counter() - t0,
                             "params": params, "steps": steps,
                             "dev_in_ref_se": {n: (params[n] - ref.params[n]) / ref.stderr[n] for n in params}})
            print(f"start {i + 1:2d} {key:<8} (start's ψ departs ≤ {dep:6.1f}°) dev {in_se:9.3g} ref se  "
                  f"cost {cost:.6g}  worst {worst:.3g} "
                  f"{status[:50]} {out[key][-1]['seconds']:.1f} s", flush=True)
        if on_start is not None:
            on_start(judge(out, variants))
    return judge(out, variants)


def judge(out, variants):
    """Mark each start's ``right_optimum``: every free parameter within 1 standard error (of the fit from the
    truth) of the fit from the truth. The earlier second test, a cost within 1e-4 relative of the lowest cost
    found, is kept only as ``cost_within_1e-4`` (not judged): with ``weights="noise"`` each fit re-weights
    its channels by its own first-pass residual RMS, so a fit far off (large residuals, large σ_c) can end
    with a *lower* cost than the right one (measured: 2734 against 2978 on the 5/5 zigzag, 560 se away)."""
    best = min([out["reference"]["cost"]] + [c["cost"] for v in variants for c in out[v]])
    out["best_cost"] = best
    for v in variants:
        for c in out[v]:
            c["right_optimum"] = bool(c["max_dev_in_ref_se"] <= 1.0)
            c["cost_within_1e-4"] = bool(c["cost"] <= best * (1 + 1e-4))
    return out


def write(out_dir: Path, quick: bool, usv, conv, argv, tag=""):
    tag = ("_quick" if quick else "") + tag
    (out_dir / f"estimators{tag}.json").write_text(json.dumps({"usv": usv, "kvlcc2": conv}, indent=1, default=str))
    lines = ["# Estimators for sea data (benchmarks/estimators.py)", "",
             f"Command: `python -m benchmarks estimators {' '.join(argv)}`; load average at the end "
             f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores (a shared machine: times are indicative).", "",
             "## USV, parameter errors and held-out prediction", "",
             "| case | method | conv. | worst error | worst in se | median error | within 3 se "
             "| held-out RMSE u, v, r | max abs diff from OE in OE se | wall s |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in usv:
        h = r["held_rmse"]
        lines.append(f"| {r['case']} | {r['method']} | {'yes' if r['converged'] else 'no'} "
                     f"| {r['worst_err_pct']:.2f} % ({r['worst_param']}) | {r['worst_in_se']:.1f} "
                     f"| {r['median_err_pct']:.2f} % | {r['within_3se']}/{r['n_free']} "
                     f"| {h['u']:.3g}, {h['v']:.3g}, {h['r']:.3g} | {r.get('vs_oe_in_oe_se', math.nan):.2f} "
                     f"| {r['seconds']:.1f} |")
    pem = [r for r in usv if r["method"].startswith("PEM")]
    if pem:
        lines += ["", "PEM noise estimates (measurement sd per channel; disturbance sd on the accelerations "
                  "[m/s², rad/s²] and time constant): " + "; ".join(
                      f"{r['case']}: {r['noise']}, {r['disturbance']}, τ {r['tau']:.3g} s" for r in pem),
                  "Truth: sensor u, v 0.05 m/s, r 0.00349 rad/s; disturbance ×1 on the accelerations about "
                  "30/5335 = 0.0056 m/s², 12/5535 = 0.0022 m/s², 40/28928 = 0.0014 rad/s², τ 8 s."]
    if conv:
        st = conv["setting"]
        lines += ["", f"## MMG KVLCC2 zigzags: convergence from random starts (±{100 * st['spread']:g} % of the truth)",
                  "",
                  f"{'/'.join(f'{a:g}' for a in st['amps'])} zigzags of {st['duration']:g} s "
                  f"(samples every {st.get('dt', 0.1):g} s), sensor noise, OU disturbance ×{st.get('disturbance_level', 0):g} "
                  f"(K2_DIST), {len(st.get('free', ())) or 10} free "
                  "parameters, no priors. "
                  "'Right optimum': every free parameter within 1 standard error (of the fit from the truth) of the "
                  "fit from the truth (costs are not compared: each fit's noise weights are its own, see judge). "
                  "Fit from the truth: " + ("converged." if conv["reference"]["converged"] else "NOT converged."),
                  "", ("| method | right optimum | says converged | starts whose ψ departs > 45° (start_departure): "
                       "right optimum | median wall s |"), "|---|---|---|---|---|"]
        names = {"single": "single shooting (growing horizon)", "plain": "single shooting (whole runs at once)",
                 "multiple": f"multiple shooting ({st['segment_s']:g} s segments, polish)"}
        for key, name in names.items():
            if key in conv:
                n, k = len(conv[key]), sum(c["right_optimum"] for c in conv[key])
                far = [c for c in conv[key] if c.get("start_psi_departure_deg", 0.0) > 45.0]
                lines.append(f"| {name} | {k}/{n} ({100 * k / max(n, 1):.0f} %) | "
                             f"{sum(c['converged'] for c in conv[key])}/{n} | "
                             f"{sum(c['right_optimum'] for c in far)}/{len(far)} | "
                             f"{np.median([c['seconds'] for c in conv[key]]):.1f} |")
        lines += per_start_table(conv, [k for k in names if k in conv])
    (out_dir / f"estimators{tag}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def per_start_table(conv, variants):
    """Markdown lines: one row per start, each variant's deviation from the reference (in its standard
    errors), right optimum, status, LM steps and wall time."""
    by = {v: {c["number"]: c for c in conv[v]} for v in variants}
    numbers = sorted(set().union(*(by[v] for v in variants))) if variants else []
    if not numbers:
        return []
    head = "| start | start's ψ departs [deg] | " + " | ".join(
        f"{v}: max dev [ref se] | {v}: right | {v}: status | {v}: steps | {v}: s" for v in variants) + " |"
    out = ["", "### Per start", "", head, "|" + "---|" * (2 + 5 * len(variants))]
    for k in numbers:
        cells = []
        dep = next(by[v][k]["start_psi_departure_deg"] for v in variants if k in by[v])
        for v in variants:
            c = by[v].get(k)
            if c is None:
                cells += ["not run"] + [""] * 4
                continue
            st = "converged" if c["status"] == "converged" else ("max steps" if "maximum number of steps" in c["status"]
                                                                 else c["status"][:40])
            cells += [f"{c['max_dev_in_ref_se']:.3g}", "yes" if c["right_optimum"] else "**no**", st,
                      str(c.get("steps", "")), f"{c['seconds']:.0f}"]
        out.append(f"| {k} | {dep:.1f} | " + " | ".join(cells) + " |")
    return out


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--quick", action="store_true")
    p.add_argument("--starts", type=int, default=None)
    p.add_argument("--skip", nargs="*", default=[], choices=("usv", "kvlcc2"))
    p.add_argument("--levels", nargs="*", type=float, default=None, help="disturbance levels (×30/12/40 N, N m)")
    p.add_argument("--tag", default="", help="suffix of the result files")
    p.add_argument("--duration", type=float, default=None,
                   help="USV training-run length [s] (default 300, --quick 120)")
    p.add_argument("--runs", type=int, default=2, help="USV training runs")
    p.add_argument("--design", default="base", choices=tuple(THRUST), help="USV surge-thrust design (THRUST)")
    p.add_argument("--seeds", nargs="*", type=int, default=[0], help="USV data seeds")
    p.add_argument("--methods", nargs="*", default=list(USV_METHODS), choices=USV_METHODS,
                   help="USV estimators (the Butterworth EE always runs: it is a start)")
    p.add_argument("--start-seed", type=int, default=None, help="seed of the random starts (default: data seed + 1)")
    p.add_argument("--variants", nargs="*", default=["single", "multiple"], choices=("single", "plain", "multiple"),
                   help="KVLCC2 fits: single (growing horizon), plain (single shooting, whole runs at once), multiple")
    p.add_argument("--k-duration", type=float, default=90.0, help="KVLCC2 zigzag length [s]")
    p.add_argument("--k-amps", nargs="*", type=float, default=[10.0, 20.0], help="KVLCC2 zigzag angles [deg]")
    p.add_argument("--segment", type=float, default=10.0, help="KVLCC2 multiple-shooting segment [s]")
    p.add_argument("--spread", type=float, default=0.5,
                   help="KVLCC2 starts: uniform within ± this fraction of the truth")
    p.add_argument("--k-free", default="ten", choices=tuple(K2_FREE),
                   help="KVLCC2 free set: the MMG default ten, or the KVLCC2 study's 33 (K2_FREE)")
    p.add_argument("--k-dt", type=float, default=0.1, help="KVLCC2 sample interval of the fitted data [s]")
    p.add_argument("--k-dist", type=float, default=0.0, help="KVLCC2 OU disturbance level (× K2_DIST, τ 8 s)")
    p.add_argument("--k-max-steps", type=int, default=None, help="KVLCC2: LM steps per pass (OutputErrorOptions)")
    p.add_argument("--k-gntol", type=float, default=None,
                   help="KVLCC2: LM Gauss–Newton-step stopping tolerance in standard errors (inf: the plain rule)")
    p.add_argument("--out", default=str(Path(__file__).resolve().parent / "results"))
    p.add_argument("--only-starts", nargs="*", type=int, default=None,
                   help="KVLCC2: fit only these (1-based) start numbers of the --starts drawn")
    p.add_argument("--from-json", default=None,
                   help="only rewrite the KVLCC2 table from a (partial) JSON of an earlier run (e.g. one stopped for time)")
    args = p.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.from_json:
        conv = json.loads(Path(args.from_json).read_text())["kvlcc2"]
        conv = judge(conv, [v for v in ("single", "plain", "multiple") if v in conv])
        write(out, args.quick, [], conv, argv if argv is not None else __import__("sys").argv[1:], args.tag)
        return
    levels = args.levels if args.levels is not None else ((0.0, 1.0) if args.quick else (0.0, 1.0, 2.0))
    duration = args.duration or (120.0 if args.quick else 300.0)
    usv = [] if "usv" in args.skip else [row for seed in args.seeds for row in usv_rows(
        duration, levels, seed, args.design, args.runs, tuple(args.methods))]
    starts = args.starts if args.starts is not None else (6 if args.quick else 50)
    partial = out / f"estimators{'_quick' if args.quick else ''}{args.tag}_partial.json"

    def dump(res):
        partial.write_text(json.dumps({"kvlcc2": res}, indent=1, default=str))

    conv = None if "kvlcc2" in args.skip else kvlcc2_convergence(
        starts, start_seed=args.start_seed, variants=tuple(args.variants), duration=args.k_duration,
        amps=tuple(args.k_amps), segment_s=args.segment, spread=args.spread, free_set=args.k_free, dt=args.k_dt,
        dist_level=args.k_dist, only=set(args.only_starts) if args.only_starts else None,
        on_start=dump, max_steps=args.k_max_steps, gntol=args.k_gntol)
    write(out, args.quick, usv, conv, argv if argv is not None else __import__("sys").argv[1:], args.tag)
