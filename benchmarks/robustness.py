r"""The robustness matrix: one fit, one answer, whatever the rate, the path or the options left at their defaults.

Every **case** (independent noisy truths made by :mod:`benchmarks.independent.robust_truths`, which shares no
code with diffship; the bundled SSPA zigzag; the HSVA KVLCC2 zigzags where ``../shared/data`` has them) is
fitted under every **variant** of what a user may leave at its default or change:

* ``default`` — ``OutputError()``, four starts;
* ``rate`` — the runs resampled (``Run.resample``) to a coarser sample interval; for the independent truths, the
  same experiment logged at that interval (regenerated with the same seed: its own noise draws). A subsampled
  command log is not the command the vessel had: linear interpolation between every other sample cuts the
  corners of the jet commands, the heading integrates that, and the USV's optimum at 5 Hz moved with it (heading
  residuals correlated over 30 samples, Nrdot 3.6 deviations away) while the same runs logged at 5 Hz fit white;
* ``x0 data`` — the data's filtered first sample taken as the exact initial state (``--x0 data``);
* ``starts 1`` / ``starts 16`` / ``starts 64 whole`` — one start; sixteen; sixty-four started on the whole
  runs (no warm-up): the **best** the search can find, the reference of every row (``--quick``: sixteen);
* ``no warm-up`` — ``warmup=0``;
* ``rk4`` / ``tsit5`` — the hand-written RK4 / diffrax Tsit5 (adaptive within each sample).

The **best** cell is the one with the lowest objective among the cells that solve the default problem (the
sixty-four whole-run starts among them: a cell that finds a better point than they do is the reference).
Each cell is judged on **one fixed scale**: the objective :math:`F` of the reference problem
(:func:`diffship.fit.weights.concentrated_cost` — the likelihood with each channel's noise level unknown, on
effective samples — plus the prior rows of the initial states and of the parameters), evaluated at the cell's
parameters on the case's reference data, every run's start estimated with the parameters held
(:func:`diffship.initial.estimate_starts`) with the best cell's channel scales and correlation times. A cell
**lands** when :math:`F - F_\text{best} \le 0.5` (one standard error along one direction of the likelihood) and
every free parameter is within one of the best cell's standard errors of the best cell's value. The ``rate``
variant fits a subset of the samples, whose estimate scatters about the whole set's with covariance
:math:`\Sigma_v - \Sigma` (a subset's minus the whole set's; :math:`\Sigma_v + \Sigma` for an independent truth
logged at the coarser rate, whose noise is its own). Its parameters are judged in the standard deviations
:math:`\sqrt{se_v^2 - se^2}` against the two-sided 95 % family-wise bound for ``p`` parameters,
:math:`\Phi^{-1}(1 - 0.025/p)`; its objective on the whole data rises by
:math:`\tfrac12\Delta\theta^\top\Sigma^{-1}\Delta\theta`, whose mean is :math:`\tfrac12\operatorname{tr}A` and
variance :math:`\tfrac12\operatorname{tr}A^2` with :math:`A = \Sigma^{-1}\Sigma_v - I`, and may rise by the mean
plus two standard deviations (white residuals sampled half as often: :math:`A = I`, ``p/2 + √(2p)``). A cell that cannot land says why (``x0 data`` changes the problem: a noisy first
sample held exactly; ``starts 1`` is no search).

    python benchmarks/robustness.py            # every case (KVLCC2 where ../shared/data has it)
    python benchmarks/robustness.py --quick    # the CI subset, under a minute on 2 cores
    python benchmarks/robustness.py --timing-only --cases sspa,usv   # the default cell's time alone

Writes ``benchmarks/results/robustness[_quick].md`` and ``.csv``. ``--timing-only`` uses only the API that
every diffship version since the one driver has (``fit(model, runs, OutputError(...), n_starts=...)``), so
the same command times an older checkout (``PYTHONPATH=<old>/src``).
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import math
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

if __name__ == "__main__":
    sys.path[0] = str(Path(__file__).resolve().parents[1])  # run as a script: import `benchmarks` from the repo root

from benchmarks.independent import robust_truths as truths  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"
SHARED = Path(os.environ.get("DIFFSHIP_SHARED_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))


# -- cases -------------------------------------------------------------------------------------------------
@dataclasses.dataclass
class Case:
    """A fit problem: its model and runs, the free set and the coarser rate of its ``rate`` variant."""

    name: str
    model: Callable
    runs: Callable  # () -> list[Run] at the reference rate
    coarse_dt: float
    free: tuple[str, ...] | None = None
    fixed: dict | None = None
    reference_priors: bool = True
    note: str = ""
    native: Callable | None = None  # (dt) -> list[Run]: the same experiment logged at another rate (independent truths)


def _runs_from(records) -> list:
    from diffship.data import Run

    out = []
    for rec in records:
        ch = {k: np.asarray(v) for k, v in rec.items() if k not in ("name", "time", "truth") and not k.startswith("clean")}
        out.append(Run(rec["name"], np.asarray(rec["time"]), ch))
    return out


def _sspa():
    from diffship.data import example_runs

    return [example_runs("sspa_zigzag")[0]]


def _sspa10():
    return [r.resample(0.1) for r in _sspa()]


def _kvlcc2():
    from diffship.data import load_runs

    names = ("Z_10_05", "Z_20_05", "Z_35_05", "Z_20_10_S")
    return load_runs([SHARED / "kvlcc2_hsva" / f"HSVA_CPMC_KVLCC2_{n}.csv" for n in names], rudder_sign="port")


def cases(quick: bool) -> dict[str, Case]:
    from diffship.models import Fossen3, get_model
    from diffship.vessel import load_vessel

    usv_truth = truths.USV()
    out = {
        "nomoto1": Case("nomoto1", lambda: get_model("nomoto1"),
                        lambda: _runs_from(truths.nomoto1_runs(0, duration=60.0 if quick else 120.0)), 0.2,
                        note="independent first-order Nomoto truth, two closed-loop zigzags, 0.5° / 0.2°/s noise",
                        native=lambda dt: _runs_from(truths.nomoto1_runs(0, duration=60.0 if quick else 120.0, dt=dt))),
        "sspa": Case("sspa", lambda: get_model("nomoto2"), _sspa10 if quick else _sspa, 0.2 if quick else 0.1,
                     note="the bundled SSPA 20/20 zigzag (real model test), second-order Nomoto model"
                     + (" at 10 Hz" if quick else ", 50 Hz")),
    }
    if quick:
        return out
    out["nomoto2"] = Case("nomoto2", lambda: get_model("nomoto2"), lambda: _runs_from(truths.nomoto2_runs(0)), 0.2,
                          note="independent second-order Nomoto truth, two closed-loop 120-s zigzags, 0.5° / 0.2°/s noise",
                          native=lambda dt: _runs_from(truths.nomoto2_runs(0, dt=dt)))
    out["usv"] = Case("usv", lambda: Fossen3(m=usv_truth.m, Iz=usv_truth.Iz), lambda: _runs_from(truths.usv_runs(0)),
                      0.2, free=truths.USV_FREE, reference_priors=False,
                      note="independent 3-DOF USV truth, 2 runs × 300 s, seed-002 sensor noise, --no-prior",
                      native=lambda dt: _runs_from(truths.usv_runs(0, dt=dt)))
    if (SHARED / "kvlcc2_hsva").is_dir():
        out["kvlcc2"] = Case("kvlcc2", lambda: get_model("mmg").with_vessel(load_vessel("kvlcc2_model")), _kvlcc2, 0.2,
                             note="real HSVA KVLCC2 zigzags 10/5, 20/5, 35/5, 20/10-S (20 Hz), MMG, reference priors")
    return out


# -- variants ----------------------------------------------------------------------------------------------
VARIANTS = ("default", "rate", "x0 data", "starts 1", "starts 16", "no warm-up", "rk4", "tsit5", "starts 64 whole")
QUICK_VARIANTS = ("default", "rate", "x0 data", "starts 1", "no warm-up", "starts 16 whole")
WHY = {"x0 data": "the data's first sample held as the exact start is another problem (a noisy first sample "
                  "biases every estimate); --x0 data is an override whose cost the report states",
       "starts 1": "one start is no search: it ends in the basin its start lies in"}


def _variant(case: Case, name: str, runs):
    """``(runs, estimator keywords, n_starts)`` of one variant."""
    from diffship.integrators import RK4, Tsit5

    kw: dict = {"reference_priors": case.reference_priors}
    n = None
    if name == "rate":
        runs = case.native(case.coarse_dt) if case.native else [r.resample(case.coarse_dt) for r in runs]
    elif name == "x0 data":
        kw["estimate_x0"] = ()
    elif name.startswith("starts"):
        n = int(name.split()[1])
        if name.endswith("whole"):
            kw["warmup"] = 0.0
    elif name == "no warm-up":
        kw["warmup"] = 0.0
    elif name == "rk4":
        kw["integrator"] = RK4()
    elif name == "tsit5":
        kw["integrator"] = Tsit5()
    return runs, kw, n


def _spec(case: Case, model):
    spec = model.spec()
    if case.free is not None:
        spec = spec.only_free(case.free)
    return spec.with_values(case.fixed) if case.fixed else spec


def fit_cell(case: Case, variant: str, runs):
    from diffship.fit import OutputError, fit

    model = case.model()
    runs_v, kw, n = _variant(case, variant, runs)
    t0 = time.perf_counter()
    res = fit(model, runs_v, OutputError(**kw), spec=_spec(case, model), n_starts=n, throw=False)
    return res, time.perf_counter() - t0


# -- the fixed scale ---------------------------------------------------------------------------------------
def objective(res, runs, ref) -> float:
    """F of the reference problem at ``res``'s parameters (module docstring)."""
    from diffship.fit.weights import concentrated_cost
    from diffship.initial import channel_noise, estimate_starts, estimated_states
    from diffship.simulate import simulate_run

    model = res.model
    chans = tuple(ref.channels)
    scales = dict(ref.channel_scales)
    tau = np.asarray([ref.info["correlation_time"][c] for c in chans]) if ref.info.get("correlation_time") \
        else np.ones(len(chans))
    starts = estimate_starts(model, runs, chans, scales, integrator=ref.integrator)
    n = max(r.n for r in runs)
    e = np.zeros((len(runs), n, len(chans)))
    mask = np.zeros((len(runs), n), bool)
    ys = np.zeros_like(e)
    for i, (run, x0) in enumerate(zip(runs, starts)):
        sol = simulate_run(model, run, x0, ref.integrator)
        for j, c in enumerate(chans):
            y = np.unwrap(run[c]) if c in model.angle_outputs else np.asarray(run[c])
            d = np.asarray(sol.ys)[:, model.output_names.index(c)] - y
            e[i, :run.n, j] = np.arctan2(np.sin(d), np.cos(d)) if c in model.angle_outputs else d
            ys[i, :run.n, j] = y
        mask[i, :run.n] = True
    noise = channel_noise(ys, mask)
    prior = []
    for i, x0 in enumerate(starts):
        for s in estimated_states(model, chans):
            if s in chans:
                prior.append((x0[model.state_names.index(s)] - ys[i, 0, chans.index(s)]) / noise[chans.index(s)])
    for name, row in (ref.info.get("priors") or {}).items():
        prior.append((res.params[name] - row["mean"]) / row["sd"])
    return concentrated_cost(e.reshape(-1), mask, np.ones(len(chans)), tau, np.asarray(prior))


