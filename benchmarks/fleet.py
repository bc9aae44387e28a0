"""Fleet throughput: ``python -m diffship.fleet`` (Dask LocalCluster) vs a shell loop of ``python -m diffship.fit``.

The same synthetic vessel-runs (the seed-002 USV, fossen3 with force inputs, realistic noise, each run
its own excitation seed), the same fit (output error, the fit command's defaults, ``--vessel usv``).
The shell loop starts one process per vessel-run (import, trace, compile or load from the persistent
cache, fit, write a fit file); the fleet keeps ``--workers`` processes and fits every vessel-run in them.
Throughput = fitted vessel-runs / wall time, cluster start-up and first compilation included.

    python -m benchmarks fleet --runs 40 --loop 4 --workers 1 2

Writes ``benchmarks/results/fleet.md``. The shell loop's throughput is measured on ``--loop`` of the
runs (each process is independent, so its per-fit time does not depend on how many follow), half before and half
after the fleet runs, so that a change in the shared machine's load shows (both are reported; the baseline is both).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def make_fleet(folder: Path, n: int, duration: float) -> Path:
    from diffship.synthetic import usv_runs

    lines = ["vessel,run,runs,model,vessel_file"]
    for i in range(n):
        (r,) = usv_runs(1, duration=duration, dt=0.1, seed=500 + i)
        r.to_dataframe().to_csv(folder / f"v{i}.csv", index=False)
        lines.append(f"boat{i},d1,v{i}.csv,fossen3,usv")
    (folder / "fleet.csv").write_text("\n".join(lines) + "\n")
    return folder / "fleet.csv"


def child_cpu() -> float:
    """[s] user + system CPU of this process's finished children (and theirs: a fleet's workers)."""
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def same_answer(loop_fit: Path, fleet_fit: Path) -> float:
    """Largest difference of a free parameter between the two fit files, in the loop fit's standard errors."""
    a, b = json.loads(loop_fit.read_text()), json.loads(fleet_fit.read_text())
    return max(abs(a["params"][n] - b["params"][n]) / a["stderr"][n] for n in a["free"])


