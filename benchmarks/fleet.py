"""Fleet throughput: ``python -m diffship.fleet`` (Dask LocalCluster) vs a shell loop of ``python -m diffship.fit``.

The same synthetic vessel-runs (the seed-002 USV, fossen3 with force inputs, realistic noise, each run
its own excitation seed), the same fit (output error, the fit command's defaults, ``--vessel usv``).
The shell loop starts one process per vessel-run (import, trace, compile or load from the persistent
cache, fit, write a fit file); the fleet keeps ``--workers`` processes and fits every vessel-run in them.
Throughput = fitted vessel-runs / wall time, cluster start-up and first compilation included.

    PYTHONPATH=src python benchmarks/fleet.py --runs 40 --loop 4 --workers 1 2

Writes ``benchmarks/results/fleet.md``. The shell loop's throughput is measured on ``--loop`` of the
runs (each process is independent, so its per-fit time does not depend on how many follow), half before and half
after the fleet runs, so that a change in the shared machine's load shows (both are reported; the baseline is both).
"""

from __future__ import annotations

import argparse
import os
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


def load() -> str:
    return "load average " + ", ".join(f"{x:.2f}" for x in os.getloadavg()) + f" on {os.cpu_count()} cores"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=40, help="vessel-runs in the fleet")
    ap.add_argument("--loop", type=int, default=4, help="vessel-runs timed in the shell loop")
    ap.add_argument("--duration", type=float, default=40.0, help="[s] each run's length (10 Hz)")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "fleet.md"))
    args = ap.parse_args(argv)
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    rows, notes = [], [f"before: {load()}"]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        manifest = make_fleet(tmp, args.runs, args.duration)
        def shell_loop(indices, label):
            t0, per = time.perf_counter(), []
            for i in indices:
                t1 = time.perf_counter()
                subprocess.run([sys.executable, "-m", "diffship.fit", str(tmp / f"v{i}.csv"), "--model", "fossen3",
                                "--vessel", "usv", "--method", "output-error", "--save", str(tmp / f"loop{i}.json"),
                                "--quiet"], env=env, capture_output=True, check=False)  # exit 1: not converged (still a fit)
                per.append(time.perf_counter() - t1)
            s = time.perf_counter() - t0
            rows.append((f"shell loop of python -m diffship.fit ({label})", 1, len(indices), s, len(indices) / s))
            notes.append(f"shell loop {label}, per process [s]: {', '.join(f'{p:.1f}' for p in per)}; after: {load()}")

        half = max(1, args.loop // 2)
        shell_loop(range(half), "before the fleet runs")
        for w in args.workers:
            out = tmp / f"out{w}"
            t1 = time.perf_counter()
            r = subprocess.run([sys.executable, "-m", "diffship.fleet", str(manifest), "--out", str(out),
                                "--workers", str(w), "--quiet"], env=env, capture_output=True, text=True, check=False)
            s = time.perf_counter() - t1
            if r.returncode not in (0, 1):
                print(r.stdout, r.stderr, file=sys.stderr)
                return 1
            rows.append((f"python -m diffship.fleet --workers {w}", w, args.runs, s, args.runs / s))
            notes.append(f"fleet {w} worker(s): {r.stdout.strip().split('; table')[0]}; after: {load()}")
        shell_loop(range(half, max(args.loop, 2 * half)), "after the fleet runs")
    loop_rows = [r for r in rows if r[0].startswith("shell loop")]
    both = sum(r[2] for r in loop_rows) / sum(r[3] for r in loop_rows)
    rows.insert(0, ("shell loop of python -m diffship.fit (both halves: the baseline)", 1,
                    sum(r[2] for r in loop_rows), sum(r[3] for r in loop_rows), both))
    base = rows[0][4]
    lines = ["# Fleet throughput (issue 30)", "",
             f"`PYTHONPATH=src python benchmarks/fleet.py --runs {args.runs} --loop {args.loop} --duration "
             f"{args.duration:g} --workers {' '.join(map(str, args.workers))}`", "",
             f"Vessel-runs: seed-002 USV, fossen3 (force inputs), {args.duration:g} s at 10 Hz each, output error with "
             "the fit command's defaults (`--vessel usv`, reference priors). Wall time includes process / cluster "
             "start-up and compilation. **Machine: 2 cores shared with other engineers' jobs** (load below); the "
             "numbers are under that load, not on an idle machine.", "",
             "| how | workers | vessel-runs | wall [s] | fits/s | × shell loop |", "|---|---|---|---|---|---|"]
    lines += [f"| {n} | {w} | {k} | {s:.1f} | {f:.3f} | {f / base:.1f} |" for n, w, k, s, f in rows]
    lines += ["", "Notes:", *[f"- {n}" for n in notes], ""]
    Path(args.out).write_text("\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