# -- the matrix --------------------------------------------------------------------------------------------
def run_case(case: Case, variants, say) -> list[dict]:
    runs = case.runs()
    cells = {}
    for v in variants:
        say(f"  {case.name}: {v}...")
        cells[v] = fit_cell(case, v, runs)
    # the best: the many-start cell's problem, and of every cell solving it the lowest objective on its scale
    ref = next(v for v in variants if v.endswith("whole"))
    scale_ref = cells[ref][0]
    fs = {v: objective(res, runs, scale_ref) if math.isfinite(res.cost) else math.inf for v, (res, _) in cells.items()}
    ref = min((v for v in cells if v not in WHY or v == ref), key=lambda v: fs[v])
    best = cells[ref][0]
    rows = []
    for v, (res, secs) in cells.items():
        f = objective(res, runs, scale_ref) if math.isfinite(res.cost) else math.inf
        # a fit to a subset of the data (a coarser rate) differs from the full one by sqrt(se_v² − se²) standard
        # deviations, one to the same experiment logged at that rate (independent noise) by sqrt(se_v² + se²);
        # every other variant fits the same data
        sign = 1.0 if case.native else -1.0
        se = {n: math.sqrt(max(res.stderr.get(n, 0.0) ** 2 + sign * best.stderr[n] ** 2, best.stderr[n] ** 2))
              if v == "rate" else best.stderr[n] for n in best.free}
        z = {n: (res.params[n] - best.params[n]) / se[n] for n in best.free
             if se.get(n, 0) and math.isfinite(se[n])}
        rows.append(dict(case=case.name, variant=v, seconds=secs, usable=bool(res.usable), status=res.status,
                         objective=f, params={n: res.params[n] for n in best.free}, z=z,
                         reached=res.starts.reached if res.starts else 0, n_starts=len(res.starts.labels) if res.starts else 0))
    f_best = next(r["objective"] for r in rows if r["variant"] == ref)
    # how many times fewer samples the rate cell fitted (its runs are not made again)
    k = best.info["n_residuals"] / max(cells["rate"][0].info["n_residuals"], 1) if "rate" in cells else 1.0
    for r in rows:
        r["best"] = r["variant"] == ref
    for r in rows:
        r["delta_objective"] = r["objective"] - f_best
        r["max_abs_z"] = max((abs(v) for v in r["z"].values()), default=math.nan)
        # a subset of the data: the objective on the full data rises by ½ Δθᵀ Σ⁻¹ Δθ (module docstring)
        tol, zmax = (rate_allowance(best, cells[r["variant"]][0], independent=case.native is not None, ratio=k)
                     if r["variant"] == "rate" else (0.5, 1.0))
        r["tolerance"] = tol
        r["lands"] = bool(r["delta_objective"] <= tol and r["max_abs_z"] <= zmax)
        r["why"] = "" if r["lands"] else WHY.get(r["variant"], "DOES NOT LAND")
    return rows