def load() -> str:
    return "load average " + ", ".join(f"{x:.2f}" for x in os.getloadavg()) + f" on {os.cpu_count()} cores"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=40, help="vessel-runs in the fleet")
    ap.add_argument("--loop", type=int, default=4, help="vessel-runs timed in the shell loop")
    ap.add_argument("--duration", type=float, default=40.0, help="[s] each run's length (10 Hz)")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--threads", type=int, default=None, help="the fleet's --threads (default: its own)")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "fleet.md"))
    args = ap.parse_args(argv)
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    rows, notes, cpu = [], [f"before: {load()}"], {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        manifest = make_fleet(tmp, args.runs, args.duration)
        def shell_loop(indices, label):
            t0, per, c0 = time.perf_counter(), [], child_cpu()
            for i in indices:
                t1 = time.perf_counter()
                subprocess.run([sys.executable, "-m", "diffship.fit", str(tmp / f"v{i}.csv"), "--model", "fossen3",
                                "--vessel", "usv", "--method", "output-error", "--save", str(tmp / f"loop{i}.json"),
                                "--quiet"], env=env, capture_output=True, check=False)  # exit 1: not converged (still a fit)
                per.append(time.perf_counter() - t1)
            s = time.perf_counter() - t0
            cpu[label] = (child_cpu() - c0, len(indices))
            rows.append((f"shell loop of python -m diffship.fit ({label})", 1, len(indices), s, len(indices) / s))
            notes.append(f"shell loop {label}, per process [s]: {', '.join(f'{p:.1f}' for p in per)}; after: {load()}")

        half = max(1, args.loop // 2)
        shell_loop(range(half), "before the fleet runs")
        for w in args.workers:
            out = tmp / f"out{w}"
            t1, c1 = time.perf_counter(), child_cpu()
            r = subprocess.run([sys.executable, "-m", "diffship.fleet", str(manifest), "--out", str(out),
                                "--workers", str(w), "--quiet"]
                               + (["--threads", str(args.threads)] if args.threads else []),
                               env=env, capture_output=True, text=True, check=False)
            s = time.perf_counter() - t1
            cpu[f"fleet {w}"] = (child_cpu() - c1, args.runs)
            if r.returncode not in (0, 1):
                print(r.stdout, r.stderr, file=sys.stderr)
                return 1
            rows.append((f"python -m diffship.fleet --workers {w}", w, args.runs, s, args.runs / s))
            notes.append(f"fleet {w} worker(s): {r.stdout.strip().split('; table')[0]}; after: {load()}")
        shell_loop(range(half, max(args.loop, 2 * half)), "after the fleet runs")
        answers = []  # the fleet's fit of a vessel-run against the command line's (same optimum?)
        for i in range(max(args.loop, 2 * half)):
            for w in args.workers:
                f = tmp / f"out{w}" / "fits" / f"boat{i}__d1.json"
                if (tmp / f"loop{i}.json").is_file() and f.is_file():
                    answers.append(same_answer(tmp / f"loop{i}.json", f))
        notes.append(f"same answer: {len(answers)} fleet fits compared with the command line's fit of the same "
                     f"vessel-run; largest parameter difference {max(answers, default=float('nan')):.2g} standard "
                     "errors")
        import pandas as pd

        for w in args.workers:
            t = pd.read_parquet(tmp / f"out{w}" / "results.parquet")
            if "cpu_seconds" in t:
                notes.append(f"fleet {w} worker(s): CPU inside the fits (rows' cpu_seconds) "
                             f"{t.cpu_seconds.sum():.0f} s, median {t.cpu_seconds.median():.2f} s per fit; wall inside the fits median "
                             f"{t.seconds.median():.2f} s")
    loop_rows = [r for r in rows if r[0].startswith("shell loop")]
    both = sum(r[2] for r in loop_rows) / sum(r[3] for r in loop_rows)
    rows.insert(0, ("shell loop of python -m diffship.fit (both halves: the baseline)", 1,
                    sum(r[2] for r in loop_rows), sum(r[3] for r in loop_rows), both))
    base = rows[0][4]
    lines = ["# Fleet throughput", "",
             f"`python -m benchmarks fleet --runs {args.runs} --loop {args.loop} --duration "
             f"{args.duration:g} --workers {' '.join(map(str, args.workers))}`", "",
             f"Vessel-runs: the water-jet USV, fossen3 (force inputs), {args.duration:g} s at 10 Hz each, output error with "
             "the fit command's defaults (`--vessel usv`, reference priors). Wall time includes process / cluster "
             "start-up and compilation. **Machine: 2 cores shared with other engineers' jobs** (load below); the "
             "numbers are under that load, not on an idle machine.", "",
             "| how | workers | vessel-runs | wall [s] | fits/s | × shell loop |", "|---|---|---|---|---|---|"]
    lines += [f"| {n} | {w} | {k} | {s:.1f} | {f:.3f} | {f / base:.1f} |" for n, w, k, s, f in rows]
    loop_cpu = sum(c for k, (c, n) in cpu.items() if not k.startswith("fleet")) / sum(
        n for k, (c, n) in cpu.items() if not k.startswith("fleet"))
    lines += ["", ("CPU time (user + system of every process: the shell loop's processes, the fleet's driver, nannies "
                   "and workers; less sensitive to the shared machine's load than wall time):"), "",
              "| how | CPU per vessel-run [s] | × shell loop |", "|---|---|---|",
              f"| shell loop of python -m diffship.fit | {loop_cpu:.2f} | 1.0 |"]
    lines += [f"| python -m diffship.fleet --workers {k.split()[1]} | {c / n:.2f} | {loop_cpu / (c / n):.1f} |"
              for k, (c, n) in cpu.items() if k.startswith("fleet")]
    lines += ["", "Notes:", *[f"- {n}" for n in notes], ""]
    Path(args.out).write_text("\n".join(lines))
    print("\n".join(lines))
    return 0
