"""Is the KVLCC2 "1.29 standard errors" point a premature LM stop or a second minimum?

On the 5°/5° zigzag of 300 s at 0.2 s (``benchmarks/estimators.py --k-amps 5 --k-duration 300
--k-dt 0.2``) several starts end "converged" at one point 1.29 reference standard errors from the
fit started from the truth, with a cost 0.77 higher. This script takes that point from a
benchmark JSON (the multiple-shooting result of start ``--start``), refits from it and from the
reference with the *same* channel weights (the reference's), and then

1. evaluates the cost along the straight line (parameters and fitted initial states) between the
   two end points (one compiled residual program);
2. computes the Gauss–Newton step in θ/scale (not the bound-mapped fit variable ``z``) at both,
   its length in standard errors, and the eigenvalue ratio of ``JᵀJ`` in ``z`` (what LM sees).

Run from the repository root::

    python -m benchmarks kvlcc2_second_minimum RESULTS.json [--start 1] [--variant multiple]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np

from benchmarks import estimators_truth as E  # noqa: E402  (the NumPy truth of the benchmark)

from diffship.fit import OutputErrorOptions, fit_output_error  # noqa: E402
from diffship.fit.identifiability import per_scale_columns  # noqa: E402
from diffship.fit.kernel import Kernel, kernel_data  # noqa: E402
from diffship.fit.output_error import x0_scales  # noqa: E402
from diffship.fit.problem import make_batch  # noqa: E402
from diffship.models import MMG  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("json")
    ap.add_argument("--start", type=int, default=1)
    ap.add_argument("--variant", default="multiple")
    args = ap.parse_args(argv)
    runs = E.kvlcc2_runs(0, 300.0, (5.0,), 0.2, 0.0)
    model = MMG()
    spec0 = model.spec()
    free = spec0.free_names
    truth = {n: E.K2.get(E.K2_NAMES.get(n, n), 0.0) for n in free}
    truth["delta0"] = 0.0
    conv = json.loads(Path(args.json).read_text())["kvlcc2"]
    point = next(c for c in conv[args.variant] if c["number"] == args.start)["params"]
    est = ("psi", "u", "v", "r")
    plain = OutputErrorOptions(reference_priors=False, estimate_x0=est, warmup=0.0)
    ref = fit_output_error(model, runs, spec=spec0.with_values(truth), options=plain)
    same = dataclasses.replace(plain, channel_scales=dict(ref.channel_scales), choose="first")
    a = fit_output_error(model, runs, spec=spec0.with_values(point), options=same)
    b = fit_output_error(model, runs, spec=spec0.with_values(ref.params), options=same)
    dev = {n: (a.params[n] - b.params[n]) / ref.stderr[n] for n in free}
    print(f"with the reference's channel weights: from the point {a.status[:40]}, cost {a.cost:.4f}; "
          f"from the reference {b.status[:40]}, cost {b.cost:.4f}")
    print("point − reference in reference se: " + ", ".join(f"{n} {v:+.3f}" for n, v in dev.items()))
    print("point: " + ", ".join(f"{n} {a.params[n]:.4g}" for n in free))
    batch = make_batch(model, runs, None, plain.flt)
    kernel = Kernel(spec=spec0.structural(), out_idx=tuple(model.output_names.index(c) for c in batch.channels),
                    angle=tuple(c in model.angle_outputs for c in batch.channels),
                    x0_idx=tuple(model.state_names.index(s) for s in est), integrator=plain.integrator)
    scales = np.asarray([ref.channel_scales[c] for c in batch.channels])
    xs = x0_scales(model, batch, est)
    data = kernel_data(model.with_params(spec0.values()), batch.ts, batch.us, batch.ys, batch.mask, batch.x0, scales,
                       x0_scale=xs)
    idx = [model.state_names.index(s) for s in est]

    def ends(res):
        return (np.array([res.params[n] for n in free]),
                ((np.asarray(res.initial_states)[:, idx] - batch.x0[:, idx]) / xs).reshape(-1))

    (tha, da), (thb, db) = ends(a), ends(b)
    print("cost along the straight line from the point (0) to the reference (1):")
    for al in np.linspace(0.0, 1.0, 11):
        th = (1 - al) * tha + al * thb
        z = np.concatenate([spec0.to_z(dict(zip(free, th))), (1 - al) * da + al * db])
        r = np.asarray(kernel.call("residuals", z, data))
        print(f"  {al:.1f}: Jz {th[free.index('Jz')]:.4g}, f_alpha {th[free.index('f_alpha')]:.4g}, "
              f"cost {0.5 * float(r @ r):.4f}")
    scale = np.array([spec0[n].scale for n in free])
    for name, (th, d) in (("point", (tha, da)), ("reference", (thb, db))):
        z = np.concatenate([spec0.to_z(dict(zip(free, th))), d])
        r = np.asarray(kernel.call("residuals", z, data))
        Jz = np.asarray(kernel.call("jacobian", z, data))
        Jt = Jz * per_scale_columns(spec0, z, len(z))
        s2 = float(r @ r) / (r.size - len(z))
        step = -np.linalg.lstsq(Jt, r, rcond=None)[0]
        chi2 = float((Jt @ step) @ (Jt @ step)) / s2
        wz = np.linalg.eigvalsh(Jz.T @ Jz)
        print(f"{name}: Gauss–Newton step in θ {chi2 ** 0.5:.3f} se long (σ̂² {s2:.3f}); θ + step: "
              + ", ".join(f"{n} {th[i] + step[i] * scale[i]:.4g}" for i, n in enumerate(free)))
        print(f"  JᵀJ in z: smallest/largest eigenvalue {wz[0] / wz[-1]:.2g} (pseudo-inverse cut n·eps "
              f"{len(z) * np.finfo(float).eps:.2g})")
