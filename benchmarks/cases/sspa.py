"""Case ``sspa`` (``sspa_zigzag_real`` in the CSV): the real SSPA 20/20 zigzag bundled with diffship.

What is measured: the linear Nomoto model fitted by every method (:func:`.nomoto.nomoto_methods`)
to the first 25 s of the run (resampled to 10 Hz) and validated on the whole run by open-loop
simulation with the measured rudder: validation NRMSE of psi and r, the error of the simulated
first overshoot against the measured one, wall/compile time. No truth: no parameter errors.
"""

from __future__ import annotations

from benchmarks.cases.nomoto import nomoto_methods
from benchmarks.record import say
from diffship.metrics import evaluate


def run(rec, quick, figs=None):
    from diffship.data import example_runs
    from diffship.manoeuvres import zigzag_metrics

    case = "sspa_zigzag_real"
    run_ = example_runs("sspa_zigzag")[0].resample(0.1)
    t_split = run_.time[0] + 25.0
    train = [run_.slice(None, t_split)]
    val = [run_]

    def zig(m):
        ev = evaluate(m, [run_])
        sim = run_.with_channels(psi=ev.simulated[run_.name]["psi"], r=ev.simulated[run_.name]["r"])
        try:
            zm = zigzag_metrics(run_, switch_deg=20.0, rudder_deg=20.0)
            zs = zigzag_metrics(sim, switch_deg=20.0, rudder_deg=20.0)
            return {"err_overshoot1_20_20": zs.first_overshoot - zm.first_overshoot}
        except Exception as exc:
            say(f"  zigzag metrics failed: {exc}")
            return {}

    say(f"{case}: train on the first 25 s, validate on the whole run (open loop, measured rudder)")
    start = {"K": 0.3, "T1": 3.0, "delta0": 0.0}
    nomoto_methods(rec, case, "train=first25s", train, val, None, None, start=start, zig=zig)


CASES = {"sspa": run}
