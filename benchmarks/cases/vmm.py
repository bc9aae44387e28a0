"""Case ``vmm`` (``vmm_linear_ship`` in the CSV): the ``VMMLinear`` reference ship (prime system).

What is measured: 2 training and 2 validation open-loop alternating-rudder runs (10°–25°, 2.3°/s)
with ±20–30 % thrust steps, 300 s at 2 Hz (quick: 200 s), realistic noise; all parameters free,
start ±30 %. For diffship output error (u, v, r initial states estimated) and equation error
(= seed 000's per-DOF OLS of inverse-dynamics forces): parameter errors, validation NRMSE, the
10/10 and 20/20 zigzag overshoot errors and the turning circle's tactical diameter and advance of
the fitted model against the truth (closed loop, ``diffship.manoeuvres``), wall/compile time,
memory. No NumPy peer (it would need a NumPy VMM).
"""

from __future__ import annotations

import numpy as np

from benchmarks.common.fitapi import fit_ee, fit_oe, fitted_model
from benchmarks.record import EE_KEYS, record_common, record_fit, say, timed
from diffship.synthetic import rudder_sequence, simulate_run

DEG = np.pi / 180.0
OE_KEYS = ("compile_s", "fit_s", "converged")


def vmm_case_runs(model, n_runs=2, duration=300.0, dt=0.5, noise="realistic", seed=0, first=0):
    """Open-loop alternating-rudder runs (10°–25°, 2.3°/s) with ±20–30 % thrust steps."""
    from diffship.models.vmm import approach_thrust

    T0 = approach_thrust(float(model.X0), float(model.XT), float(model.U0), float(model.L), float(model.rho))
    out = []
    for j in range(n_runs):
        i = first + j
        t = np.arange(0.0, duration + dt / 2, dt)
        amp = [10, -20, 15, -25][i % 4] * DEG
        period = [60.0, 80.0, 70.0, 90.0][i % 4]
        delta = rudder_sequence(t, amp, period, rate=2.3 * DEG, start=5.0)
        thrust = T0 * (1 + [0.3, -0.3, 0.2, -0.2][i % 4] * ((t > 0.3 * duration) & (t < 0.75 * duration)))
        x0 = np.array([0.0, 0.0, 0.0, float(model.U0), 0.0, 0.0])
        out.append(simulate_run(model, t, {"delta": delta, "thrust": thrust}, x0, name=f"zigzag_{i}", noise=noise,
                                seed=100 * seed + i))
    return out, T0


def manoeuvre_errors(truth_model, init, T0):
    """Zigzag overshoot errors [deg] and relative turning-circle errors of a model against the truth."""
    from diffship.manoeuvres import turning_circle, turning_metrics, zigzag, zigzag_metrics

    def zig(m):
        out = {}
        try:
            for a in (10.0, 20.0):
                zr = zigzag_metrics(zigzag(m, init, inputs={"thrust": T0}, rudder_deg=a, duration=300.0, dt=0.5))
                zt = zigzag_metrics(zigzag(truth_model, init, inputs={"thrust": T0}, rudder_deg=a, duration=300.0, dt=0.5))
                out[f"err_overshoot1_{a:g}_{a:g}"] = zr.first_overshoot - zt.first_overshoot
                out[f"err_overshoot2_{a:g}_{a:g}"] = zr.second_overshoot - zt.second_overshoot
            tm = turning_metrics(turning_circle(m, init, inputs={"thrust": T0}, duration=400.0, dt=0.5))
            tt = turning_metrics(turning_circle(truth_model, init, inputs={"thrust": T0}, duration=400.0, dt=0.5))
            out["rel_err_tactical_diameter"] = (tm.tactical_diameter - tt.tactical_diameter) / tt.tactical_diameter
            out["rel_err_advance"] = (tm.advance - tt.advance) / tt.advance
        except Exception as exc:
            say(f"  manoeuvre metrics failed: {exc}")
        return out

    return zig


def run(rec, quick, figs=None):
    from diffship.models import VMMLinear

    case = "vmm_linear_ship"
    truth_model = VMMLinear()
    truth = truth_model.param_values()
    dur = 200.0 if quick else 300.0
    tr, T0 = vmm_case_runs(truth_model, n_runs=2, duration=dur, noise="realistic", seed=0)
    va, _ = vmm_case_runs(truth_model, n_runs=2, duration=dur, noise="realistic", seed=1, first=2)
    spec = truth_model.spec()
    free = spec.free_names
    start = {n: truth[n] * (1.3 if i % 2 else 0.7) for i, n in enumerate(free)}
    spec = spec.with_values(start)
    zig = manoeuvre_errors(truth_model, {"u": float(truth_model.U0)}, T0)

    say(f"{case}: output error")
    oe, wall = timed(fit_oe, truth_model, tr, spec=spec, estimate_x0=("u", "v", "r"), weights="spread")
    record_fit(rec, case, "noise=realistic", "diffship_oe", oe, wall, OE_KEYS)
    record_common(rec, case, "noise=realistic", "diffship_oe", fitted_model(oe), va, truth, free, zig)
    say(f"{case}: equation error (= per-DOF OLS of inverse-dynamics forces, seed 000's way)")
    ee, wall = timed(fit_ee, truth_model, tr, spec=spec)
    record_fit(rec, case, "noise=realistic", "diffship_ee", ee, wall, EE_KEYS)
    record_common(rec, case, "noise=realistic", "diffship_ee", fitted_model(ee), va, truth, free, zig)


CASES = {"vmm": run}
