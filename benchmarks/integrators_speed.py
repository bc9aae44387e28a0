"""Integrators compared on the fossen3 output-error problem: compile, simulate, Jacobian, whole fit.

The same problem as ``fossen3_speed.py`` (seed-002 USV truth, realistic noise, 10 free
parameters, start ±50 %, initial states of the fitted channels estimated), fitted with each of
diffship's integrators in one process:

* ``diffrax-rk4``: diffrax's stage machinery (``ClassicalRK4`` tableau) stepped on the sample grid;
* ``rk4``: the same classical RK4 written out by hand;
* ``diffrax-tsit5``: diffrax's Tsit5 stepped on the sample grid (5th order, 6 stages);
* ``tsit5``: diffrax Tsit5 with a PID controller inside every sample interval (adaptive).

Reported per integrator: compile time of the residual, Jacobian and LM programs; one batched
simulation and one Jacobian (warm, median of repeats); the whole warm fit; final cost and the
largest parameter difference to the ``diffrax-rk4`` fit.

    python -m benchmarks integrators_speed [--runs 3] [--duration 300] [--out FILE]
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import jax
import numpy as np

import diffship  # noqa: F401  (float64)
from diffship import compiled
from diffship.fit import OutputErrorOptions, fit_output_error
from diffship.fit.kernel import Kernel, kernel_data
from diffship.fit.output_error import channel_spread, x0_scales
from diffship.fit.problem import make_batch
from diffship.integrators import get_integrator
from diffship.models import Fossen3
from diffship.synthetic import usv_runs, usv_truth

NAMES = ("diffrax-rk4", "rk4", "diffrax-tsit5", "tsit5")
CHANNELS = ("psi", "u", "v", "r")


def _median_time(fn, repeats=5):
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn())
        out.append(time.perf_counter() - t0)
    return statistics.median(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--duration", type=float, default=300.0)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "integrators_speed.md"))
    a = ap.parse_args(argv)
    truth = usv_truth().param_values()
    runs = usv_runs(a.runs, a.duration, 0.1, noise="realistic", seed=2)
    free = Fossen3().spec().free_names
    start = {n: truth[n] * (1.5 if i % 2 else 0.5) for i, n in enumerate(free)}
    fixed = {n: truth[n] for n in Fossen3().spec().fixed_names}
    spec = Fossen3().spec().with_values({**fixed, **start})
    model = Fossen3().with_params(spec.values())
    batch = make_batch(model, runs, CHANNELS)
    est = model.states_for_channels(CHANNELS)
    rows, ref = [], None
    for name in NAMES:
        integ = get_integrator(name)
        kern = Kernel(spec=spec.structural(), out_idx=tuple(model.output_names.index(c) for c in CHANNELS),
                      angle=tuple(c == "psi" for c in CHANNELS),
                      x0_idx=tuple(model.state_names.index(s) for s in est), integrator=integ)
        data = kernel_data(model, batch.ts, batch.us, batch.ys, batch.mask, batch.x0, channel_spread(batch),
                           x0_scale=x0_scales(model, batch, est))
        z = np.concatenate([spec.to_z(), np.zeros(len(runs) * len(est))])
        compiled.clear()
        res, c_res = kern.compiled("residuals", z, data)
        jac, c_jac = kern.compiled("jacobian", z, data)
        t_sim = _median_time(lambda: res(z, data))
        t_jac = _median_time(lambda: jac(z, data))
        opts = OutputErrorOptions(estimate_x0=est, weights="spread", integrator=integ)
        compiled.clear()
        first = fit_output_error(Fossen3(), runs, spec=spec, channels=CHANNELS, options=opts)
        warm = fit_output_error(Fossen3(), runs, spec=spec, channels=CHANNELS, options=opts)
        if ref is None:
            ref = warm.params
        dp = max(abs(warm.params[n] - ref[n]) / abs(ref[n]) for n in free)
        rows.append(dict(integrator=name, describe=integ.describe(), compile_residual=c_res, compile_jacobian=c_jac,
                         compile_fit=first.compile_seconds, simulate_ms=1e3 * t_sim, jacobian_ms=1e3 * t_jac,
                         fit_s=warm.fit_seconds, steps=warm.iterations, cost=warm.cost, max_param_diff=dp,
                         status=warm.status))
        print(rows[-1], flush=True)
    lines = [
        "# Integrators on the fossen3 output-error problem",
        "",
        f"`python -m benchmarks integrators_speed --runs {a.runs} --duration {a.duration:g}` "
        f"({a.runs} runs × {a.duration:g} s at 10 Hz, {len(free)} free parameters + {len(runs) * len(est)} initial "
        "states, start ±50 %, weights = spread). One process; 2-core CPU; timings noisy, compare within the table.",
        "",
        "| integrator | compile residual [s] | compile Jacobian [s] | compile fit [s] | simulate [ms] | Jacobian [ms] "
        "| warm fit [s] | LM steps | final cost | max rel. param. diff. to diffrax-rk4 |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(f"| {r['integrator']} | {r['compile_residual']:.2f} | {r['compile_jacobian']:.2f} | "
                     f"{r['compile_fit']:.2f} | {r['simulate_ms']:.1f} | {r['jacobian_ms']:.1f} | {r['fit_s']:.2f} | "
                     f"{r['steps']} | {r['cost']:.6g} | {r['max_param_diff']:.1e} |")
    lines += ["", *(f"- `{r['integrator']}`: {r['describe']} ({r['status']})" for r in rows), ""]
    Path(a.out).write_text("\n".join(lines))
    print("\n".join(lines))
    return 0
