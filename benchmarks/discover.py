"""Structure discovery on a USV with withheld terms (``python -m benchmarks discover [OUTDIR] [--null] [--hold H]``).

Truth: :mod:`benchmarks.independent.usv_terms` (NumPy, its own RK4; the seed-002 USV with added masses and
the withheld terms ``EXTRA``), noise at real-log levels. Training: steps, sines, chirp, zigzag (120 s,
10 Hz); held out: a pull-out and a fast run with sway-force pulses. Runs ``python -m diffship.discover``
and prints the held-out heading and yaw-rate RMSE of the base and selected structures beside the noise
floor and 1.5× the floor, the model error sqrt(RMSE² − noise²) relative to the base's, and the terms
found beside the truth's. ``--null``: the same runs from plain fossen3 (no extra terms): what is selected
and every term's inclusion probability. ``--hold zero``: the truth holds each input sample until the next
(a digital command) and discover is told so (``--input-hold zero``); without telling it, such a log reads half a
sample early (see :mod:`benchmarks.independent.usv_terms`); ``--hold zero-untold`` shows that case.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd

from benchmarks.independent.usv_terms import EXTRA, NOISE, run_table

TRAIN, HELD = ("steps", "sines", "chirp", "zigzag"), ("pullout", "fast_pulses")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", nargs="?", default="/tmp/diffship-discover", help="folder for the runs and results")
    ap.add_argument("--null", action="store_true", help="the same runs from plain fossen3 (no extra terms)")
    ap.add_argument("--hold", default="linear", choices=("linear", "zero", "zero-untold"))
    a = ap.parse_args(argv)
    return discover_runs(Path(a.out), null=a.null, hold=a.hold)


def discover_runs(out: Path, null: bool = False, hold: str = "linear") -> int:
    """Write the runs to ``out``, run ``python -m diffship.discover`` on them and print what it found."""
    told = hold != "zero-untold"
    hold = "zero" if hold == "zero-untold" else hold
    out.mkdir(parents=True, exist_ok=True)
    paths = {}
    truth = {} if null else EXTRA
    for i, k in enumerate(TRAIN + HELD):
        paths[k] = out / f"{k}.csv"
        pd.DataFrame(run_table(k, 120.0, 0.1, i, extra=truth, hold=hold)).to_csv(paths[k], index=False)
    cmd = [sys.executable, "-m", "diffship.discover", *(str(paths[k]) for k in TRAIN), "--validate",
           *(str(paths[k]) for k in HELD), "--model", "fossen3", "--vessel", "usv", "--no-prior", "--solver", "rk4",
           "--json", str(out / "discover.json"), "--save", str(out / "fit.json"), "--quiet", "--input-hold", hold if told else "linear"]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True)
    wall = time.perf_counter() - t0
    doc = json.loads((out / "discover.json").read_text())
    print("command:", " ".join(cmd))
    sel = doc["selected"]
    print(f"truth terms: {truth or 'none (plain fossen3)'}; wall {wall:.0f} s (discover itself {doc['seconds']:.0f} s)")
    for t, v in sel["terms"].items():
        print(f"selected {t:8s} {v['value']:10.1f} ± {v['stderr']:.1f} (truth {truth.get(t, 0.0):g}); inclusion "
              f"{v['inclusion_probability']:.2f}, equation-error screen {v['screen_inclusion']:.2f}")
    for t, v in sel["possible"].items():
        print(f"possible {t:8s} inclusion {v['inclusion_probability']:.2f} (truth {truth.get(t, 0.0):g})")
    for label, why in sel["not_selected"].items():
        print(f"not selected: {label}: {why}")
    oe = doc.get("oe_screen") or {}
    if oe:
        print("output-error screen path: " + ", ".join(f"{t} (T {T:.1f})" for t, T in zip(oe["path"], oe["statistic"])))
    for c in doc["candidates"]:
        print(f"  {' + '.join(c['terms']) or '(base)':40s} BIC {c['bic']:10.1f}  held-out/base "
              f"{c['held_out_relative_rmse']:.3f}  bootstrap wins {c['bootstrap_wins']:.2f}"
              + ("  <- selected" if c["selected"] else ""))
    for run in HELD:
        for c in ("psi", "r"):
            b = doc["base"]["validation"]["per_run"][run]["rmse"][c]
            s = doc["selected"]["validation"]["per_run"][run]["rmse"][c]
            n = NOISE[c]
            me = lambda x: math.sqrt(max(x * x - n * n, 0.0))  # noqa: E731
            print(f"{run:12s} {c:4s} base {b:.4g}  selected {s:.4g}  floor {n:.4g} (1.5x {1.5 * n:.4g})  "
                  f"model error selected/base {me(s) / max(me(b), 1e-12):.2f}")
    return 0
