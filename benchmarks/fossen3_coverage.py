"""Accuracy and honesty of the default fossen3 output-error fit on independent noisy USV truths.

Problem: the 3-DOF water-jet USV of :mod:`benchmarks.independent.robust_truths` (code that shares nothing with
diffship), two runs × 300 s at 10 Hz of open-loop jet commands, sensor noise at the seed-002 levels on every
sample (GNSS position 0.5 m and velocity 0.05 m/s, heading 0.5°, rate gyro 0.2°/s), mass and inertia known
(fixed), the ten hydrodynamic coefficients free, no priors (``--no-prior``). For each noise seed the default fit
(``OutputError(reference_priors=False)``: initial states estimated within their noise, four starts, the GNSS
positions added where a Hausman test finds the fit with them agrees with the fit without: :mod:`diffship.fit.positions`)
and, beside it, the same fit with the first samples taken as exact starts (``--x0 data``), with ``--positions`` the
fit that always takes the positions as channels (``--channels x0 y0 psi u v r``), and with ``--no-positions`` the fit
that never does (``--positions off``). Beside :mod:`benchmarks.fossen3_crlb`: each fit's spread is the Cramér–Rao
bound of the channels it fits.

Reported: per coefficient the coverage of the 95 % intervals (θ̂ ± 1.96 se) over seeds, the largest relative
error and distance in standard errors, the first five seeds' worst coefficient, and the fits per second.

    python -m benchmarks fossen3_coverage [--seeds 50] [--duration 300] [--no-data-x0] [--positions] [--no-positions]
        [--out DIR]
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

import numpy as np

if __name__ == "__main__":
    sys.path[0] = str(Path(__file__).resolve().parents[1])  # run as a script: import `benchmarks` from the repo root

from benchmarks.independent import robust_truths as truths  # noqa: E402


def _runs(seed: int, duration: float):
    from diffship.data import Run

    recs = truths.usv_runs(seed, n_runs=2, duration=duration)
    return [Run(r["name"], r["time"], {k: v for k, v in r.items() if k not in ("name", "time", "truth")})
            for r in recs], recs[0]["truth"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=50)
    ap.add_argument("--duration", type=float, default=300.0)
    ap.add_argument("--no-data-x0", action="store_true", help="skip the --x0 data comparison")
    ap.add_argument("--positions", action="store_true", help="also the fit with the GNSS positions as channels "
                    "(--channels x0 y0 psi u v r, without the test)")
    ap.add_argument("--no-positions", action="store_true", help="also the fit that never fits the positions "
                    "(--positions off)")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = ap.parse_args(argv)
    from diffship.fit import OutputError, fit
    from diffship.models import Fossen3

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    free = truths.USV_FREE
    methods = {"default": OutputError(reference_priors=False)}
    if not args.no_data_x0:
        methods["x0 data"] = OutputError(reference_priors=False, estimate_x0=())
    if args.positions:
        methods["with positions"] = OutputError(reference_priors=False)
    if args.no_positions:
        methods["positions off"] = OutputError(reference_priors=False, positions="off")
    channels = {"with positions": ("x0", "y0", "psi", "u", "v", "r")}
    rows, secs = [], {m: [] for m in methods}
    for seed in range(args.seeds):
        runs, tv = _runs(seed, args.duration)
        model = Fossen3(m=tv["m"], Iz=tv["Iz"])
        spec = model.spec().only_free(free)
        for label, est in methods.items():
            t0 = time.perf_counter()
            res = fit(model, runs, est, spec=spec, channels=channels.get(label), throw=False)
            secs[label].append(time.perf_counter() - t0)
            for n in free:
                se = res.stderr.get(n, np.nan)
                rows.append(dict(seed=seed, method=label, param=n, truth=tv[n], estimate=res.params[n], stderr=se,
                                 z=(res.params[n] - tv[n]) / se, rel_err=(res.params[n] - tv[n]) / abs(tv[n]),
                                 usable=bool(res.usable), seconds=secs[label][-1],
                                 positions=",".join(c for c in res.channels if c in ("x0", "y0")) or "-",
                                 hausman_p=res.info.get("positions_test", {}).get("p_value", np.nan)))
        last = [r for r in rows if r["seed"] == seed and r["method"] == "default"]
        print(f"seed {seed}: default max |z| {max(abs(r['z']) for r in last):.2f}, max |rel| "
              f"{max(abs(r['rel_err']) for r in last):.2%}, {secs['default'][-1]:.1f} s", flush=True)
    with open(out / "fossen3_coverage.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    lines = [f"# fossen3 default fit on independent USV truths ({args.seeds} noise seeds, 2 runs × {args.duration:g} s "
             "at 10 Hz)", "",
             "Truth: `benchmarks/independent/robust_truths.usv_runs` (NumPy, shares no code with diffship); sensor "
             "noise on every sample; m, I_z fixed, 10 hydrodynamic coefficients free, no priors. Command: "
             f"`python -m benchmarks fossen3_coverage --seeds {args.seeds} --duration {args.duration:g}"
             + " --no-data-x0" * args.no_data_x0 + " --positions" * args.positions
             + " --no-positions" * args.no_positions + "`.", "",
             "| method | 95 % coverage (all) | lowest coefficient coverage | max \\|z\\| | max \\|rel. error\\| | "
             "median s per fit | fits per s | seeds fitting the positions | Hausman p: min, median |",
             "|---|---|---|---|---|---|---|---|---|"]
    for label in methods:
        rr = [r for r in rows if r["method"] == label]
        z = np.array([r["z"] for r in rr])
        cov = {n: np.mean([abs(r["z"]) < 1.96 for r in rr if r["param"] == n]) for n in free}
        low = min(cov, key=cov.get)
        med = float(np.median(secs[label]))
        seeds = {r["seed"]: r for r in rr}
        with_pos = sum(r["positions"] != "-" for r in seeds.values())
        ps = np.array([r["hausman_p"] for r in seeds.values()], dtype=float)
        ps = ps[np.isfinite(ps)]
        pcol = f"{ps.min():.3f}, {np.median(ps):.2f}" if ps.size else "—"
        lines.append(f"| {label} | {np.mean(np.abs(z) < 1.96):.1%} | {low} {cov[low]:.0%} | {np.max(np.abs(z)):.2f} | "
                     f"{np.max(np.abs([r['rel_err'] for r in rr])):.1%} | {med:.1f} | {1 / med:.2f} | "
                     f"{with_pos}/{len(seeds)} | {pcol} |")
    for label in methods:
        lines += ["", f"Per coefficient ({label} fit): coverage of the 95 % intervals, RMS relative error, largest |z|.",
                  "", "| coefficient | coverage | RMS rel. error | max \\|z\\| |", "|---|---|---|---|"]
        for n in free:
            rr = [r for r in rows if r["method"] == label and r["param"] == n]
            lines.append(f"| {n} | {np.mean([abs(r['z']) < 1.96 for r in rr]):.0%} | "
                         f"{np.sqrt(np.mean([r['rel_err'] ** 2 for r in rr])):.2%} | {max(abs(r['z']) for r in rr):.2f} |")
        lines += ["", f"First five seeds, {label} fit: the worst coefficient by relative error and by standard errors.",
                  "", "| seed | worst rel. error | worst \\|z\\| | within 5 % and 3 se |", "|---|---|---|---|"]
        for seed in range(min(5, args.seeds)):
            rr = [r for r in rows if r["method"] == label and r["seed"] == seed]
            wr = max(rr, key=lambda r: abs(r["rel_err"]))
            wz = max(rr, key=lambda r: abs(r["z"]))
            ok = all(abs(r["rel_err"]) < 0.05 and abs(r["z"]) < 3 for r in rr)
            lines.append(f"| {seed} | {wr['param']} {wr['rel_err']:+.1%} | {wz['param']} {wz['z']:+.2f} | "
                         f"{'yes' if ok else 'no'} |")
    text = "\n".join(lines)
    (out / "fossen3_coverage.md").write_text(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
