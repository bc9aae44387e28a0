"""Coverage of the bootstrap 95 % intervals over seeds, beside the covariance intervals.

Problem (small enough for a shared 2-core CPU): Nomoto1 (K = 0.2 1/s, T1 = 8 s, δ0 = 0.01 rad), two
zigzag-like runs (``diffship.synthetic.nomoto_runs``) of ``--duration`` s at 0.2 s, output noise
"realistic" (heading 0.5°, rate gyro 0.2°/s, white) and **input noise**: the fit sees the rudder
angle plus white noise of ``--input-noise`` degrees (the simulation that made the data used the
true rudder). Per seed: ``fit_output_error`` (initial states estimated, no priors) and
``diffship.fit.bootstrap.bootstrap_fit`` with ``--resamples`` moving-block resamples; the truth is
inside a parameter's interval or not. Reported: coverage per parameter of the percentile and of the
covariance (θ̂ ± 1.96 se) intervals, with the binomial 95 % range of a coverage of 95 % over that
many seeds.

    python -m benchmarks bootstrap_coverage [--seeds 50] [--resamples 64] [--duration 60]
"""

from __future__ import annotations

import argparse
import math
import os
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

from diffship.data import Run
from diffship.fit import OutputErrorOptions, fit_output_error
from diffship.fit.bootstrap import bootstrap_fit
from diffship.models import Nomoto1
from diffship.synthetic import nomoto_runs

TRUTH = Nomoto1(K=0.2, T1=8.0, delta0=0.01)
OPTIONS = OutputErrorOptions(reference_priors=False, estimate_x0=("psi", "r"))


def noisy_input(run: Run, sd: float, rng) -> Run:
    ch = dict(run.channels)
    ch["delta"] = np.asarray(ch["delta"]) + rng.normal(0.0, sd, size=len(run.time))
    return Run(run.name, run.time, ch, dict(run.metadata, input_noise_rad=sd))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=50)
    ap.add_argument("--resamples", type=int, default=64)
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--input-noise", type=float, default=0.5, help="rudder noise [deg]")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "bootstrap_coverage.md"))
    args = ap.parse_args(argv)
    load0, t0 = " ".join(f"{x:.2f}" for x in os.getloadavg()), time.perf_counter()
    names = ("K", "T1", "delta0")
    truth = np.array([TRUTH.param_values()[n] for n in names])
    hit_b, hit_c, n_ok, secs, blocks = [], [], [], [], []
    for seed in range(args.seeds):
        rng = np.random.default_rng(10_000 + seed)
        runs = [noisy_input(r, math.radians(args.input_noise), rng)
                for r in nomoto_runs(TRUTH, n_runs=2, duration=args.duration, dt=0.2, noise="realistic", seed=seed)]
        res = fit_output_error(Nomoto1(), runs, options=OPTIONS)
        if not res.converged:
            print(f"seed {seed}: fit did not converge ({res.status}); skipped", flush=True)
            continue
        b = bootstrap_fit(res, runs, spec=Nomoto1().spec(), options=OPTIONS, n=args.resamples, seed=seed)
        se = np.array([res.stderr[n] for n in names])
        hit_b.append(b.contains(dict(zip(names, truth))))
        hit_c.append(np.abs(b.estimate - truth) <= 1.96 * se)
        n_ok.append(b.n_ok)
        secs.append(b.seconds)
        blocks.append(b.block)
        print(f"seed {seed}: percentile {hit_b[-1].astype(int)}, covariance {hit_c[-1].astype(int)}, "
              f"{b.n_ok}/{b.n} refits, block {b.block}, {b.seconds:.1f} s", flush=True)
    hb, hc = np.array(hit_b), np.array(hit_c)
    S = len(hb)
    lo, hi = 0.95 - 1.96 * math.sqrt(0.95 * 0.05 / S), 0.95 + 1.96 * math.sqrt(0.95 * 0.05 / S)
    load1 = " ".join(f"{x:.2f}" for x in os.getloadavg())
    L = ["## Bootstrap 95 % intervals: coverage over seeds", "",
         f"Nomoto1 (K = 0.2 1/s, T1 = 8 s, δ0 = 0.01 rad), 2 runs × {args.duration:g} s at 0.2 s, output noise "
         f"realistic (heading 0.5°, yaw rate 0.2°/s), input noise {args.input_noise:g}° on the rudder the fit sees; "
         f"{args.resamples} moving-block resamples per seed (block length chosen from the residuals: "
         f"{min(blocks)}–{max(blocks)} samples); {S} seeds with a converged fit. One run; 2 shared CPUs, load "
         f"{load0} at the start, {load1} at the end; total {(time.perf_counter() - t0) / 60:.1f} min; bootstrap "
         f"refits {np.median(secs):.1f} s per seed (median, {args.resamples} refits, compile included on the first).",
         "", f"A 95 % coverage over {S} seeds lies in [{lo:.2f}, {hi:.2f}] with 95 % probability.", "",
         "| parameter | percentile bootstrap | covariance θ̂ ± 1.96 se |", "|---|---:|---:|"]
    for j, n in enumerate(names):
        L.append(f"| {n} | {hb[:, j].mean():.2f} | {hc[:, j].mean():.2f} |")
    L.append(f"| all three at once | {hb.all(axis=1).mean():.2f} | {hc.all(axis=1).mean():.2f} |")
    L.append(f"| all parameters pooled | {hb.mean():.3f} | {hc.mean():.3f} |")
    L += ["", f"Refits converged: {int(np.sum(n_ok))} of {S * args.resamples}.",
          f"Command: `python -m benchmarks bootstrap_coverage --seeds {args.seeds} --resamples {args.resamples} "
          f"--duration {args.duration:g} --input-noise {args.input_noise:g}`"]
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text("\n".join(L) + "\n")
    print("\n".join(L))
