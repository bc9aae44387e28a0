"""Case ``rov`` (``fossen6_rov`` in the CSV): the 6-DOF ``Fossen6`` ROV (BlueROV2 Heavy).

What is measured: 2 training runs and 1 validation run of independent smoothed random
force/moment steps in all six DOF (30 s at 20 Hz, ROV-grade noise); all parameters free, start
±30 %. diffship equation error first, then output error on the nine attitude/velocity channels
started from the equation-error estimate (60 steps at most): parameter errors, validation NRMSE,
wall/compile time (the 12-state model's compilation dominates), memory. No NumPy peer.
"""

from __future__ import annotations

import numpy as np

from benchmarks.common.fitapi import fit_ee, fit_oe, fitted_model, fitted_params
from benchmarks.record import EE_KEYS, record_common, record_fit, say, timed
from diffship.synthetic import simulate_run

DEG = np.pi / 180.0
OE_KEYS = ("compile_s", "fit_s", "converged")
ROV_NOISE = {"x0": 0.1, "y0": 0.1, "z0": 0.02, "phi": 0.3 * DEG, "theta": 0.3 * DEG, "psi": 0.3 * DEG,
             "u": 0.01, "v": 0.01, "w": 0.01, "p": 0.2 * DEG, "q": 0.2 * DEG, "r": 0.2 * DEG}
ROV_AMPLITUDE = (40.0, 40.0, 40.0, 2.0, 2.0, 3.0)


def rov_case_runs(model, n_runs=2, duration=30.0, dt=0.05, noise=ROV_NOISE, seed=0):
    """Independent smoothed random force/moment steps in all six DOF (held 2–4 s)."""
    names = ("tau_x", "tau_y", "tau_z", "tau_k", "tau_m", "tau_n")
    out = []
    for i in range(n_runs):
        rng = np.random.default_rng(1000 * seed + i)
        t = np.arange(0.0, duration + dt / 2, dt)
        inp = {}
        for n, amp in zip(names, ROV_AMPLITUDE):
            k = max(1, int(round(rng.uniform(2.0, 4.0) / dt)))
            sig = np.repeat(rng.uniform(-amp, amp, size=t.size // k + 2), k)[: t.size]
            w = max(1, int(round(0.5 / dt)))
            inp[n] = np.convolve(np.concatenate([np.full(w, sig[0]), sig]), np.ones(w) / w, mode="valid")[1 : t.size + 1]
        out.append(simulate_run(model, t, inp, np.zeros(12), name=f"rov_{i}", noise=noise, seed=7 + 100 * seed + i))
    return out


def run(rec, quick, figs=None):
    from diffship.models import Fossen6

    case = "fossen6_rov"
    truth_model = Fossen6()
    truth = truth_model.param_values()
    tr = rov_case_runs(truth_model, n_runs=2, duration=30.0, dt=0.05, seed=0)
    va = rov_case_runs(truth_model, n_runs=1, duration=30.0, dt=0.05, seed=1)
    spec = truth_model.spec()
    free = spec.free_names
    spec = spec.with_values({n: truth[n] * (1.3 if i % 2 else 0.7) for i, n in enumerate(free)})
    chans = ("phi", "theta", "psi", "u", "v", "w", "p", "q", "r")
    say(f"{case}: equation error")
    ee, wall = timed(fit_ee, truth_model, tr, spec=spec)
    record_fit(rec, case, "noise=realistic", "diffship_ee", ee, wall, EE_KEYS)
    record_common(rec, case, "noise=realistic", "diffship_ee", fitted_model(ee), va, truth, free)
    say(f"{case}: output error ({len(free)} parameters)")
    ee_params = fitted_params(ee)
    oe, wall = timed(fit_oe, truth_model, tr, spec=spec, channels=chans, starts=[{n: ee_params[n] for n in free}],
                     weights="spread", max_steps=60)
    record_fit(rec, case, "noise=realistic", "diffship_oe", oe, wall, OE_KEYS)
    record_common(rec, case, "noise=realistic", "diffship_oe", fitted_model(oe), va, truth, free)


CASES = {"rov": run}