def rate_allowance(best, sub, independent: bool = False, ratio: float = 2.0) -> tuple[float, float]:
    """How far a fit to a subset of the samples (``sub``) may land from the whole set's (``best``): the objective's
    rise, mean plus two standard deviations of :math:`\\tfrac12\\Delta\\theta^\\top\\Sigma^{-1}\\Delta\\theta` with
    :math:`\\Delta\\theta \\sim N(0, \\Sigma_v - \\Sigma)` (``independent``: the same experiment logged at that rate,
    its own noise, :math:`\\Sigma_v + \\Sigma`), and the family-wise 95 % bound on each parameter's |z|. Each
    eigenvalue of :math:`A` is at most what white residuals give, ``ratio − 1`` (``ratio + 1``) for ``ratio`` times
    fewer samples: standard errors estimated from a few effective samples (one 40-s zigzag) would otherwise make
    the allowance as loose as their noise."""
    from scipy.stats import norm

    p = len(best.free)
    zmax = float(norm.ppf(1.0 - 0.025 / max(p, 1)))
    cov_b, cov_v = np.asarray(best.covariance, dtype=float), np.asarray(sub.covariance, dtype=float)
    if cov_b.shape != (p, p) or cov_v.shape != (p, p) or not np.all(np.isfinite(cov_b)) or not np.all(np.isfinite(cov_v)):
        k = ratio + 1.0 if independent else ratio - 1.0  # white residuals: A = (ratio ∓ 1) I
        return 0.5 * k * p + math.sqrt(2.0 * k * k * p), zmax
    w, u = np.linalg.eigh(cov_b)
    half = u @ np.diag(1.0 / np.sqrt(np.maximum(w, 1e-300))) @ u.T  # Σ^{-1/2}
    a = np.clip(np.linalg.eigvalsh(half @ cov_v @ half) + (1.0 if independent else -1.0), 0.0,
                ratio + 1.0 if independent else max(ratio - 1.0, 0.0))
    return 0.5 * float(np.sum(a)) + 2.0 * math.sqrt(0.5 * float(np.sum(a ** 2))), zmax


