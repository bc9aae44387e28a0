"""Is an injected water drift the best explanation of the real logs? The HSVA KVLCC2 zigzags with a drift put in.

``withheld_real`` injects a uniform water drift (0.05 m/s towards 0.8 rad NED: positions + v_c·t, over-ground
u, v + Rᵀ(ψ) v_c; exact, since a uniform current leaves the hydrodynamics in the water frame unchanged) into the
real HSVA zigzags and asks the diagnosis which effect the logs carry. On these logs a force fixed to the hull
(``constant_force``) explains the held-out runs better than the current, and the verdict is a tie
(:mod:`diffship.diagnose.rivals`). This benchmark asks the question below the diagnosis: does the model with the
*true* current fit the logs better than the model with the rival?

Each row is one output-error fit (:func:`diffship.fit.fit`, ``OutputError()`` defaults) of the MMG model on the
four training zigzags with the drift, its default free set refitted from the published values, plus:

- ``none``: no effect;
- ``current (free)``: the current ``Vcx, Vcy`` estimated;
- ``current (held at the truth)``: the current fixed at the injected value;
- ``constant_force``: ``Y0, N0`` estimated;
- ``constant_force + current``: both estimated.

Judged by the Gaussian log-likelihood of the training residuals at each fit's own channel variances,
:math:`-\\log L = \\sum_c \\tfrac{N_c}{2}\\,(\\log 2\\pi\\hat\\sigma_c^2 + 1)` per sample (comparable between the
rows: the same data and channels), and by the held-out runs' RMS errors (free simulation from initial states estimated
by the one initial-state rule, :func:`diffship.metrics.evaluate`), the three zigzags the diagnosis validates on.

Usage: ``python -m benchmarks drift_truth [--drift 0.05]`` (needs ``../shared/data``; about 3 min on 2 cores).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from diffship.data import kvlcc2_runs
from diffship.fit import OutputError, fit
from diffship.metrics import evaluate
from diffship.models import get_model
from diffship.models.effects import augment

from benchmarks.common.injections import inject_current
from benchmarks.withheld_real import DRIFT_DIR, TRAIN, VALIDATE  # the same runs and drift direction

OUT = Path(__file__).resolve().parent / "results"
CHANNELS = ("x0", "y0", "psi", "u", "v", "r")


def neg_log_l(res, runs) -> float:
    """-log L per sample of the training residuals at the fit's own channel RMS (Gaussian, independent)."""
    n_c = {c: sum(int(np.sum(np.isfinite(np.asarray(r[c], dtype=float)))) for r in runs) for c in res.channels}
    n = sum(n_c.values())
    return sum(n_c[c] / 2 * (math.log(2 * math.pi * res.noise_std[c] ** 2) + 1) for c in res.channels) / n


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--drift", type=float, default=0.05, help="injected water speed [m/s]")
    p.add_argument("--horizon", type=float, default=100.0)
    p.add_argument("--dt", type=float, default=0.2)
    p.add_argument("--write-only", action="store_true", help="only write the report from drift_truth.json")
    a = p.parse_args(argv)
    vc = (a.drift * math.cos(DRIFT_DIR), a.drift * math.sin(DRIFT_DIR))
    if a.write_only:
        write(json.loads((OUT / "drift_truth.json").read_text()), a, vc)
        return 0
    runs = {r.metadata["test"]: r for r in kvlcc2_runs()}
    prep = {k: r.resample(a.dt).slice(None, r.t0 + a.horizon) for k, r in runs.items()}
    train = [inject_current(prep[k], *vc) for k in TRAIN]
    val = [inject_current(prep[k], *vc) for k in VALIDATE]
    base = get_model("mmg")
    rows = []
    cases = [("none", base, {}), ("current (free)", augment(base, "current", runs=train), {}),
             ("current (held at the truth)", augment(base, "current", runs=train), {"Vcx": vc[0], "Vcy": vc[1]}),
             ("constant_force", augment(base, "constant_force", runs=train), {}),
             ("constant_force + current", augment(base, "constant_force", "current", runs=train), {})]
    for label, model, held in cases:
        t0 = time.perf_counter()
        spec = model.spec()
        if held:
            spec = spec.fix(held)
        res = fit(model, train, OutputError(), spec=spec, channels=CHANNELS, progress=None)
        ev = evaluate(res.model, val, channels=CHANNELS, integrator=res.integrator, fitted=res.channels,
                      scales=res.channel_scales)
        extra = {k: res.params[k] for k in ("Vcx", "Vcy", "Y0", "N0") if k in res.params}
        rows.append({"fit": label, "nll": neg_log_l(res, train), "rmse": ev.rmse, "values": extra,
                     "status": res.status, "seconds": time.perf_counter() - t0})
        print(f"{label}: -log L {rows[-1]['nll']:.4f}, {extra}, {res.status}, {rows[-1]['seconds']:.0f} s", flush=True)
    (OUT / "drift_truth.json").write_text(json.dumps(rows, indent=1) + "\n")
    write(rows, a, vc)
    return 0


