"""Timing of the gap diagnosis on the issue's reference problem (issue 5, done-when).

fossen3 (USV test truth) with a hidden constant current, 4 training runs × 500 samples and 2
held-out runs at 10 Hz, realistic noise; all 12 candidate effects (11 applicable: no wind
measured). Reports the screening time (first call, compilation included) and the whole
diagnosis with its refits.

    python benchmarks/diagnose_timing.py
"""

import sys
import time
from pathlib import Path

import numpy as np

import diffship
from diffship.diagnose import diagnose
from diffship.models.effects import augment
from diffship.models import Fossen3
from diffship.synthetic import simulate_run, usv_excitation, usv_truth


def main():
    truth = augment(usv_truth(), "current", Vcx=0.15, Vcy=-0.1)
    runs = []
    for i in range(6):
        t, inp = usv_excitation(49.9, 0.1, seed=7100 + i)
        x0 = np.asarray(truth.initial_state({"u": 2.0}))
        runs.append(simulate_run(truth, t, inp, x0, name=f"usv{i}", noise="realistic", seed=1000 + i))
    t0 = time.perf_counter()
    d = diagnose(Fossen3(), runs[:4], runs[4:], progress=lambda s: print(s, file=sys.stderr, flush=True))
    total = time.perf_counter() - t0
    lines = ["# diagnose timing (fossen3, hidden current, 4 × 500 samples train, 2 held out)", "",
             f"- samples per training run: {runs[0].n}",
             f"- selected: {d.selected}; shrink {d.shrink:.2f}",
             *[f"- {k}: {v:.1f} s" for k, v in d.timings.items()],
             f"- total diagnosis: {total:.1f} s"]
    text = "\n".join(lines)
    print(text)
    out = Path(__file__).parent / "results" / "diagnose_timing.md"
    out.write_text(text + "\n")


if __name__ == "__main__":
    main()
