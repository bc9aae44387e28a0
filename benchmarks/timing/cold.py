"""Cold start: diffship against CasADi (and scipy) on one fossen3 output-error problem.

The question: how long does a user wait, from typing the command to having the fitted
parameters, with diffship and with the strongest peer (CasADi, ``benchmarks/common/casadi_peer.py``),
on the identical problem, from the identical start, to the same optimum?

The problem is :mod:`benchmarks.timing.problem`'s (``--quick``: 2 × 60 s), identical for every
method; the CSV files are read back and checked identical, and the CasADi problem's arrays and
parameter declarations are checked against diffship's below.

Measured in one run (the machine load is written into the results):

1. **whole process** (``subprocess``, wall clock from start to exit), ``--repeats`` rounds,
   interleaved: ``python -m diffship.fit RUN1.csv RUN2.csv --model fossen3 --method output-error
   --weights spread --filter none --channels psi u v r --x0 estimate --no-prior --init ... --quiet --json F``
   with ``DIFFSHIP_CACHE_DIR`` a fresh empty folder (cold, empty cache), then the same command with
   the same folder (cold process, warm cache); the CasADi peer's process with
   ``--mode jit`` (CasADi JIT to C via gcc -O2), ``--mode nojit`` (CasADi's virtual machine), and
   ``--mode cache`` with an empty then a filled folder (the C code compiled once and loaded with
   ``casadi.external``: CasADi's counterpart of a persistent cache);
2. **in process**: ``fit_output_error`` (through ``benchmarks/common/fitapi.py``) called ``1 + repeats``
   times (the first call compiles, this process runs without the persistent cache); CasADi setup
   (graph + JIT) and ``repeats`` solves per mode;
3. **same problem**: CasADi's residual and Jacobian at diffship's optimum against
   ``Kernel.residuals``/``Kernel.jacobian``; the CasADi problem arrays (read from the CSVs with
   pandas) against diffship's batch; the parameter declarations against ``Fossen3().spec()``;
   final costs and parameters; and both solvers from the same start at tight tolerances;
4. **scipy + finite differences** over the NumPy RK4 (``peers.Fossen3Problem``), time-bounded;
5. **a batch of fits** (``--batch`` starts, log-uniform ×0.5…×2 around the truth, rng seed 0, zero
   offsets): ``jax.vmap`` of ``Kernel.solve`` over the starts, the same compiled one-start solve in a
   loop, ``Kernel.solve_many`` (that program in one thread per core), CasADi (JIT) looped, and —
   the same parallelism for the peer — CasADi in one process per core, each solving its share of the
   starts with the JIT-compiled code loaded from a cache folder (process start included).

Tolerances: diffship its defaults (``rtol = atol = 1e-6`` on the scaled unknowns and the cost,
stall at a relative cost decrease ``<= 1e-9``, 200 steps); every MINPACK peer ``ftol = 1e-9``,
``xtol = 1e-6``, ``gtol = 1e-8``, ``max_nfev = 200`` (``casadi_peer.TOL``).

Run (from the repository root; needs ``pip install -e ".[bench]"`` for casadi)::

    python -m benchmarks timing cold [--quick] [--out benchmarks/results]

Writes ``OUT/timing_cold.md`` and ``OUT/timing_cold.csv`` (``--quick``: ``timing_cold_quick.*``).
This module measures; :mod:`.cold_report` writes the Markdown report.
"""

from __future__ import annotations

import os

# This process measures in-process fits without diffship's persistent compilation cache (set
# before diffship is imported); the subprocesses get their own cache folders.
os.environ["DIFFSHIP_CACHE_DIR"] = "off"

import argparse  # noqa: E402
import csv  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import jax  # noqa: E402
import numpy as np  # noqa: E402

from benchmarks.common import casadi_peer as cp  # noqa: E402
from benchmarks.common.fitapi import (FLT_NONE, fit_oe, initial_states, kernel_jacobian,  # noqa: E402
                                      kernel_residuals, kernel_solver, oe_kernel)
