"""Compile time of every model: cold ``python -m diffship.fit`` with an empty and a warm cache.

For each model (nomoto2, fossen3, fossen6, vmm_simple, vmm_abkowitz, mmg, decay2) small synthetic
runs are written to CSV (each model's own reference values, small sensor noise; see
:func:`write_data`), then, ``--repeats`` times:

1. ``python -m diffship.fit RUN.csv ... --model M [--vessel REF] --quiet --json F`` (``REF`` the model's
   reference vessel, whose particulars made the data) in a new process with
   ``DIFFSHIP_CACHE_DIR`` a fresh empty folder (**cold**: every program compiled);
2. the same command with the same folder (**cached**: a new process that loads the programs).

Wall clock from process start to exit; the compile and fit seconds each method reports in its
JSON are recorded beside it. ``--hlo`` also counts, in this process, the lines of the lowered
StableHLO text (``jax.jit(f).lower(...).as_text()``) of each output-error program (residuals,
Jacobian, solve) and of one vector-field evaluation: what makes a program large.

    python -m benchmarks compile_time [--models fossen6 vmm_simple] [--repeats 1] [--hlo]

Writes ``benchmarks/results/compile_time.md`` (and ``compile_time.csv``). Timings on a shared
machine are disturbed by other jobs: the load average is written beside them.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


MODELS = ("nomoto2", "fossen3", "fossen6", "vmm_simple", "vmm_abkowitz", "mmg", "decay2")
DEG = np.pi / 180.0


def write_data(name: str, folder: Path, input_noise: bool = False) -> list[Path]:
    """Two small noisy runs of the model's reference vessel, as CSV files (returns the paths);
    ``input_noise``: the logged inputs carry measurement noise too."""
    from diffship.data import Run
    from diffship.manoeuvres import zigzag
    from diffship.models import get_model
    from diffship.synthetic import nomoto_runs, simulate_run, usv_runs

    model = get_model(name)
    rng = np.random.default_rng(0)
    runs: list[Run]
    if name.startswith("nomoto"):
        runs = nomoto_runs(model, n_runs=2, duration=60.0, dt=0.1, seed=0)
    elif name == "fossen3":
        runs = usv_runs(2, 120.0, 0.1, noise="realistic", seed=0)
    elif name == "fossen6":
        from benchmarks.cases.rov import rov_case_runs

        runs = rov_case_runs(model, n_runs=2, duration=30.0, dt=0.1, seed=0)
    elif name.startswith("vmm"):
        from diffship.models.vmm import approach_thrust

        T0 = approach_thrust()
        runs = [zigzag(model, {"u": float(model.U0)}, rudder_deg=a, inputs={"thrust": T0}, duration=300.0, dt=0.5,
                       name=f"zz{a:g}") for a in (10.0, 20.0)]
    elif name == "mmg":
        runs = [zigzag(model, {"u": 1.179}, rudder_deg=a, inputs={"n": 10.23}, duration=80.0, dt=0.2, scale=45.714,
                       name=f"zz{a:g}") for a in (10.0, 20.0)]
    elif name.startswith("decay"):
        t = np.arange(0.0, 60.0, 0.1)
        runs = [simulate_run(model, t, {"tau": np.zeros_like(t)}, np.array([a, 0.0]), name=f"decay{i}",
                             noise={"angle": 1e-3, "rate": 1e-3}, seed=i) for i, a in enumerate((0.2, -0.3))]
    else:
        raise ValueError(name)
    paths = []
    for i, run in enumerate(runs):
        df = run.to_dataframe()
        if name in ("vmm_simple", "vmm_abkowitz", "mmg"):  # noise-free manoeuvres: add small sensor noise
            for c, s in (("psi", 0.1 * DEG), ("u", 0.01), ("v", 0.01), ("r", 0.05 * DEG)):
                df[c] = df[c] + rng.normal(0.0, s, len(df))
        if input_noise:  # measured inputs, as in model tests: rudder 0.05°, thrust/forces 1 %
            for c in model.input_names:
                if c == "delta":
                    df[c] = df[c] + rng.normal(0.0, 0.05 * DEG, len(df))
                elif c != "tau":
                    df[c] = df[c] * (1 + 0.01 * rng.normal(size=len(df)))
        p = folder / f"{name}_{i}.csv"
        df.to_csv(p, index=False)
        paths.append(p)
    return paths


def one_process(model: str, files: list[Path], cache: Path, out_json: Path, src: str | None = None) -> dict:
    env = {**os.environ, "DIFFSHIP_CACHE_DIR": str(cache), "PYTHONPATH": src or os.environ.get("PYTHONPATH", "src")}
    from diffship.models import get_model

    vessel = type(get_model(model)).REFERENCE_VESSEL  # the data are the reference vessel's (write_data)
    cmd = [sys.executable, "-m", "diffship.fit", *map(str, files), "--model", model, "--quiet", "--json", str(out_json),
           *(["--vessel", vessel] if vessel else [])]
    if model.startswith("decay"):  # no vessel file holds a decaying DOF's inertia: fixed at the truth's, as a user would
        m = get_model(model)
        need = list(m.PARTICULARS)
        cmd += ["--fix", f"{need[0]}={float(m.param_values()[need[0]])!r}", *(["--free", *need[1:]] if need[1:] else [])]
    t0 = time.perf_counter()
    p = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    row = {"wall_s": wall, "rc": p.returncode}
    if out_json.exists():
        doc = json.loads(out_json.read_text())
        for m, r in doc["methods"].items():
            row[f"{m}_compile_s"] = r["compile_seconds"]
            row[f"{m}_fit_s"] = r["fit_seconds"]
            row[f"{m}_converged"] = r["converged"]
        out_json.unlink()
    if p.returncode not in (0, 1):
        row["error"] = (p.stderr.strip().splitlines() or ["?"])[-1][:200]
    return row


def particulars_stop(files: list[Path], repeats: int = 5) -> dict:
    """Whole-process wall time of ``python -m diffship.fit RUN --model vmm_simple`` without a vessel: the stop
    that names the twelve missing particulars (it must answer within a second); median and max of ``repeats``."""
    cmd = [sys.executable, "-m", "diffship.fit", str(files[0]), "--model", "vmm_simple"]
    env = {**os.environ, "PYTHONPATH": os.environ.get("PYTHONPATH", "src")}
    walls, codes, err = [], set(), ""
    for _ in range(repeats):
        t0 = time.perf_counter()
        p = subprocess.run(cmd, env=env, capture_output=True, text=True)
        walls.append(time.perf_counter() - t0)
        codes.add(p.returncode)
        err = p.stderr.strip()
    return {"model": "vmm_simple (no vessel)", "mode": "particulars_stop", "median_s": float(np.median(walls)),
            "max_s": float(np.max(walls)), "rc": sorted(codes), "lines": err.count("\n") + 1, "stderr": err[:90]}


def hlo_lines(name: str, files: list[Path]) -> dict:
    """Lines of the lowered StableHLO of each output-error program and of one vector-field call."""
    import jax
    import jax.numpy as jnp

    from diffship.data import load_runs
    from diffship.fit.kernel import Kernel, kernel_data
    from diffship.fit.output_error import channel_spread
    from diffship.fit.problem import make_batch
    from diffship.models import get_model
    from diffship.preprocess import Filter

    model = get_model(name)
    runs = load_runs(files)
    spec = model.spec()
    batch = make_batch(model, runs, None, Filter())
    k = Kernel(spec=spec.structural(), out_idx=tuple(model.output_names.index(c) for c in batch.channels),
               angle=tuple(c in model.angle_outputs for c in batch.channels))
    data = kernel_data(model, batch.ts, batch.us, batch.ys, batch.mask, batch.x0, channel_spread(batch))
    z = jnp.asarray(spec.to_z(spec.nudged(spec.values())[0]))
    out = {}
    for meth, static in (("residuals", {}), ("jacobian", {}), ("solve", dict(max_steps=200, rtol=1e-6, atol=1e-6))):
        fn = getattr(k, meth)
        t0 = time.perf_counter()
        text = jax.jit(lambda z, d, fn=fn, s=static: fn(z, d, **s)).lower(z, data).as_text()
        out[f"hlo_{meth}"] = text.count("\n")
        out[f"lower_{meth}_s"] = time.perf_counter() - t0
    x = jnp.asarray(batch.x0[0])
    u = jnp.asarray(batch.us[0, 0])
    vf = jax.jit(lambda m, x, u: m.vector_field(0.0, x, u))
    out["hlo_vector_field"] = vf.lower(model, x, u).as_text().count("\n")
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", nargs="*", default=list(MODELS))
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--hlo", action="store_true", help="also count lowered HLO lines per program")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    ap.add_argument("--tag", default="", help="suffix of the result files")
    ap.add_argument("--input-noise", action="store_true", help="noisy logged inputs (rudder 0.05°, thrust 1 %%)")
    ap.add_argument("--src", nargs="*", default=[None],
                    help="diffship source folders to compare (PYTHONPATH of the CLI processes; default: $PYTHONPATH)")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    load0 = os.getloadavg()
    t_all = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for name in args.models:
            files = write_data(name, tmp, args.input_noise)
            for rep in range(args.repeats):
                for k, src in enumerate(args.src):  # interleaved: the sources see the same load
                    cache = tmp / f"cache_{name}_{rep}_{k}"
                    cache.mkdir()
                    for mode in ("cold", "cached"):
                        row = {"model": name, "src": src or "", "repeat": rep, "mode": mode, "load1": os.getloadavg()[0],
                               **one_process(name, files, cache, tmp / "out.json", src)}
                        rows.append(row)
                        print(json.dumps(row), flush=True)
            if args.hlo:
                try:
                    h = hlo_lines(name, files)
                except Exception as exc:  # a measurement, not a test: say what failed and go on
                    h = {"error": f"{type(exc).__name__}: {exc}"[:200]}
                rows.append({"model": name, "mode": "hlo", **h})
                print(json.dumps(rows[-1]), flush=True)
        rows.append(particulars_stop(write_data("vmm_simple", tmp) if "vmm_simple" not in args.models else
                                     sorted(tmp.glob("vmm_simple*.csv"))))
        print(json.dumps(rows[-1]), flush=True)
    keys = sorted({k for r in rows for k in r}, key=lambda k: (k not in ("model", "mode", "repeat"), k))
    tag = f"_{args.tag}" if args.tag else ""
    with open(out / f"compile_time{tag}.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)
    lines = [f"# Compile time per model: cold `python -m diffship.fit` process, empty vs warm cache" + (f" ({args.tag})" if args.tag else ""), "",
             f"Machine: {os.cpu_count()} CPUs shared with other sessions; load average at start "
             f"{' '.join(f'{x:.2f}' for x in load0)}, at end {' '.join(f'{x:.2f}' for x in os.getloadavg())}. "
             f"Total {(time.perf_counter() - t_all) / 60:.1f} min. Median over {args.repeats} repeat(s). "
             f"Data: two small synthetic runs per model (see `write_data`), default `--method both`; logged inputs "
             f"{'noisy (rudder 0.05°, thrust 1 %)' if args.input_noise else 'exact'}.", "",
             "| model | source | cold wall [s] | OE compile (cold) [s] | EE compile (cold) [s] | cached wall [s] | "
             "OE compile (cached) [s] | OE fit [s] | OE converged | load1 |",
             "|---|---|---:|---:|---:|---:|---:|---:|---|---:|"]

    def med(rs, k):
        v = [r[k] for r in rs if isinstance(r.get(k), (int, float))]
        return f"{np.median(v):.1f}" if v else "–"

    for name, src in ((n, s) for n in args.models for s in args.src):
        cold = [r for r in rows if r["model"] == name and r["mode"] == "cold" and r["src"] == (src or "")]
        warm = [r for r in rows if r["model"] == name and r["mode"] == "cached" and r["src"] == (src or "")]
        conv = ",".join(str(r.get("output_error_converged", r.get("error", "?"))) for r in cold)
        lines.append(f"| {name} | {src or '$PYTHONPATH'} | {med(cold, 'wall_s')} | {med(cold, 'output_error_compile_s')} | "
                     f"{med(cold, 'equation_error_compile_s')} | {med(warm, 'wall_s')} | "
                     f"{med(warm, 'output_error_compile_s')} | {med(warm, 'output_error_fit_s')} | {conv} | "
                     f"{med(cold, 'load1')} |")
    stop = [r for r in rows if r["mode"] == "particulars_stop"]
    for r in stop:
        lines += ["", f"Missing particulars (`python -m diffship.fit RUN.csv --model vmm_simple`, no vessel): whole process "
                      f"{r['median_s']:.2f} s median, {r['max_s']:.2f} s max of 5; exit {r['rc']}, {r['lines']} line: "
                      f"`{r['stderr']}...`"]
    hl = [r for r in rows if r["mode"] == "hlo"]
    if hl:
        lines += ["", "Lowered StableHLO lines per program (output-error kernel, all default-free parameters):", "",
                  "| model | vector field | residuals | Jacobian | LM solve |", "|---|---:|---:|---:|---:|"]
        lines += [f"| {r['model']} | {r.get('hlo_vector_field', r.get('error'))} | {r.get('hlo_residuals')} | "
                  f"{r.get('hlo_jacobian')} | {r.get('hlo_solve')} |" for r in hl]
    (out / f"compile_time{tag}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