def write(rows, cases_, out: Path, stem: str) -> None:
    out.mkdir(parents=True, exist_ok=True)
    with open(out / f"{stem}.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["case", "variant", "seconds", "usable", "objective", "delta_objective", "max_abs_z", "lands", "why",
                    "params"])
        for r in rows:
            w.writerow([r["case"], r["variant"], f"{r['seconds']:.2f}", r["usable"], f"{r['objective']:.6f}",
                        f"{r['delta_objective']:.4f}", f"{r['max_abs_z']:.3f}", r["lands"], r["why"],
                        " ".join(f"{k}={v:.6g}" for k, v in r["params"].items())])
    lines = [f"# Robustness matrix ({stem})", "",
             "Each case fitted under each variant; **F − F_best**: the reference problem's objective (likelihood "
             "with unknown channel noise levels on effective samples, plus prior rows) at the cell's parameters minus "
             "that of the best cell (the lowest objective of the cells that solve the default problem, the 64 starts on the "
             "whole runs among them; 16 with --quick; marked *); **max |z|**: the largest parameter "
             "distance from the best cell in its standard errors (rate: in the standard deviation of a subset's "
             "estimate about the whole set's). A cell lands when F − F_best ≤ 0.5 and max |z| ≤ 1 (rate: F − F_best within "
             "the mean plus two standard deviations of the rise a subset's estimate has, its allowance in the note, "
             "and max |z| within the 95 % family-wise bound for the free parameters).",
             "", "Command: `python benchmarks/robustness.py" + (" --quick`" if stem.endswith("quick") else "`"), ""]
    for name, case in cases_.items():
        rr = [r for r in rows if r["case"] == name]
        if not rr:
            continue
        lines += [f"## {name}", "", case.note, "", "| variant | lands | F − F_best | max \\|z\\| | time [s] | usable | note |",
                  "|---|---|---|---|---|---|---|"]
        for r in rr:
            lines.append(f"| {r['variant']}{' *' if r.get('best') else ''} | {'yes' if r['lands'] else 'NO'} | {r['delta_objective']:+.3f} | "
                         f"{r['max_abs_z']:.2f} | {r['seconds']:.1f} | {'yes' if r['usable'] else 'no'} | {r['why']}"
                         + (f" allowance {r['tolerance']:.2f}" if r["variant"] == "rate" else "") + " |")
        lines.append("")
    default_times = [r["seconds"] for r in rows if r["variant"] == "default"]
    lines += [f"Median time of the default cell over the cases: {np.median(default_times):.1f} s (first cell of a case "
              "includes its compilation).", ""]
    (out / f"{stem}.md").write_text("\n".join(lines))