from benchmarks.common.peers import Fossen3Problem  # noqa: E402
from benchmarks.common.timing import (commit, fmt, loadavg, max_rel_params, med, ratio, rel, scipy_fd,  # noqa: E402
                                      timed_process)
from benchmarks.timing.cold_report import markdown  # noqa: E402
from benchmarks.timing.problem import (CHANNELS, LM, ROOT, SAME_COST, fit_command, peer_command,  # noqa: E402
                                       random_starts, start_values, write_runs)
from diffship.data import load_runs  # noqa: E402
from diffship.models import Fossen3  # noqa: E402


# -- the measurement -------------------------------------------------------------------------------------
def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="2 x 60 s, batch of 8, one round, scipy guard 60 s")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results"), help="output folder")
    ap.add_argument("--repeats", type=int, default=None, help="whole-process rounds and warm repeats (3; quick 1)")
    ap.add_argument("--batch", type=int, default=None, help="starts in the batch (64; quick 8)")
    ap.add_argument("--guard", type=float, default=None, help="scipy wall-clock guard [s] (300; quick 60)")
    ap.add_argument("--src", default=str(ROOT / "src"),
                    help="diffship source folder on the PYTHONPATH of the CLI subprocesses (default: this checkout's)")
    ap.add_argument("--label", default=None,
                    help="what diffship source is measured, for the report (default: this checkout's git commit)")
    args = ap.parse_args(argv)
    quick = args.quick
    duration = 60.0 if quick else 300.0
    repeats = args.repeats or (1 if quick else 3)
    n_batch = args.batch or (8 if quick else 64)
    guard = args.guard or (60.0 if quick else 300.0)
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    stem = "timing_cold_quick" if quick else "timing_cold"
    rows = []  # the CSV: section, method, metric, value, unit, note

    def rec(section, method, metric, value, unit="s", note=""):
        rows.append(dict(mode="quick" if quick else "full", section=section, method=method, metric=metric,
                         value=value, unit=unit, note=note))

    label = args.label if args.label is not None else f"{args.src} (checkout at {commit()})"
    import diffship

    label += f"; this process imports diffship from {Path(diffship.__file__).parent}"
    load_start = loadavg()
    t_all = time.perf_counter()
    work = Path(tempfile.mkdtemp(prefix="diffship_cold_start_"))
    print(f"cold start benchmark ({'quick' if quick else 'full'}), load {load_start}, work folder {work}", flush=True)

    # -- the problem, as CSV files ----------------------------------------------------------------------
    runs, csvs = write_runs(work, duration)
    loaded = load_runs(csvs)
    roundtrip = all(
        np.array_equal(np.asarray(a.time), np.asarray(b.time))
        and set(a.channels) == set(b.channels)
        and all(np.array_equal(np.asarray(a[c]), np.asarray(b[c])) for c in a.channels)
        for a, b in zip(runs, loaded)
    )
    assert roundtrip, "the CSV files do not load back identically"
    runs = loaded
    truth, start = start_values()
    base = Fossen3().spec()
    free = base.free_names
    fixed_equal = all(base.values()[n] == truth[n] for n in base.fixed_names)
    assert fixed_equal, "the CLI fixes the model's defaults: they must equal the truth's fixed values"
    spec = base.with_values(start)
    kernel, data, z0, batch = oe_kernel(Fossen3(), runs, spec=spec, channels=CHANNELS, estimate_x0=CHANNELS,
                                        flt=FLT_NONE)
    n_res = batch.n_residuals
    print(f"problem: {len(runs)} runs x {duration:g} s, {n_res} residuals, {z0.size} unknowns", flush=True)

    # the CasADi process reads the same CSVs with pandas; its arrays and declarations must be diffship's
    prob = cp.load_problem(csvs, start)
    checks = {}
    checks["csv_roundtrip_identical"] = roundtrip
    # diffship may pad the runs to a bucketed length (masked samples): compare the real samples
    N = prob.N
    assert bool(np.all(batch.mask[:, :N])) and not bool(np.any(batch.mask[:, N:])), "runs of equal length"
    checks["problem_arrays_max_abs_diff"] = max(
        float(np.max(np.abs(prob.ts - batch.ts[:, :N]))), float(np.max(np.abs(prob.us - batch.us[:, :N]))),
        float(np.max(np.abs(prob.ys - batch.ys[:, :N]))), float(np.max(np.abs(prob.x0 - batch.x0))),
        float(np.max(np.abs(prob.scales - np.asarray(data.scales)))),
        float(np.max(np.abs(prob.x0_scale - np.asarray(data.x0_scale)))))
    checks["diffship_padded_samples_per_run"] = int(batch.ts.shape[1] - N)

    def unpad(a):
        """diffship's (run, sample, channel)-ordered rows without the padded samples."""
        a = np.asarray(a)
        return a.reshape(len(runs), -1, len(CHANNELS), *a.shape[1:])[:, :N].reshape(-1, *a.shape[1:])

    decl_ok = cp.PARAM_NAMES == tuple(Fossen3().param_names)
    for p in base.params:
        default, is_free, kind, bound, scale = cp.PARAMS[p.name]
        b = p.upper if kind == cp.UPPER else p.lower if kind == cp.LOWER else 0.0
        decl_ok &= (is_free == p.free and kind == p.kind and bound == b and scale == p.scale
                    and default == Fossen3().spec().values()[p.name])
    checks["param_declarations_equal"] = bool(decl_ok and cp.FREE == tuple(free))
    checks["z0_max_abs_diff"] = float(np.max(np.abs(prob.to_z(dict(zip(cp.PARAM_NAMES, prob.theta0))) - z0)))
    zt = np.linspace(-2.0, 2.0, z0.size)
    checks["from_z_max_rel_diff"] = max(rel(prob.params(zt)[n], v) for n, v in
                                        zip(free, np.asarray(spec.from_z(jax.numpy.asarray(zt[:len(free)])))))
    assert checks["problem_arrays_max_abs_diff"] == 0.0 and checks["param_declarations_equal"], checks
    print(f"checks: {checks}", flush=True)

    # -- 1. whole processes ------------------------------------------------------------------------------------
    env = {**os.environ, "PYTHONPATH": str(Path(args.src).resolve())}
    env.pop("DIFFSHIP_CACHE_DIR", None)
    cli = fit_command(csvs, start)
    peer_cmd = peer_command(csvs, start)
    proc = {k: [] for k in ("ds_empty", "ds_warm", "ca_jit", "ca_nojit", "ca_cache_empty", "ca_cache_warm")}
    proc_json = {}
    for rnd in range(repeats):
        cache = work / f"jax_cache_{rnd}"
        cache.mkdir()
        ccache = work / f"casadi_cache_{rnd}"
        for key, cmd, e in (
            ("ds_empty", cli + ["--json", str(work / "ds_empty.json")], {**env, "DIFFSHIP_CACHE_DIR": str(cache)}),
            ("ds_warm", cli + ["--json", str(work / "ds_warm.json")], {**env, "DIFFSHIP_CACHE_DIR": str(cache)}),
            ("ca_jit", peer_cmd + ["--mode", "jit", "--json", str(work / "ca_jit.json")], env),
            ("ca_nojit", peer_cmd + ["--mode", "nojit", "--json", str(work / "ca_nojit.json")], env),
            ("ca_cache_empty", peer_cmd + ["--mode", "cache", "--cache-dir", str(ccache), "--json",
                                           str(work / "ca_cache_empty.json")], env),
            ("ca_cache_warm", peer_cmd + ["--mode", "cache", "--cache-dir", str(ccache), "--json",
                                          str(work / "ca_cache_warm.json")], env),
        ):
            wall = timed_process(cmd, e, work)
            proc[key].append(wall)
            doc = json.loads((work / f"{key}.json").read_text())
            proc_json.setdefault(key, []).append(doc)
            rec("whole process", key, "wall", wall, note=f"round {rnd + 1}, load {loadavg()}")
            print(f"  round {rnd + 1} {key}: {wall:.2f} s", flush=True)
        if rnd == 0:
            n_files = sum(1 for _ in cache.rglob("*") if _.is_file())
            rec("whole process", "ds_empty", "persistent_cache_files", n_files, "files")
    ds_cli = proc_json["ds_empty"][-1]["methods"]["output_error"]
    ds_cli_warm = proc_json["ds_warm"][-1]["methods"]["output_error"]
    for key in ("ds_empty", "ds_warm"):
        for d in proc_json[key]:
            m = d["methods"]["output_error"]
            rec("whole process", key, "compile_seconds (reported)", m["compile_seconds"])
            rec("whole process", key, "fit_seconds (reported)", m["fit_seconds"])
    for key in ("ca_jit", "ca_nojit", "ca_cache_empty", "ca_cache_warm"):
        for d in proc_json[key]:
            for k in ("import_s", "setup_s", "solve_s"):
                rec("whole process", key, k, d[k])

    # -- 2. in process --------------------------------------------------------------------------------------
    print("in process: diffship fit_output_error ...", flush=True)
    ds_calls = []
    for i in range(1 + repeats):
        t = time.perf_counter()
        res = fit_oe(Fossen3(), runs, spec=spec, estimate_x0=CHANNELS, weights="spread", flt=FLT_NONE,
                     channels=CHANNELS, reference_priors=False)
        ds_calls.append((time.perf_counter() - t, res))
        rec("in process", "diffship fit_output_error", "wall" if i else "wall_first_call", ds_calls[-1][0],
            note=f"compile {res.compile_seconds:.2f} s, fit {res.fit_seconds:.2f} s, {res.iterations} steps")
        print(f"  call {i + 1}: {ds_calls[-1][0]:.2f} s (compile {res.compile_seconds:.2f} s), cost {res.cost:.12g}",
              flush=True)
    ds = ds_calls[-1][1]
    ds_warm = [w for w, _ in ds_calls[1:]]
    ca_in = {}
    peers_by_mode = {}
    for mode in ("jit", "nojit"):
        peer = cp.CasadiFossen3(prob, mode=mode)
        peers_by_mode[mode] = peer
        sols = [cp.solve_lm(peer, prob.to_z(dict(zip(cp.PARAM_NAMES, prob.theta0)))) for _ in range(repeats)]
        ca_in[mode] = dict(setup=peer.setup_seconds, solves=[s["wall"] for s in sols], sol=sols[-1])
        rec("in process", f"casadi {mode}", "setup", peer.setup_seconds)
        for s in sols:
            rec("in process", f"casadi {mode}", "solve", s["wall"], note=f"{s['nfev']} f-evals, {s['njev']} Jacobians")
        print(f"  casadi {mode}: setup {peer.setup_seconds:.2f} s, solve {fmt(ca_in[mode]['solves'])} s, "
              f"cost {sols[-1]['cost']:.12g}", flush=True)

    # -- 3. same problem ---------------------------------------------------------------------------------------
    x0_idx = list(kernel.x0_idx)
    z_ds = np.concatenate([spec.to_z({n: ds.params[n] for n in free}),
                           ((initial_states(ds) - batch.x0)[:, x0_idx] / np.asarray(data.x0_scale)).reshape(-1)])
    r_ds = unpad(kernel_residuals(kernel, data, z_ds))
    peer = peers_by_mode["jit"]
    r_ca, J_ca = peer.residuals_and_jacobian(z_ds)
    J_ds = unpad(kernel_jacobian(kernel, data, z_ds))
    c_ds, c_ca = 0.5 * float(r_ds @ r_ds), 0.5 * float(r_ca @ r_ca)
    checks["residual_max_abs_diff_at_diffship_optimum"] = float(np.max(np.abs(r_ds - r_ca)))
    checks["cost_rel_diff_at_diffship_optimum"] = rel(c_ca, c_ds)
    checks["cost_rel_diff_vs_fit_result"] = rel(c_ca, ds.cost)
    checks["jacobian_max_abs_diff_over_max_abs"] = float(np.max(np.abs(J_ds - J_ca)) / np.max(np.abs(J_ds)))
    r_vm = peers_by_mode["nojit"].residuals(z_ds)
    checks["nojit_vs_jit_residual_max_abs_diff"] = float(np.max(np.abs(r_vm - r_ca)))
    # both solvers from the same start at tight tolerances: the same optimum
    tight_fn, _ = kernel_solver(kernel, data, z0[None], max_steps=400, rtol=1e-12, atol=1e-12, ftol=1e-15,
                                batched=False)
    z_t, steps_t, cost_t, _ = tight_fn(z0)
    ca_t = cp.solve_lm(peer, z0, ftol=1e-14, xtol=1e-14, gtol=1e-14, max_nfev=400)
    p_t_ds, p_t_ca = prob.params(np.asarray(z_t)), prob.params(ca_t["z"])
    checks["tight_tol_param_max_rel_diff"] = max_rel_params(p_t_ca, p_t_ds, free)
    checks["tight_tol_cost_rel_diff"] = rel(ca_t["cost"], float(cost_t))
    n_p = len(free)
    checks["tight_tol_offsets_max_abs_diff"] = float(np.max(np.abs(ca_t["z"][n_p:] - np.asarray(z_t)[n_p:])))
    for k, v in checks.items():
        rec("same problem", "check", k, float(v), "")
    print(f"checks: {checks}", flush=True)

    # -- 4. scipy + finite differences -------------------------------------------------------------------------
    print(f"scipy + finite differences (guard {guard:.0f} s) ...", flush=True)
    npprob = Fossen3Problem(spec, Fossen3().with_params(spec.values()), batch, x0_idx, np.asarray(data.x0_scale),
                            np.asarray(data.scales))
    assert float(np.max(np.abs(unpad(npprob.residuals(z_ds)) - r_ds))) < 1e-9
    t = time.perf_counter()
    npprob.residuals(z0)
    t_sim = time.perf_counter() - t
    sp = scipy_fd(npprob, z0, guard)
    sp_params = npprob.params(sp["z"])
    rec("in process", "scipy FD + NumPy RK4", "solve", sp["wall"], note=f"{sp['calls']} residual evaluations; "
        f"{sp['status']}")
    print(f"  scipy: {sp['wall']:.1f} s, cost {sp['cost']:.12g}, {sp['calls']} evaluations: {sp['status']}", flush=True)

    # -- 5. batch of fits ----------------------------------------------------------------------------------------
    print(f"batch of {n_batch} fits ...", flush=True)
    Z = random_starts(spec, truth, z0.size, n_batch)
    lm = LM  # fit_output_error's defaults
    vfn, v_compile = kernel_solver(kernel, data, Z, batched=True, **lm)
    t = time.perf_counter()
    zv, sv, cv, okv = vfn(Z)
    v_run = time.perf_counter() - t
    cv = np.asarray(cv)
    lfn, l_compile = kernel_solver(kernel, data, Z, batched=False, **lm)
    t = time.perf_counter()
    cl = np.array([float(lfn(Z[b])[2]) for b in range(n_batch)])
    l_run = time.perf_counter() - t
    n_workers = os.cpu_count() or 1
    t = time.perf_counter()
    outs = kernel.solve_many(Z, data, workers=n_workers, **lm)
    t_run = time.perf_counter() - t
    ct = np.array([0.5 * float(np.sum(np.asarray(o[3]) ** 2)) for o in outs])
    t = time.perf_counter()
    cc = np.array([cp.solve_lm(peer, Z[b])["cost"] for b in range(n_batch)])
    c_run = time.perf_counter() - t
    # the same parallelism for CasADi: its solves hold the interpreter (MINPACK calls back into
    # Python), so threads do not help it; a pool of processes does, each loading the JIT-compiled
    # code from one cache folder (compiled once, before the clock starts)
    pool_cache = work / "casadi_pool_cache"
    cp.CasadiFossen3(prob, mode="cache", cache_dir=str(pool_cache))
    parts = np.array_split(np.arange(n_batch), n_workers)
    for i, idx in enumerate(parts):
        np.save(work / f"starts_{i}.npy", Z[idx])
    t = time.perf_counter()
    procs = [subprocess.Popen(peer_cmd + ["--mode", "cache", "--cache-dir", str(pool_cache), "--starts",
                                          str(work / f"starts_{i}.npy"), "--costs", str(work / f"costs_{i}.npy")],
                              env=env, cwd=work, stdout=subprocess.DEVNULL) for i in range(len(parts))]
    assert all(p.wait() == 0 for p in procs), "a CasADi batch process failed"
    p_run = time.perf_counter() - t
    cpool = np.concatenate([np.load(work / f"costs_{i}.npy") for i in range(len(parts))])
    best = float(min(cv.min(), cl.min(), ct.min(), cc.min(), cpool.min()))
    hit = lambda c: int(np.sum(c <= best * (1 + SAME_COST)))  # noqa: E731
    batch_rows = [
        ("diffship jax.vmap(Kernel.solve)", v_compile, v_run, hit(cv), int(np.max(np.asarray(sv)))),
        ("diffship Kernel.solve looped (fit_output_error's program, already compiled by the fits above)",
         l_compile, l_run, hit(cl), None),
        (f"diffship Kernel.solve_many ({n_workers} threads, the same compiled program)", 0.0, t_run, hit(ct), None),
        ("CasADi JIT + MINPACK looped", peer.setup_seconds, c_run, hit(cc), None),
        (f"CasADi JIT + MINPACK in {n_workers} processes (each loads the compiled code from its cache; process "
         "start included)",
         0.0, p_run, hit(cpool), None),
    ]
    for name, comp, run, h, _ in batch_rows:
        rec("batch", name, "compile_or_setup", comp)
        rec("batch", name, "run", run, note=f"{n_batch} fits")
        rec("batch", name, "run_per_fit", run / n_batch)
        rec("batch", name, "reached_best_cost", h, "fits", note=f"within {SAME_COST:g} relative of {best:.12g}")
        print(f"  {name}: compile/setup {comp:.2f} s, run {run:.2f} s ({run / n_batch:.3f} s/fit), "
              f"{h}/{n_batch} at the best cost", flush=True)
    load_end = loadavg()
    total = time.perf_counter() - t_all

    # -- tables ---------------------------------------------------------------------------------------------
    ca_jit_sol, ca_vm_sol = ca_in["jit"]["sol"], ca_in["nojit"]["sol"]
    finals = {
        "truth": truth,
        "start": {**truth, **start},
        "diffship CLI (cold, empty cache)": ds_cli["params"],
        "diffship fit_output_error (in process)": ds.params,
        "CasADi JIT + MINPACK": prob.params(ca_jit_sol["z"]),
        "CasADi no JIT + MINPACK": prob.params(ca_vm_sol["z"]),
        "CasADi JIT process": proc_json["ca_jit"][-1]["params"],
        "scipy FD + NumPy RK4": sp_params,
    }
    costs = {
        "diffship CLI (cold, empty cache)": ds_cli["cost"],
        "diffship CLI (warm cache)": ds_cli_warm["cost"],
        "diffship fit_output_error (in process)": ds.cost,
        "CasADi JIT + MINPACK": ca_jit_sol["cost"],
        "CasADi no JIT + MINPACK": ca_vm_sol["cost"],
        "CasADi JIT process": proc_json["ca_jit"][-1]["cost"],
        "CasADi cache process (warm)": proc_json["ca_cache_warm"][-1]["cost"],
        "scipy FD + NumPy RK4": sp["cost"],
    }
    ref = ds.params
    for k, v in costs.items():
        rec("final", k, "cost", v, "")
    for k, p in finals.items():
        if k not in ("truth", "start"):
            rec("final", k, "max_rel_param_diff_vs_diffship", max_rel_params(p, ref, free), "")
        for n in free:
            rec("final", k, n, p[n], "SI")

    W = {k: med(v) for k, v in proc.items()}
    ca_jit_solve, ca_vm_solve, ds_w = med(ca_in["jit"]["solves"]), med(ca_in["nojit"]["solves"]), med(ds_warm)
    ratios = [
        ("cold process, empty cache (diffship CLI) vs CasADi process (setup + solve)",
         W["ds_empty"], W["ca_jit"], W["ca_nojit"], W["ca_cache_empty"]),
        ("cold process, warm cache (diffship CLI) vs CasADi process (setup + solve; cache: loaded)",
         W["ds_warm"], W["ca_jit"], W["ca_nojit"], W["ca_cache_warm"]),
        ("warm, in process: fit_output_error 2nd call vs CasADi solve",
         ds_w, ca_jit_solve, ca_vm_solve, math.nan),
        (f"batch of {n_batch}, run only: jax.vmap vs CasADi JIT looped",
         v_run, c_run, math.nan, math.nan),
        (f"batch of {n_batch}, with compile/setup: jax.vmap vs CasADi JIT looped",
         v_run + v_compile, c_run + peer.setup_seconds, math.nan, math.nan),
        (f"batch of {n_batch}, run only: diffship Kernel.solve looped vs CasADi JIT looped",
         l_run, c_run, math.nan, math.nan),
        (f"batch of {n_batch}, run only: diffship Kernel.solve_many ({n_workers} threads) vs CasADi JIT looped",
         t_run, c_run, math.nan, math.nan),
        (f"batch of {n_batch}, run only: diffship Kernel.solve_many ({n_workers} threads) vs CasADi JIT in "
         f"{n_workers} processes", t_run, p_run, math.nan, math.nan),
    ]
    for name, d, a, b, c in ratios:
        rec("ratio", name, "diffship_over_casadi_jit", ratio(d, a), "")
        if not math.isnan(b):
            rec("ratio", name, "diffship_over_casadi_nojit", ratio(d, b), "")
        if not math.isnan(c):
            rec("ratio", name, "diffship_over_casadi_cache", ratio(d, c), "")

    md = markdown(quick=quick, n_runs=len(runs), duration=duration, channels=CHANNELS, n_res=n_res, free=free,
                  n_unknowns=z0.size, integrator=kernel.integrator.describe(), load_start=load_start,
                  load_end=load_end, label=label, total=total, repeats=repeats, ratios=ratios, proc=proc,
                  proc_json=proc_json, ds_calls=ds_calls, ds_warm=ds_warm, ds=ds, ca_in=ca_in, sp=sp, t_sim=t_sim,
                  n_batch=n_batch, batch_rows=batch_rows, best=best, same_cost=SAME_COST, checks=checks,
                  finals=finals, costs=costs, ref=ref)
    print()
    print(md)
    (out_dir / f"{stem}.md").write_text(md)
    with open(out_dir / f"{stem}.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=["mode", "section", "method", "metric", "value", "unit", "note"])
        w.writeheader()
        w.writerows(rows)
    print(f"wrote {out_dir / (stem + '.md')} and {out_dir / (stem + '.csv')}")
    shutil.rmtree(work, ignore_errors=True)
    return 0
