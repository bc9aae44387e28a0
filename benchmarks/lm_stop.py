"""Cost of the Gauss–Newton-step stopping check on ordinary fits.

Fits the fossen3 test problem of ``tests/fit/test_output_error.py`` (3 × 60 s at 10 Hz,
realistic noise, seed 2, 10 free parameters from ±50 % of the truth, initial states of psi, u, v,
r estimated per run; default two-pass noise weighting) and a Nomoto 1 problem (2 × 120 s, psi and r initial values estimated), each twice in
one process (the second call reuses the compiled programs: its ``fit_seconds`` is the solve
alone), and prints the LM steps per pass, the warm solve time and the largest parameter error in
standard errors.

Run from the repository root::

    python -m benchmarks lm_stop [--gntol 0.05|inf]

``--gntol inf`` is the plain step/cost rule (what the solver did before the check).
"""

from __future__ import annotations

import argparse
import json
import time

from diffship.fit import OutputErrorOptions, fit_output_error
from diffship.models import Fossen3, Nomoto1
from diffship.synthetic import nomoto_runs, usv_runs, usv_truth


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--gntol", type=float, default=None, help="OutputErrorOptions.gntol (default: the options' default)")
    args = ap.parse_args(argv)
    extra = {} if args.gntol is None else {"gntol": args.gntol}
    truth = usv_truth().param_values()
    free = Fossen3().spec().free_names
    spec = Fossen3().spec().with_values({n: truth[n] * (0.5 if i % 2 else 1.5) for i, n in enumerate(free)})
    runs = usv_runs(3, 60.0, 0.1, noise="realistic", seed=2)
    nomoto_truth = Nomoto1(K=0.2, T1=8.0, delta0=0.01)
    n_runs = nomoto_runs(nomoto_truth, n_runs=2, duration=120.0, dt=0.1, noise="realistic", seed=3)
    n_spec = Nomoto1().spec().with_values({"K": 0.1, "T1": 16.0, "delta0": 0.0})
    out = {}
    for name, model, r, s, o, tv in [
        ("fossen3", Fossen3(), runs, spec, OutputErrorOptions(estimate_x0=("psi", "u", "v", "r"), **extra), truth),
        ("nomoto1", Nomoto1(), n_runs, n_spec, OutputErrorOptions(estimate_x0=("psi", "r"), **extra), nomoto_truth.param_values()),
    ]:
        for call in ("cold", "warm"):
            t0 = time.perf_counter()
            res = fit_output_error(model, r, spec=s, options=o)
            wall = time.perf_counter() - t0
        worst = max(abs(res.params[n] - tv[n]) / res.stderr[n] for n in res.free)
        out[name] = {"status": res.status, "steps_per_pass": list(res.info["steps_per_pass"]),
                     "warm_fit_seconds": round(res.fit_seconds, 3), "warm_wall_seconds": round(wall, 3),
                     "worst_error_in_se": round(worst, 3),
                     "params": {n: res.params[n] for n in res.free}}
        print(name, json.dumps({k: v for k, v in out[name].items() if k != "params"}), flush=True)
    return out
