"""diffship benchmark suite: output error vs equation error vs the tools users would pick instead.

One command (from the repository root)::

    python -m benchmarks suite [--quick] [--cases nomoto,fossen3] [--report-only] [--out benchmarks/results]

writes ``OUT/report.md`` (headline table first), ``OUT/all_numbers.csv`` (every number, long
format: case, variant, method, metric, value, unit, note) and ``OUT/fig_*.png``. ``--quick``
(CI size, a few minutes) writes ``report_quick.md`` / ``all_numbers_quick.csv`` /
``fig_quick_*.png`` so that it never overwrites the full results. ``--cases`` runs a subset;
``--report-only`` rewrites the report and figures from the CSV. The cases live in
:mod:`benchmarks.cases` (one module each); see ``benchmarks/README.md`` for what is measured and how.
"""

from __future__ import annotations

import argparse
import importlib
import math
import os
import platform
import time
from pathlib import Path

import jax
import numpy as np
import scipy

from benchmarks.cases import MODULES
from benchmarks.common.timing import cpu_name
from benchmarks.record import Recorder, say
from benchmarks.report import figures, headline, write_report

#: every case, in the order the full mode runs them (each case module's ``CASES``)
CASES = {name: run for m in MODULES for name, run in importlib.import_module(f"benchmarks.cases.{m}").CASES.items()}
QUICK_CASES = ("nomoto", "nomoto_cubic", "sspa", "kvlcc2")
RESULTS = Path(__file__).resolve().parent / "results"


def environment() -> str:
    return (f"machine: {cpu_name()}, {os.cpu_count()} CPUs, {platform.platform()}; Python "
            f"{platform.python_version()}, JAX {jax.__version__} ({jax.default_backend()}), NumPy {np.__version__}, "
            f"SciPy {scipy.__version__}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="CI size (a few minutes)")
    ap.add_argument("--out", default=str(RESULTS))
    ap.add_argument("--cases", default=None, help=f"comma-separated subset of {','.join(CASES)}")
    ap.add_argument("--report-only", action="store_true",
                    help="rewrite the report and figures from the existing all_numbers CSV (no fitting)")
    args = ap.parse_args(argv)
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    cases = args.cases.split(",") if args.cases else (list(QUICK_CASES) if args.quick else list(CASES))
    unknown = [c for c in cases if c not in CASES]
    if unknown:
        ap.error(f"unknown case(s) {unknown}; choose from {', '.join(CASES)}")
    stem = "report_quick" if args.quick else "report"
    csv_path = out_dir / f"{stem.replace('report', 'all_numbers')}.csv"
    prefix = "fig_quick_" if args.quick else "fig_"
    rec = Recorder()
    t0 = time.perf_counter()
    env = environment()

    def write(done, final):
        total = time.perf_counter() - t0
        rec.write_csv(csv_path)
        figs = figures(rec, out_dir, prefix)
        write_report(rec, out_dir, stem, args.quick, done if final else done + ["(incomplete: still running)"],
                     total, figs, env)
        return total

    if args.report_only:
        rec.read_csv(csv_path)
        rec.write_csv(csv_path)
        done = sorted({r["case"] for r in rec.rows if r["metric"] == "case_wall_s"})
        tot = rec.get("all", "-", "-", "total_wall_s")
        figs = figures(rec, out_dir, prefix)
        write_report(rec, out_dir, stem, args.quick, done, tot if math.isfinite(tot) else 0.0, figs,
                     env + " (report rewritten from the CSV)")
        print("\n".join(f"{q}: {v} ({h})" for q, v, h in headline(rec)))
        return 0
    done = []
    for c in cases:
        tc = time.perf_counter()
        try:
            CASES[c](rec, args.quick, None)
        except Exception as exc:  # one broken case must not hide the others
            import traceback

            traceback.print_exc()
            rec.add(c, "-", "-", "failed", 1.0, "", f"{type(exc).__name__}: {str(exc)[:200]}")
        rec.add(c, "-", "-", "case_wall_s", time.perf_counter() - tc, "s")
        say(f"case {c} done in {time.perf_counter() - tc:.1f} s")
        done.append(c)
        if c != cases[-1]:
            write(done, False)
    total = time.perf_counter() - t0
    rec.add("all", "-", "-", "total_wall_s", total, "s")
    write(done, True)
    say(f"wrote {out_dir / (stem + '.md')} ({total / 60:.1f} min)")
    print("\n".join(f"{q}: {v} ({h})" for q, v, h in headline(rec)))
    return 0
