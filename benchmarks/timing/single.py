"""One fit as a user runs it: ``python -m diffship.fit`` against CasADi, warm caches.

Problem: :mod:`benchmarks.timing.problem` (the fossen3 USV, 2 runs × 300 s, 10 free parameters from a
±50 % start (``--init``), 8 initial-state offsets). Interleaved rounds of whole processes:

* diffship, warm compilation cache (a second process with the same ``DIFFSHIP_CACHE_DIR``): the default
  multi-start fit (4 starts: the user's, the equation-error estimate, spread starts) and ``--starts 1``
  (the user's start alone, as CasADi solves it);
* CasADi JIT (gcc) + MINPACK LM in a process (``casadi_peer.py --mode jit``: setup every process);
* CasADi with its generated code compiled once and loaded (``--mode cache``, warm: CasADi's counterpart of
  diffship's persistent cache).

"fit" is the solve as each program reports it: diffship's ``fit_seconds`` (every start's first solve and the
rest from the best, compiles excluded), CasADi's ``solve_s``. Whole process: start to exit, wall clock.
Usage: ``python -m benchmarks timing single [--rounds 3]``; results ``benchmarks/results/timing_single.md``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import time
from pathlib import Path

from benchmarks.common.timing import loadavg, timed_process
from benchmarks.timing.problem import RESULTS, ROOT, fit_command, peer_command, start_values, write_runs


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--out", default=str(RESULTS / "timing_single.md"))
    args = ap.parse_args(argv)
    work = Path(tempfile.mkdtemp(prefix="diffship_single_fit_"))
    _, csvs = write_runs(work)
    _, start = start_values()
    cli = fit_command(csvs, start)
    peer = peer_command(csvs, start)
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "DIFFSHIP_CACHE_DIR": str(work / "jax_cache")}
    cases = {
        "diffship CLI, warm cache, default starts (4)": (cli, "ds"),
        "diffship CLI, warm cache, --starts 1": (cli + ["--starts", "1"], "ds"),
        "CasADi JIT + MINPACK process": (peer + ["--mode", "jit"], "ca"),
        "CasADi codegen cache (warm) + MINPACK process": (peer + ["--mode", "cache", "--cache-dir",
                                                                  str(work / "casadi_cache")], "ca"),
    }
    load0, t0 = loadavg(), time.perf_counter()
    # fill both caches once (not timed)
    timed_process(cli + ["--json", str(work / "warmup.json")], env, work)
    timed_process(cases["CasADi codegen cache (warm) + MINPACK process"][0] + ["--json", str(work / "w.json")], env, work)
    res = {k: {"wall": [], "fit": [], "setup": [], "cost": []} for k in cases}
    for rnd in range(args.rounds):
        for name, (cmd, kind) in cases.items():
            out = work / "out.json"
            wall = timed_process(cmd + ["--json", str(out)], env, work)
            doc = json.loads(out.read_text())
            if kind == "ds":
                m = doc["methods"]["output_error"]
                fit, setup, cost = m["fit_seconds"], m["compile_seconds"], m["cost"]
            else:
                fit, setup, cost = doc["solve_s"], doc["setup_s"], doc["cost"]
            for key, v in (("wall", wall), ("fit", fit), ("setup", setup), ("cost", cost)):
                res[name][key].append(v)
            print(f"round {rnd + 1} {name}: wall {wall:.2f} s, fit {fit:.2f} s, cost {cost:.8g}", flush=True)
    load1 = loadavg()
    med = {k: {m: statistics.median(v[m]) for m in v} for k, v in res.items()}
    ca_jit = med["CasADi JIT + MINPACK process"]
    ca_cache = med["CasADi codegen cache (warm) + MINPACK process"]
    L = ["## One fit as a user runs it: `python -m diffship.fit` against CasADi", "",
         f"Problem: fossen3 USV, `usv_runs(2, 300, 0.1)`, 10 free parameters from a ±50 % start + 8 initial-state "
         f"offsets, 24 008 residuals. {args.rounds} interleaved rounds, medians. Machine: {os.cpu_count()} CPUs "
         f"shared with other engineers' jobs, load (1/5/15 min) **{load0}** at the start, **{load1}** at the end; "
         f"{(time.perf_counter() - t0) / 60:.1f} min. Command: `python -m benchmarks timing single --rounds "
         f"{args.rounds}`.", "",
         "| what | whole process [s] | fit / solve [s] | compile / setup [s] | final cost | fit ÷ CasADi solve | "
         "process ÷ CasADi JIT process |", "|---|---:|---:|---:|---:|---:|---:|"]
    for name, m in med.items():
        L.append(f"| {name} | {m['wall']:.2f} | {m['fit']:.2f} | {m['setup']:.2f} | {m['cost']:.8g} | "
                 f"{m['fit'] / ca_jit['fit']:.2f} | {m['wall'] / ca_jit['wall']:.2f} |")
    L += ["", f"CasADi's warm codegen-cache process: {ca_cache['wall']:.2f} s (its solve {ca_cache['fit']:.2f} s).",
          "diffship's fit is the whole solve from every start it tries (the one-answer rule); `--starts 1` is the "
          "like-for-like solve from the one start CasADi is given."]
    Path(args.out).write_text("\n".join(L) + "\n")
    print("\n".join(L))
    return 0
