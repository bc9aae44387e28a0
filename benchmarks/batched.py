"""Batched Levenberg–Marquardt (issue 27): many fits of one problem, diffship against CasADi's loop.

Problem (the issue's): the seed-002 USV, ``diffship.synthetic.usv_runs(2, 300, 0.1)`` (realistic
noise, seed 0), fossen3, 10 free parameters + 8 initial-state offsets, 24 008 residuals, channel
spreads as weights, RK4 one step per sample; starts log-uniform ×0.5…×2 around the truth (rng seed 0,
the starts of ``benchmarks/cold_start.py``); ``fit_output_error``'s LM tolerances (max 200 steps,
rtol = atol = 1e-6). For each batch size ``B``:

* ``Kernel.solve_many(method="batched")``: all ``B`` fits in one compiled program (per-problem
  damping and status; on a CPU in rounds that repack unfinished fits). First call (compiles every
  bucket size it meets) and second call (run only);
* ``Kernel.solve_many(method="threads")``: the one-fit program (``Kernel.solve``, ``B = 1`` of the
  same LM) in one thread per core;
* CasADi (JIT, gcc -O2) + MINPACK looped over the starts (``benchmarks/casadi_peer.py``), setup
  once.

"Reached the best" = final cost within 1e-6 relative of the best cost any method found.
Usage: ``python benchmarks/batched.py [--batches 1 64] [--no-casadi]`` (needs ``pip install casadi``
for the peer). Results: ``benchmarks/results/batched.md``.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if __package__ in (None, ""):
    sys.path[0] = str(ROOT)

import jax
import optimistix as optx

from benchmarks.fitapi import FLT_NONE, oe_kernel
from diffship.models import Fossen3
from diffship.synthetic import usv_runs, usv_truth

CHANNELS = ("psi", "u", "v", "r")
SAME_COST = 1e-6
LM = dict(max_steps=200, rtol=1e-6, atol=1e-6)


def load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def problem():
    runs = usv_runs(2, 300.0, 0.1, noise="realistic", seed=0)
    truth = usv_truth().param_values()
    base = Fossen3().spec()
    free = base.free_names
    start = {n: truth[n] * 1.5 if i % 2 else truth[n] * 0.5 for i, n in enumerate(free)}
    spec = base.with_values(start)
    kernel, data, z0, batch = oe_kernel(Fossen3(), runs, spec=spec, channels=CHANNELS, estimate_x0=CHANNELS,
                                        flt=FLT_NONE)
    return runs, truth, spec, start, kernel, data, z0, batch


def starts(spec, truth, z0, n, seed=0):
    rng = np.random.default_rng(seed)
    free = spec.free_names
    Z = np.zeros((n, z0.size))
    for b in range(n):
        f = np.exp(rng.uniform(math.log(0.5), math.log(2.0), len(free)))
        Z[b, :len(free)] = spec.to_z({k: truth[k] * fi for k, fi in zip(free, f)})
    return Z


def diffship_batch(kernel, data, Z, method):
    t = time.perf_counter()
    outs = kernel.solve_many(Z, data, method=method, workers=os.cpu_count(), **LM)
    wall = time.perf_counter() - t
    cost = np.array([0.5 * float(np.sum(np.asarray(o[3]) ** 2)) for o in outs])
    ok = np.array([o[1] == optx.RESULTS.successful for o in outs])
    steps = np.array([int(o[2]) for o in outs])
    return dict(wall=wall, cost=cost, ok=ok, steps=steps)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batches", type=int, nargs="*", default=[1, 64])
    ap.add_argument("--no-casadi", action="store_true")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "batched.md"))
    args = ap.parse_args(argv)
    load0, t_all = load(), time.perf_counter()
    runs, truth, spec, start, kernel, data, z0, batch = problem()
    print(f"problem: {batch.n_residuals} residuals, {z0.size} unknowns; load {load0}", flush=True)
    rows = []
    peer = None
    if not args.no_casadi:
        from benchmarks import casadi_peer as cp
        work = Path(tempfile.mkdtemp(prefix="diffship_batched_"))
        csvs = []
        for r in runs:
            p = work / f"{r.name}.csv"
            r.to_dataframe().to_csv(p, index=False)
            csvs.append(str(p))
        prob = cp.load_problem(csvs, start)
        peer = cp.CasadiFossen3(prob, mode="jit")
        print(f"casadi setup {peer.setup_seconds:.2f} s", flush=True)
    for B in args.batches:
        Z = starts(spec, truth, z0, B)
        res = {}
        res["batched (first call, compiles included)"] = diffship_batch(kernel, data, Z, "batched")
        print(B, "batched first", f"{res['batched (first call, compiles included)']['wall']:.2f}", flush=True)
        if B <= 64:
            res["batched (second call, run only)"] = diffship_batch(kernel, data, Z, "batched")
            print(B, "batched second", f"{res['batched (second call, run only)']['wall']:.2f}", flush=True)
        kernel.solve_many(Z[:1], data, method="threads", **LM)  # compile the one-fit program outside the timing
        res[f"threads ({os.cpu_count()} workers, run only)"] = diffship_batch(kernel, data, Z, "threads")
        print(B, "threads", f"{list(res.values())[-1]['wall']:.2f}", flush=True)
        if peer is not None:
            t = time.perf_counter()
            sols = [cp.solve_lm(peer, Z[b]) for b in range(B)]
            res["CasADi JIT + MINPACK looped (run only)"] = dict(
                wall=time.perf_counter() - t, cost=np.array([s["cost"] for s in sols]),
                ok=np.array([s["converged"] for s in sols]), steps=np.array([s["nfev"] for s in sols]))
            print(B, "casadi", f"{list(res.values())[-1]['wall']:.2f}", flush=True)
        best = min(float(np.min(r["cost"])) for r in res.values())
        for name, r in res.items():
            reached = int(np.sum(np.abs(r["cost"] - best) <= SAME_COST * best))
            rows.append((B, name, r["wall"], B / r["wall"], reached, int(np.sum(r["ok"])), int(np.max(r["steps"])),
                         int(np.sum(r["steps"]))))
    load1 = load()
    total = time.perf_counter() - t_all
    L = ["## Batched Levenberg–Marquardt: many fits of the fossen3 USV problem (issue 27)", "",
         f"Problem: `usv_runs(2, 300, 0.1)` (realistic noise, seed 0), fossen3, 10 free parameters + 8 initial-state "
         f"offsets, {batch.n_residuals} residuals; starts log-uniform x0.5..x2 around the truth (seed 0); "
         f"LM max 200 steps, rtol = atol = 1e-6 (CasADi: MINPACK defaults of `benchmarks/casadi_peer.py`). "
         f"One run. Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs shared with other "
         f"engineers, JAX {jax.__version__} ({jax.default_backend()}); load (1/5/15 min) at the start **{load0}**, "
         f"at the end **{load1}**; total {total / 60:.1f} min."
         + (f" CasADi setup (JIT, gcc): {peer.setup_seconds:.2f} s (not in the run times)." if peer else ""), "",
         "| B | method | wall [s] | fits/s | reached best | converged | max steps | sum of steps |",
         "|---:|---|---:|---:|---:|---:|---:|---:|"]
    for B, name, wall, fps, reached, ok, mx, sm in rows:
        L.append(f"| {B} | {name} | {wall:.2f} | {fps:.3f} | {reached}/{B} | {ok}/{B} | {mx} | {sm} |")
    L += ["", "Steps: LM steps (diffship, accepted and rejected) or residual evaluations (CasADi/MINPACK).",
          "No GPU in this session: GPU figures not measured."]
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text("\n".join(L) + "\n")
    print("\n".join(L))


if __name__ == "__main__":
    main()
