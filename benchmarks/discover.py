"""Structure discovery on the done-when scenario of issue 29 (``python benchmarks/discover.py OUTDIR``).

Truth: :mod:`benchmarks.independent.usv_terms` (NumPy, its own RK4; the seed-002 USV with added masses and
the withheld terms ``EXTRA``), noise at real-log levels. Training: steps, sines, chirp, zigzag (120 s,
10 Hz); held out: a pull-out and a fast run with sway-force pulses. Runs ``python -m diffship.discover``
and prints the held-out heading and yaw-rate RMSE of the base and selected structures beside the noise
floor and 1.5× the floor, and the model error sqrt(RMSE² − noise²) relative to the base's.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from independent.usv_terms import EXTRA, NOISE, run_table  # noqa: E402

TRAIN, HELD = ("steps", "sines", "chirp", "zigzag"), ("pullout", "fast_pulses")


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    paths = {}
    for i, k in enumerate(TRAIN + HELD):
        paths[k] = out / f"{k}.csv"
        pd.DataFrame(run_table(k, 120.0, 0.1, i)).to_csv(paths[k], index=False)
    cmd = [sys.executable, "-m", "diffship.discover", *(str(paths[k]) for k in TRAIN), "--validate",
           *(str(paths[k]) for k in HELD), "--model", "fossen3", "--vessel", "usv", "--no-prior", "--solver", "rk4",
           "--json", str(out / "discover.json"), "--save", str(out / "fit.json"), "--quiet"]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True)
    wall = time.perf_counter() - t0
    doc = json.loads((out / "discover.json").read_text())
    print("command:", " ".join(cmd))
    print(f"truth terms: {EXTRA}; selected: {doc['selected']['terms']}; wall {wall:.0f} s")
    for run in HELD:
        for c in ("psi", "r"):
            b = doc["base"]["validation"]["per_run"][run]["rmse"][c]
            s = doc["selected"]["validation"]["per_run"][run]["rmse"][c]
            n = NOISE[c]
            me = lambda x: math.sqrt(max(x * x - n * n, 0.0))  # noqa: E731
            print(f"{run:12s} {c:4s} base {b:.4g}  selected {s:.4g}  floor {n:.4g} (1.5x {1.5 * n:.4g})  "
                  f"model error selected/base {me(s) / max(me(b), 1e-12):.2f}")


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "/tmp/diffship-discover"))