def timing_only(names, say) -> list[tuple[str, float]]:
    """The default cell of each case, timed with the API older checkouts have too."""
    from diffship.fit import OutputError, fit

    out = []
    for name, case in cases(False).items():
        if names and name not in names:
            continue
        runs = case.runs()
        model = case.model()
        t0 = time.perf_counter()
        fit(model, runs, OutputError(reference_priors=case.reference_priors), spec=_spec(case, model))
        out.append((name, time.perf_counter() - t0))
        say(f"{name}: {out[-1][1]:.1f} s")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the CI subset (under a minute on 2 cores)")
    ap.add_argument("--cases", default="", help="comma-separated case names (default: all)")
    ap.add_argument("--timing-only", action="store_true", help="time the default cell of each case")
    ap.add_argument("--out", default=str(RESULTS))
    args = ap.parse_args(argv)
    names = [c for c in args.cases.split(",") if c]
    say = lambda s: print(s, flush=True)  # noqa: E731
    if args.timing_only:
        timing_only(names, say)
        return 0
    all_cases = cases(args.quick)
    chosen = {k: v for k, v in all_cases.items() if not names or k in names}
    rows = []
    for case in chosen.values():
        rows += run_case(case, QUICK_VARIANTS if args.quick else VARIANTS, say)
    write(rows, chosen, Path(args.out), "robustness_quick" if args.quick else "robustness")
    bad = [r for r in rows if not r["lands"] and r["variant"] not in WHY]
    for r in rows:
        say(f"{r['case']:>8} {r['variant']:>16}: {'lands' if r['lands'] else 'NO':>5}  ΔF {r['delta_objective']:+.3f}  "
            f"max|z| {r['max_abs_z']:.2f}  {r['seconds']:.1f} s")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
