"""The report of the cold-start timing: the Markdown tables of ``results/timing_cold[_quick].md``.

:func:`markdown` turns the measurements of :func:`benchmarks.timing.cold.main` (whole processes,
in process, scipy, the batch, the same-problem checks and the final parameters) into the report:
ratios diffship / CasADi first (below 1: diffship faster), then one table per section, with the
machine load and the environment (:func:`environment`).
"""

from __future__ import annotations

import math
import os
import platform

import casadi
import jax
import numpy as np
import scipy

from benchmarks.common.timing import cpu_name, fmt, max_rel_params, ratio


def environment(label: str) -> str:
    """CPU, platform and library versions, and which diffship source was measured."""
    env_line = (f"{cpu_name()}, {os.cpu_count()} CPUs (shared with other jobs), "
                f"{platform.platform()}; Python {platform.python_version()}, JAX {jax.__version__} "
                f"({jax.default_backend()}), NumPy {np.__version__}, SciPy {scipy.__version__}, "
                f"CasADi {casadi.__version__}. diffship source: {label}")
    return env_line


def markdown(*, quick, n_runs, duration, channels, n_res, free, n_unknowns, integrator, load_start, load_end,
             label, total, repeats, ratios, proc, proc_json, ds_calls, ds_warm, ds, ca_in, sp, t_sim, n_batch,
             batch_rows, best, same_cost, checks, finals, costs, ref) -> str:
    """The report (Markdown) from the measurements; times in seconds."""
    env_line = environment(label)
    n_rep = f"median of {repeats} (min–max)" if repeats > 1 else "one run"

    def r3(x):
        return "–" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.2f}"

    L = [
        f"## Cold start: diffship vs CasADi on the fossen3 output-error fit ({'quick' if quick else 'full'} mode)",
        "",
        f"Problem: seed-002 USV truth, {n_runs} runs × {duration:g} s at 10 Hz (realistic noise, seed 0), "
        f"channels {', '.join(channels)} ({n_res} residuals); {len(free)} free parameters from ±50 % of the truth "
        f"+ {n_unknowns - len(free)} initial-state offsets = {n_unknowns} unknowns; weights = channel spread; diffship's "
        f"integrator: {integrator} (the peers: classical RK4, one step per sample, first-order-hold "
        f"inputs). Machine load (1/5/15 min) at the start **{load_start}**, at the end **{load_end}**; "
        f"{env_line}. Total benchmark time {total / 60:.1f} min. Times in seconds, {n_rep}.",
        "",
        "### Ratios (diffship / CasADi: below 1 diffship is faster)",
        "",
        "| comparison | diffship [s] | CasADi JIT [s] | ratio | CasADi no JIT [s] | ratio "
        "| CasADi codegen cache [s] | ratio |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for name, d, a, b, c in ratios:
        L.append(f"| {name} | {r3(d)} | {r3(a)} | **{r3(ratio(d, a))}** | {r3(b)} | {r3(ratio(d, b))} | {r3(c)} | "
                 f"{r3(ratio(d, c))} |")
    L += [
        "",
        "### Whole process (subprocess wall clock, start to exit)",
        "",
        "| command | wall [s] | inside the process |",
        "|---|---:|---|",
        f"| diffship CLI, empty cache (`DIFFSHIP_CACHE_DIR` = new folder) | {fmt(proc['ds_empty'])} | compile "
        f"{fmt([d['methods']['output_error']['compile_seconds'] for d in proc_json['ds_empty']])}, fit "
        f"{fmt([d['methods']['output_error']['fit_seconds'] for d in proc_json['ds_empty']])} (as reported in --json); "
        f"the rest: Python, imports, CSV, metrics simulation, report |",
        f"| diffship CLI, warm cache (same folder, 2nd process) | {fmt(proc['ds_warm'])} | compile "
        f"{fmt([d['methods']['output_error']['compile_seconds'] for d in proc_json['ds_warm']])} (tracing, lowering "
        f"and loading from the cache), fit "
        f"{fmt([d['methods']['output_error']['fit_seconds'] for d in proc_json['ds_warm']])} |",
    ]
    for key, label in (("ca_jit", "CasADi JIT (gcc -O2) + MINPACK"),
                       ("ca_nojit", "CasADi no JIT (virtual machine) + MINPACK"),
                       ("ca_cache_empty", "CasADi codegen cache, empty (generate C, gcc -O2, casadi.external)"),
                       ("ca_cache_warm", "CasADi codegen cache, warm (load the .so)")):
        ds_ = proc_json[key]
        L.append(f"| {label} | {fmt(proc[key])} | import {fmt([d['import_s'] for d in ds_])}, setup "
                 f"{fmt([d['setup_s'] for d in ds_])}, solve {fmt([d['solve_s'] for d in ds_])} |")
    L += [
        "",
        "### In process",
        "",
        "| method | first call / setup [s] | warm fit / solve [s] | final cost | steps / f-evals | note |",
        "|---|---:|---:|---:|---:|---|",
        f"| diffship `fit_output_error` | {ds_calls[0][0]:.2f} (compile {ds_calls[0][1].compile_seconds:.2f}, no "
        f"persistent cache) | {fmt(ds_warm)} | {ds.cost:.10g} | {ds.iterations} | growing horizon (first 25 % of "
        f"each run, then all) when a run has ≥ 800 samples; covariance included |",
    ]
    for mode, label in (("jit", "CasADi JIT + MINPACK"), ("nojit", "CasADi no JIT + MINPACK")):
        s = ca_in[mode]["sol"]
        L.append(f"| {label} | {ca_in[mode]['setup']:.2f} | {fmt(ca_in[mode]['solves'])} | {s['cost']:.10g} | "
                 f"{s['nfev']} f / {s['njev']} J | {s['message']} |")
    L.append(f"| scipy FD + NumPy RK4 | 0 | {sp['wall']:.2f} | {sp['cost']:.10g} | {sp['calls']} residuals | "
             f"{sp['status']}; one NumPy simulation {t_sim * 1e3:.0f} ms |")
    L += [
        "",
        f"### Batch of {n_batch} fits (starts log-uniform ×0.5…×2 around the truth, rng seed 0, same starts for all)",
        "",
        "| method | compile / setup [s] | run [s] | per fit [s] | per fit incl. compile [s] | reached the best cost |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for name, comp, run, h, ms in batch_rows:
        L.append(f"| {name} | {comp:.2f} | {run:.2f} | {run / n_batch:.3f} | {(run + comp) / n_batch:.3f} | "
                 f"{h}/{n_batch} |")
    L += [
        "",
        f"Best cost {best:.12g}; \"reached\" = within {same_cost:g} relative. The vmapped LM runs all fits in lockstep "
        f"until the slowest stops ({batch_rows[0][4]} steps).",
        "",
        "### Same problem, same optimum",
        "",
        "| check | value |",
        "|---|---:|",
    ]
    for k, v in checks.items():
        L.append(f"| {k} | {v if isinstance(v, bool) else f'{v:.3g}'} |")
    L += [
        "",
        "Residual and Jacobian checks at diffship's in-process optimum (CasADi JIT vs `Kernel.residuals` / "
        "`Kernel.jacobian`); `tight_tol_*`: `Kernel.solve` (rtol = atol = 1e-12, ftol 1e-15) and CasADi + MINPACK "
        "(ftol = xtol = gtol = 1e-14) from the same start.",
        "",
        "| result | cost | max rel. param diff vs diffship in-process |" + "".join(f" {n} |" for n in free),
        "|---|---:|---:|" + "---:|" * len(free),
    ]
    for k, p in finals.items():
        c = costs.get(k)
        dd = "–" if k in ("truth", "start") else f"{max_rel_params(p, ref, free):.1e}"
        L.append(f"| {k} | {'–' if c is None else f'{c:.10g}'} | {dd} |" + "".join(f" {p[n]:.6g} |" for n in free))
    L += [
        "",
        "Notes:",
        "* diffship's CLI process also simulates the runs for its fit metrics and prints a report; CasADi's process "
        "only fits. Both read the same CSV files with pandas.",
        "* Tolerances: diffship rtol = atol = 1e-6 (scaled unknowns, cost), stall at relative cost decrease 1e-9, "
        "200 steps; MINPACK peers ftol 1e-9, xtol 1e-6, gtol 1e-8, max_nfev 200. The criteria are not identical "
        "algorithms; at these settings the final parameters agree to the relative differences in the table.",
        "* diffship fits the first 25 % of each run first (growing horizon, its default) when a run has at least 800 "
        "samples; the peers fit the whole runs at once from the same start. The batch uses the whole runs for all.",
        "* CasADi codegen cache: the same C code as the JIT, generated once with `CodeGenerator`, compiled with "
        "gcc -O2 into a folder and loaded with `casadi.external` in later processes — the CasADi counterpart of "
        "diffship's persistent cache (a few lines a user writes; CasADi's JIT itself compiles in every process).",
    ]
    return "\n".join(L) + "\n"
