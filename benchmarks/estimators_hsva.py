"""Estimators on real data: the HSVA KVLCC2 zigzags fitted by each estimator.

The same problem for every estimator: the MMG model (:func:`diffship.models.mmg.kvlcc2_mmg`,
published KVLCC2 L7 values as start), the free set and priors of the KVLCC2 study
(:data:`diffship.studies.kvlcc2.DEFAULT_FREE`, 33 coefficients, published values as ±50 %
priors), the four training zigzags of the study (10/5, 20/5, 35/5, 20/10-S), first ``--horizon``
seconds at ``--dt``, channels ψ, u, v, r. Estimators:

* ``output-error``: single shooting (:func:`diffship.fit.fit_output_error`);
* ``multiple-shooting``: :func:`diffship.fit.shooting.fit_multiple_shooting` (``--segment`` s
  segments, then the single-shooting polish);
* ``prediction-error``: :func:`diffship.fit.prediction_error.fit_prediction_error` (EKF
  innovations, Ornstein–Uhlenbeck disturbance on u, v, r, noise levels estimated);
* ``equation-error``: the MMG model has no equation-error form (its forces are not linear in
  the coefficients through the rudder and propeller inflow models); the row says so.

Judged on what the training runs never showed (held-out numbers first): every other HSVA zigzag
flown closed loop by the fitted model with the HSVA autopilot
(:func:`diffship.studies.kvlcc2.predict_zigzags`): first- and second-overshoot errors; and the 35°
turning circle (a manoeuvre type not in the training data): tactical diameter in ship lengths
against the free-running measurements, 3.1–3.3 L.

    python -m benchmarks estimators_hsva [--estimators output-error,prediction-error]

Writes ``benchmarks/results/estimators_hsva.md`` and ``.json``. Needs ``../shared/data`` (the
HSVA files may not be copied into the repository): exits with a message where it is absent.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

import diffship  # noqa: F401  (float64)
from diffship.data import kvlcc2_runs
from diffship.errors import DataError
from diffship.fit import OutputErrorOptions, fit_output_error
from diffship.fit.prediction_error import PredictionErrorOptions, fit_prediction_error
from diffship.fit.shooting import ShootingOptions, fit_multiple_shooting
from diffship.manoeuvres.drive import turning_circle
from diffship.manoeuvres.imo import turning_metrics
from diffship.models.mmg import kvlcc2_mmg
from diffship.studies.kvlcc2 import DEFAULT_CHANNELS, DEFAULT_FREE, DEFAULT_TRAIN, HELM_RATE_DEG_S, predict_zigzags

OUT = Path(__file__).resolve().parent / "results"
ESTIMATORS = ("output-error", "multiple-shooting", "prediction-error", "equation-error")
LENGTH = 7.0  # KVLCC2 L7 model [m]


def _fit(name, model, spec, train, o, segment, say):
    if name == "output-error":
        return fit_output_error(model, train, spec=spec, channels=DEFAULT_CHANNELS, options=o, progress=say)
    if name == "multiple-shooting":
        return fit_multiple_shooting(model, train, spec=spec, channels=DEFAULT_CHANNELS, options=o,
                                     shooting=ShootingOptions(segment_s=segment), progress=say)
    if name == "prediction-error":
        return fit_prediction_error(model, train, spec=spec, channels=DEFAULT_CHANNELS, options=o,
                                    noise=PredictionErrorOptions(), progress=say)
    raise ValueError(name)


def _tactical(model) -> dict[str, float]:
    out = {}
    for side in ("starboard", "port"):
        tc = turning_circle(model, {"u": 1.179}, inputs={"n": 10.23}, duration=120.0,
                            rudder_rate_deg_s=HELM_RATE_DEG_S, first=side)
        out[side] = float(turning_metrics(tc, length=LENGTH).in_lengths()["tactical_diameter"])
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--estimators", default=",".join(ESTIMATORS))
    p.add_argument("--horizon", type=float, default=100.0, help="fitted seconds per training run")
    p.add_argument("--dt", type=float, default=0.2, help="fit sample interval [s]")
    p.add_argument("--segment", type=float, default=20.0, help="multiple-shooting segment length [s]")
    p.add_argument("--max-steps", type=int, default=60)
    p.add_argument("--tag", default="")
    a = p.parse_args(argv)
    try:
        runs = {r.name.replace("KVLCC2_", ""): r for r in kvlcc2_runs()}
    except DataError as exc:
        print(f"HSVA KVLCC2 data not available (../shared/data/kvlcc2_hsva): {exc}")
        return 2
    validate = tuple(k for k in runs if k not in DEFAULT_TRAIN)
    roles = {**{k: "train" for k in DEFAULT_TRAIN}, **{k: "validate" for k in validate}}
    model = kvlcc2_mmg()
    spec = model.spec().only_free(list(DEFAULT_FREE))
    train = [runs[k].resample(a.dt).slice(None, runs[k].time[0] + a.horizon) for k in DEFAULT_TRAIN]
    o = OutputErrorOptions(max_steps=a.max_steps)
    rows = []
    for name in [s.strip() for s in a.estimators.split(",") if s.strip()]:
        if name not in ESTIMATORS:
            p.error(f"unknown estimator {name!r}; choose from {', '.join(ESTIMATORS)}")
        print(f"[{time.strftime('%H:%M:%S')}] {name} ...", flush=True)
        if name == "equation-error":
            rows.append(dict(estimator=name, note="not available: the MMG model has no equation-error form "
                                                   "(rudder and propeller inflow make its forces nonlinear in the coefficients)"))
            continue
        t0, c0 = time.perf_counter(), time.process_time()
        res = _fit(name, model, spec, train, o, a.segment, lambda s: print("   ", s, flush=True))
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        table, _, _ = predict_zigzags(res.model, [runs[k] for k in (*DEFAULT_TRAIN, *validate)], roles)
        v = table[table.role == "validate"]
        td = _tactical(res.model)
        row = dict(estimator=name, converged=bool(res.converged), status=str(res.status), wall_s=wall, cpu_s=cpu,
                   held_out_first=dict(zip(v.test, v.err_first_cl.astype(float))),
                   held_out_second=dict(zip(v.test, v.err_second_cl.astype(float))),
                   max_abs_first=float(np.max(np.abs(v.err_first_cl))),
                   median_abs_first=float(np.median(np.abs(v.err_first_cl))),
                   median_abs_second=float(np.nanmedian(np.abs(v.err_second_cl))),
                   tactical_L=td, params={k: float(res.params[k]) for k in ("Yv", "Yr", "Nv", "Nr", "C1", "delta0")})
        if name == "prediction-error":
            row["noise"] = {k: res.info.get(k) for k in ("measurement_sd", "process_sd", "disturbance_tau") if k in res.info}
        rows.append(row)
        print(f"    held-out first overshoot: max |err| {row['max_abs_first']:.2f}°, median {row['median_abs_first']:.2f}°; "
              f"tactical diameter {td['starboard']:.2f} / {td['port']:.2f} L; {wall:.0f} s", flush=True)
        _write(rows, a, validate)
    _write(rows, a, validate)
    return 0


def _write(rows, a, validate):
    OUT.mkdir(exist_ok=True)
    stem = f"estimators_hsva{a.tag}"
    (OUT / f"{stem}.json").write_text(json.dumps(rows, indent=1, default=str))
    cmd = "python -m benchmarks estimators_hsva " + " ".join(sys.argv[1:])
    lines = [f"# Estimators on the HSVA KVLCC2 zigzags (real data)", "",
             f"Command: `{cmd.strip()}`; MMG, {len(DEFAULT_FREE)} coefficients free with the published values as ±50 % "
             f"priors; trained on {', '.join(DEFAULT_TRAIN)} (first {a.horizon:g} s at {a.dt:g} s, channels "
             f"{', '.join(DEFAULT_CHANNELS)}); held out: {', '.join(validate)}, flown closed loop with the HSVA autopilot. "
             f"Machine: {os.cpu_count()} CPUs, load {os.getloadavg()[0]:.1f} at the end (shared; timings disturbed).", "",
             "Held-out first and second overshoot errors [°] (predicted − measured), and the 35° turning circle "
             "(not in the training data; free-running measurements 3.1–3.3 L):", "",
             "| estimator | max \\|err\\| first | median \\|err\\| first | median \\|err\\| second | tactical diameter S / P [L] | converged | wall [s] |",
             "|---|---:|---:|---:|---|---|---:|"]
    for r in rows:
        if "note" in r:
            lines.append(f"| {r['estimator']} | – | – | – | – | {r['note']} | – |")
            continue
        lines.append(f"| {r['estimator']} | {r['max_abs_first']:.2f} | {r['median_abs_first']:.2f} | {r['median_abs_second']:.2f} | "
                     f"{r['tactical_L']['starboard']:.2f} / {r['tactical_L']['port']:.2f} | {r['converged']} ({r['status']}) | {r['wall_s']:.0f} |")
    lines += ["", "Per held-out run, first-overshoot error [°]:", ""]
    fitted = [r for r in rows if "note" not in r]
    if fitted:
        lines.append("| run | " + " | ".join(r["estimator"] for r in fitted) + " |")
        lines.append("|---|" + "---:|" * len(fitted))
        for k in validate:
            lines.append(f"| {k} | " + " | ".join(f"{r['held_out_first'][k]:+.2f}" for r in fitted) + " |")
    for r in fitted:
        if r.get("noise"):
            lines += ["", f"Noise levels estimated by prediction error: `{json.dumps(r['noise'], default=str)}`"]
    (OUT / f"{stem}.md").write_text("\n".join(lines) + "\n")
