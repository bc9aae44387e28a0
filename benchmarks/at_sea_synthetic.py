"""At sea, synthetic: an autopilot in narrow-band waves; output error against prediction error, the loop test.

Independent truths (:mod:`benchmarks.independent.autopilot_waves`, NumPy only): a first-order Nomoto ship (K 0.08 1/s,
T 20 s, δ0 0.5°) steered by a PD autopilot with course changes, in a wave yaw disturbance of period 8 s (relative
damping 0.08, sd 0.004 rad/s²) with a random phase per run; three runs × 600 s at 2 Hz per seed, heading and yaw-rate
channels. Cases: ``waves`` (the autopilot in waves), ``calm`` (the same autopilot, no waves), ``open`` (waves,
the rudder a pre-drawn sequence: no feedback). Per seed and case:

* output error (the default fit) and prediction error with the Ornstein–Uhlenbeck and the ``wave`` disturbance:
  K, T1 with standard errors and their z against the truth;
* the wave's fitted period and intensity against the truth;
* the closed-loop test (:mod:`diffship.fit.feedback`) on the output-error fit's errors.

``python -m benchmarks at_sea_synthetic [--seeds 5] [--cases waves,calm,open]``; writes
``results/at_sea_synthetic.md`` and ``.csv``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.independent.autopilot_waves import autopilot_runs

CASES = {"waves": dict(), "calm": dict(waves=False), "open": dict(open_loop=True)}


def _runs(seed: int, case: str):
    from diffship.data import Run

    g = autopilot_runs(seed, **CASES[case])
    return [Run(x["name"], x["time"], x["channels"], {"source": "benchmarks.independent"}) for x in g], g[0]["truth"]


def one(seed: int, case: str) -> list[dict]:
    from diffship.fit import fit_output_error, fit_prediction_error
    from diffship.fit.feedback import loop_evidence
    from diffship.fit.prediction_error import PredictionErrorOptions
    from diffship.metrics import evaluate
    from diffship.models import Nomoto1

    runs, tv = _runs(seed, case)
    ch = ("psi", "r")
    rows = []
    fits = {"output error": lambda: fit_output_error(Nomoto1(), runs, channels=ch, throw=False)}
    for kind in ("ou", "wave"):
        fits[f"prediction error ({kind})"] = lambda kind=kind: fit_prediction_error(
            Nomoto1(), runs, channels=ch, noise=PredictionErrorOptions(disturbance=kind), throw=False)
    for label, f in fits.items():
        t0 = time.perf_counter()
        res = f()
        row = dict(seed=seed, case=case, method=label, seconds=time.perf_counter() - t0, status=res.status)
        for n in ("K", "T1"):
            se = res.stderr.get(n, np.nan)
            row.update({n: res.params[n], f"se_{n}": se, f"z_{n}": (res.params[n] - tv[n]) / se})
        if label == "output error":
            ev = evaluate(res.model, runs, channels=ch, fitted=res.channels, scales=res.channel_scales)
            loop = loop_evidence(res.model, runs, ev.simulated, ch)
            row.update(closed_loop=loop["closed"], loop_r2=max(t["partial_r2"] for t in loop["tests"]))
        if "wave" in label:
            row.update(wave_period=res.info.get("wave_period"), wave_damping=res.info.get("wave_damping"),
                       wave_sd=res.info.get("process_sd", {}).get("r"))
        rows.append(row)
        print(f"seed {seed} {case:5s} {label:26s} K {row['K']:.4f} (z {row['z_K']:+.1f})  T1 {row['T1']:.2f} "
              f"(z {row['z_T1']:+.1f})  {row['seconds']:.0f} s", flush=True)
    return rows


def write(df: pd.DataFrame, out: Path) -> None:
    df.to_csv(out / "at_sea_synthetic.csv", index=False)
    lines = ["# At sea, synthetic: autopilot in narrow-band waves", "",
             "Command: `python -m benchmarks at_sea_synthetic` (module docstring: the truth, the cases). Truth K 0.08 1/s,"
             " T1 20 s; wave period 8 s, sd 0.004 rad/s². z = (estimate − truth)/standard error.", "",
             "| case | method | K (median) | max \\|z_K\\| | T1 (median) | max \\|z_T1\\| | loop closed | wave period "
             "(median) | wave sd (median) | s per fit |", "|---|---|---|---|---|---|---|---|---|---|"]
    for (case, method), g in df.groupby(["case", "method"], sort=False):
        closed = f"{int(g['closed_loop'].sum())}/{len(g)}" if "closed_loop" in g and g["closed_loop"].notna().any() else ""
        wp = f"{g['wave_period'].median():.2f} s" if "wave_period" in g and g["wave_period"].notna().any() else ""
        ws = f"{g['wave_sd'].median():.4f}" if "wave" in method and "wave_sd" in g else ""
        lines.append(f"| {case} | {method} | {g['K'].median():.4f} | {g['z_K'].abs().max():.1f} | {g['T1'].median():.2f} | "
                     f"{g['z_T1'].abs().max():.1f} | {closed} | {wp} | {ws} | {g['seconds'].median():.0f} |")
    (out / "at_sea_synthetic.md").write_text("\n".join(lines) + "\n")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--cases", default="waves,calm,open")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for case in args.cases.split(","):
        for seed in range(args.seeds):
            rows += one(seed, case)
            write(pd.DataFrame(rows), out)
    print((out / "at_sea_synthetic.md").read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