def write(rows, a, vc) -> None:
    L = [f"# Is an injected {a.drift:g}-m/s water drift the best explanation of the HSVA logs?", "",
         f"Command: `python -m benchmarks drift_truth --drift {a.drift:g}` (module docstring: what each row is). "
         f"Injected current: Vcx {vc[0]:.4f}, Vcy {vc[1]:.4f} m/s (NED). MMG, published values, default free set "
         f"refitted; train {', '.join(TRAIN)}; held out {', '.join(VALIDATE)}; {a.horizon:g} s at {a.dt:g} s.", "",
         "| fit | −log L per sample (training) | held-out heading RMSE [°] | held-out sway RMSE [m/s] | held-out "
         "track east RMSE [m] | effect values | status | s |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        rm = r["rmse"]
        vals = ", ".join(f"{k} {v:.4g}" for k, v in r["values"].items())
        L.append(f"| {r['fit']} | {r['nll']:.4f} | {math.degrees(rm['psi']):.3f} | {rm['v']:.4f} | {rm['y0']:.3f} "
                 f"| {vals} | {r['status']} | {r['seconds']:.0f} |")
    by = {r["fit"]: r for r in rows}
    free, true, cf = by["current (free)"], by["current (held at the truth)"], by["constant_force"]
    n = len(rows)
    best = min(rows, key=lambda r: r["rmse"]["psi"])["fit"]
    L += ["", f"Reading ({n} fits): held out, the model with the true current "
          + ("predicts best" if best == true["fit"] else f"does not predict best ({best} does)") + " — heading "
          f"{math.degrees(true['rmse']['psi']):.2f}° against {math.degrees(cf['rmse']['psi']):.2f}° with the "
          f"constant force and {math.degrees(free['rmse']['psi']):.2f}° with the current estimated; track east "
          f"{true['rmse']['y0']:.2f} m against {cf['rmse']['y0']:.2f} and {free['rmse']['y0']:.2f} m. On the training "
          f"runs the constant force fits better than the current by {free['nll'] - cf['nll']:.3f} in −log L per "
          f"sample, and the current's likelihood barely moves between its estimate (Vcx "
          f"{free['values']['Vcx']:.4f}) and the truth (Vcx {true['values']['Vcx']:.4f}): "
          f"{true['nll'] - free['nll']:+.4f} per sample. The runs all start on one heading, so a current along the "
          "track is confounded with the speed through the water (the surge coefficients take it); only the ψ "
          "modulation of a 26° zigzag tells them apart, and the real gap of the hull model is larger than that. "
          "The diagnosis ranks candidates by held-out runs with their *estimated* values, so it loses the current "
          "in its estimate, not in its ranking; the verdict's tie (`diffship.diagnose.rivals`) is what the logs "
          "support. A run on another heading (or a turn through 180°) separates them."]
    (OUT / "drift_truth.md").write_text("\n".join(L) + "\n")
    print("\n".join(L))


if __name__ == "__main__":
    raise SystemExit(main())
