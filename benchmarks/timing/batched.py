"""Batched Levenberg–Marquardt: many fits of one problem, diffship against CasADi's loop.

Problem: :mod:`benchmarks.timing.problem` (the fossen3 USV, 2 runs × 300 s, 10 free parameters + 8
initial-state offsets, 24 008 residuals, channel spreads as weights, RK4 one step per sample); starts
log-uniform ×0.5…×2 around the truth (rng seed 0); ``fit_output_error``'s LM tolerances (max 200 steps,
rtol = atol = 1e-6). For each batch size ``B``:

* ``Kernel.solve_many(method="batched")``: all ``B`` fits in one compiled program (per-problem
  damping and status; on a CPU in rounds that repack unfinished fits). First call (compiles every
  bucket size it meets) and second call (run only);
* ``Kernel.solve_many(method="threads")``: the one-fit program (``Kernel.solve``, ``B = 1`` of the
  same LM) in one thread per core;
* CasADi (JIT, gcc -O2) + MINPACK looped over the starts (``benchmarks/common/casadi_peer.py``), setup
  once.

"Reached the best" = final cost within 1e-6 relative of the best cost any method found.

Bootstrap as a whole process (``--bootstrap-process N``, default 64): ``python -m diffship.fit RUNS
--model fossen3 ... --init START --bootstrap N`` timed from process start to exit (imports, the fit
from the ±50 % start, N block-bootstrap refits with input-noise draws, report), with an empty and then
a warm compilation cache, against CasADi doing the same work in this process: JIT setup, the fit from
the same start, then N refits from its optimum on moving-block resamples of its own residuals (blocks of
the length diffship chose, all channels of a sample together; no input-noise draws — less work than
diffship's). CasADi's figure leaves out its import and the data loading (both small).

Usage: ``python -m benchmarks timing batched [--batches 1 64] [--no-casadi] [--bootstrap-process 64]``
(needs ``pip install -e ".[bench]"`` for the peer). Results: ``benchmarks/results/timing_batched.md``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import tempfile
import time
from pathlib import Path

import jax
import numpy as np
import optimistix as optx

from benchmarks.common.fitapi import FLT_NONE, oe_kernel
from benchmarks.common.timing import loadavg, timed_process
from benchmarks.timing.problem import (CHANNELS, LM, RESULTS, ROOT, SAME_COST, fit_command, random_starts,
                                       start_values, write_runs)
from diffship.models import Fossen3


def problem(work: Path):
    runs, csvs = write_runs(work)
    truth, start = start_values()
    spec = Fossen3().spec().with_values(start)
    kernel, data, z0, batch = oe_kernel(Fossen3(), runs, spec=spec, channels=CHANNELS, estimate_x0=CHANNELS,
                                        flt=FLT_NONE)
    return runs, csvs, truth, spec, start, kernel, data, z0, batch


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
    ap.add_argument("--bootstrap-process", type=int, default=64, metavar="N",
                    help="time python -m diffship.fit ... --bootstrap N as a whole process against CasADi setup + fit + "
                         "N refits (0: skip; needs the CasADi peer)")
    ap.add_argument("--out", default=str(RESULTS / "timing_batched.md"))
    args = ap.parse_args(argv)
    load0, t_all = loadavg(), time.perf_counter()
    work = Path(tempfile.mkdtemp(prefix="diffship_batched_"))
    runs, csvs, truth, spec, start, kernel, data, z0, batch = problem(work)
    print(f"problem: {batch.n_residuals} residuals, {z0.size} unknowns; load {load0}", flush=True)
    rows = []
    peer = None
    if not args.no_casadi:
        from benchmarks.common import casadi_peer as cp
        prob = cp.load_problem(csvs, start)
        peer = cp.CasadiFossen3(prob, mode="jit")
        print(f"casadi setup {peer.setup_seconds:.2f} s", flush=True)
    for B in args.batches:
        Z = random_starts(spec, truth, z0.size, B)
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
    boot_rows = []
    if peer is not None and args.bootstrap_process:
        boot_rows = bootstrap_process(csvs, start, peer, cp, args.bootstrap_process, work)
    load1 = loadavg()
    total = time.perf_counter() - t_all
    L = ["## Batched Levenberg–Marquardt: many fits of the fossen3 USV problem", "",
         f"Problem: `usv_runs(2, 300, 0.1)` (realistic noise, seed 0), fossen3, 10 free parameters + 8 initial-state "
         f"offsets, {batch.n_residuals} residuals; starts log-uniform x0.5..x2 around the truth (seed 0); "
         f"LM max 200 steps, rtol = atol = 1e-6 (CasADi: MINPACK defaults of `benchmarks/common/casadi_peer.py`). "
         f"Command: `python -m benchmarks timing batched`. One run. Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs shared with other "
         f"engineers, JAX {jax.__version__} ({jax.default_backend()}); load (1/5/15 min) at the start **{load0}**, "
         f"at the end **{load1}**; total {total / 60:.1f} min."
         + (f" CasADi setup (JIT, gcc): {peer.setup_seconds:.2f} s (not in the run times)." if peer else ""), "",
         "| B | method | wall [s] | fits/s | reached best | converged | max steps | sum of steps |",
         "|---:|---|---:|---:|---:|---:|---:|---:|"]
    for B, name, wall, fps, reached, ok, mx, sm in rows:
        L.append(f"| {B} | {name} | {wall:.2f} | {fps:.3f} | {reached}/{B} | {ok}/{B} | {mx} | {sm} |")
    L += ["", "Steps: LM steps (diffship, accepted and rejected) or residual evaluations (CasADi/MINPACK)."]
    if boot_rows:
        L += ["", f"### Bootstrap of {args.bootstrap_process} resamples as a whole process (same data, same start)", "",
              "| what | wall [s] | inside |", "|---|---:|---|"]
        L += [f"| {name} | {wall:.2f} | {inside} |" for name, wall, inside in boot_rows]
    L += ["", f"Backend: {jax.default_backend()}."]
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text("\n".join(L) + "\n")
    print("\n".join(L))
    return 0


def bootstrap_process(csvs, start, peer, cp, n, work):
    """Rows (what, wall, inside) of the whole-process bootstrap comparison (module docstring)."""
    cli = fit_command(csvs, start) + ["--bootstrap", str(n)]
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "DIFFSHIP_CACHE_DIR": str(work / "jax_cache")}
    rows, doc = [], None
    for label in ("empty cache", "warm cache"):
        out = work / f"boot_{label.split()[0]}.json"
        wall = timed_process(cli + ["--json", str(out)], env, work)
        doc = json.loads(out.read_text())["methods"]["output_error"]
        b = doc["bootstrap"]
        rows.append((f"diffship `python -m diffship.fit ... --bootstrap {n}`, whole process, {label}", wall,
                     f"fit {doc['fit_seconds']:.2f} s, compile {doc['compile_seconds']:.2f} s, bootstrap "
                     f"{b['seconds']:.2f} s ({b['n_converged']}/{b['n']} converged, blocks of {b['block_samples']})"))
        print(f"bootstrap process ({label}): {wall:.2f} s", flush=True)
    block = int(doc["bootstrap"]["block_samples"])
    # CasADi: setup (JIT, measured when the peer was built) + the fit + n refits on block resamples
    z_start = peer.prob.to_z(dict(zip(cp.PARAM_NAMES, peer.prob.theta0)))  # the spec's values with --init
    t = time.perf_counter()
    sol = cp.solve_lm(peer, z_start)
    t_fit = time.perf_counter() - t
    R, C = peer.prob.R, len(CHANNELS)
    e, _ = peer.f_res(sol["z"], *peer.data)
    e = np.asarray(e).reshape(-1)
    N = peer.prob.N
    E = [e[i * C * N:(i + 1) * C * N].reshape(N, C).T for i in range(R)]  # (C, N) scaled residuals per run
    scales = np.asarray(peer.prob.scales).reshape(C, 1)
    i_y = 3 + R  # data layout: theta0, X0, scales, U0..U(R-1), Y0..Y(R-1), H...
    Y0 = [np.array(peer.data[i_y + i]) for i in range(R)]
    rng = np.random.default_rng(0)
    t = time.perf_counter()
    ok = 0
    for _ in range(n):
        for i in range(R):
            k = int(math.ceil(N / block))
            first = rng.integers(0, N - block + 1, size=k)
            idx = (first[:, None] + np.arange(block)[None, :]).reshape(-1)[:N]
            peer.data[i_y + i] = Y0[i] + scales * (E[i] - E[i][:, idx])  # y* = y + s (e - e*)
        ok += int(cp.solve_lm(peer, sol["z"])["converged"])
    t_boot = time.perf_counter() - t
    for i in range(R):
        peer.data[i_y + i] = Y0[i]
    rows.append((f"CasADi JIT + MINPACK: setup + fit + {n} refits", peer.setup_seconds + t_fit + t_boot,
                 f"setup {peer.setup_seconds:.2f} s, fit {t_fit:.2f} s, {n} refits {t_boot:.2f} s ({ok}/{n} converged)"))
    print(f"casadi bootstrap: {rows[-1][1]:.2f} s", flush=True)
    return rows
