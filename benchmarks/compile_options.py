"""XLA's optimisation level for diffship's CPU programs: the same lowered program compiled at each level.

:func:`diffship.compiled.compiler_options` compiles every diffship program on a CPU at
``xla_backend_optimization_level`` 1 (XLA's default is 3). This benchmark is the measurement
behind that choice. Each program is lowered **once** and compiled at XLA's default and at levels
0–3 in one process, then the compiled versions are called in turn (interleaved, so a machine
that slows down or speeds up during the run affects every level alike); it reports the compile
seconds, the median and fastest call, and the largest difference of any output from the
default's:

* ``fossen3 jacobian``: the output-error forward-mode Jacobian of the fossen3 USV on 2 runs × 240 s
  at 10 Hz (the diagnosis benchmark's machine probe);
* ``workspace solve``: the gap diagnosis's workspace solve program (fossen3 + the 11 candidate
  effects, 3 runs × 240 s; the USV current case of ``diagnose_current_case.py``), six Levenberg–Marquardt steps of a current refit;
* ``mmg jacobian``: the output-error Jacobian of the KVLCC2 MMG model on the four training HSVA
  zigzags (100 s at 0.2 s; needs ``../shared/data``, skipped without it).

Usage::

    python -m benchmarks compile_options            # writes benchmarks/results/compile_options.md
    python -m benchmarks compile_options --reps 5 --only fossen3
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

os.environ.setdefault("DIFFSHIP_CACHE_DIR", "off")  # every level compiled here, none loaded

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import diffship  # noqa: E402,F401
import diffship.compiled as C  # noqa: E402

from benchmarks.common.timing import commit as git_commit  # noqa: E402
from benchmarks.diagnose_current_case import oe_jacobian_request  # noqa: E402  (the machine probe's program)

OUT = Path(__file__).resolve().parent / "results"
LEVELS = (None, 0, 1, 2, 3)  # None: XLA's default (no option given)


def fossen3_case():
    from diffship.models import Fossen3
    from diffship.synthetic import usv_runs, usv_truth
    spec = Fossen3().spec().with_values(usv_truth().param_values())
    runs = usv_runs(2, 240.0, 0.1, noise="realistic", seed=99)
    return oe_jacobian_request(Fossen3().with_params(spec.values()), spec, runs, ("x0", "y0", "psi", "u", "v", "r"))


def workspace_case():
    from diffship.diagnose.diagnosis import diagnosis_channels
    from diffship.diagnose.screen import Workspace
    from diffship.models import Fossen3
    from diffship.models.effects import augment, library
    from diffship.synthetic import simulate_run, usv_excitation, usv_truth
    truth = augment(usv_truth(), "current", Vcx=0.125, Vcy=0.2165)
    runs = []
    for i in range(3):
        t, inp = usv_excitation(240.0, 0.1, seed=7100 + i)
        runs.append(simulate_run(truth, t, inp, np.asarray(truth.initial_state({"u": 2.0})), name=f"usv{i}",
                                 noise="realistic", seed=1000 + i))
    base = Fossen3().with_params(usv_truth().param_values())
    spec = Fossen3().spec().with_values(usv_truth().param_values())
    chans = diagnosis_channels(base, runs)
    names = ["current", "input_delay", "actuator_lag", "rate_limit", "constant_force", "heading_bias", "damping_vv",
             "damping_rr", "damping_vr", "damping_rv", "speed_dependence"]
    effs, _ = library(base, runs, names)
    ws = Workspace(base, spec, effs, runs, chans, {c: 1.0 for c in chans}, max_iter=60, stall=(10, 1e-3))
    z = jnp.asarray(ws.z0())
    kd = ws._kd(None, ws.selection([]), ws.phi_null)
    request = ws.kernel.requests([("solve", z, kd, ws._solve_static(ws.max_iter, ws.stall))])[0]
    kd6 = kd.with_step_cap(6).replace(S=jnp.asarray(ws.selection(["Vcx", "Vcy"])))
    return request, (z, kd6)


def mmg_case():
    from diffship.data import kvlcc2_runs
    from diffship.models.mmg import kvlcc2_mmg
    from diffship.studies.kvlcc2 import DEFAULT_CHANNELS, DEFAULT_FREE, DEFAULT_TRAIN
    try:
        allruns = kvlcc2_runs()
    except Exception as e:  # noqa: BLE001 — no shared data here
        return f"skipped: {e}"
    runs = []
    for k in DEFAULT_TRAIN:
        r = next(r for r in allruns if r.name.endswith(k))
        runs.append(r.resample(0.2).slice(None, r.time[0] + 100.0))
    model = kvlcc2_mmg()
    spec = model.spec().only_free(list(DEFAULT_FREE))
    return oe_jacobian_request(model, spec, runs, DEFAULT_CHANNELS)


CASES = {"fossen3": ("fossen3 jacobian", fossen3_case), "workspace": ("workspace solve (6 LM steps)", workspace_case),
         "mmg": ("mmg jacobian", mmg_case)}


def measure(label, build, reps):
    got = build()
    if isinstance(got, str):
        return [f"| {label} | {got} | | | | |"]
    request, args = got
    lowered, wrap = C._lowered(*request)
    progs, comp = {}, {}
    for lvl in LEVELS:
        t0 = time.perf_counter()
        opts = {} if lvl is None else {"xla_backend_optimization_level": lvl}
        progs[lvl] = wrap(lowered.compile(compiler_options=opts))
        comp[lvl] = time.perf_counter() - t0
        print(f"{label}: level {lvl if lvl is not None else 'default'} compiled in {comp[lvl]:.2f} s", flush=True)
    outs, times = {}, {lvl: [] for lvl in LEVELS}
    for _ in range(reps):
        for lvl in LEVELS:
            if lvl == 0 and len(times[0]) >= 2:  # ten times slower: two calls say it
                continue
            t0 = time.perf_counter()
            outs[lvl] = jax.block_until_ready(progs[lvl](*args))
            times[lvl].append(time.perf_counter() - t0)
    ref = [np.asarray(a) for a in jax.tree_util.tree_leaves(outs[None])]
    rows = []
    for lvl in LEVELS:
        got = [np.asarray(a) for a in jax.tree_util.tree_leaves(outs[lvl])]
        diff = max((float(np.max(np.abs(a - b))) for a, b in zip(got, ref) if a.dtype.kind == "f" and a.size), default=0.0)
        name = "default (3)" if lvl is None else str(lvl)
        rows.append(f"| {label} | {name} | {comp[lvl]:.2f} | {1e3 * np.median(times[lvl]):.1f} | "
                    f"{1e3 * min(times[lvl]):.1f} | {diff:.2g} |")
        print(rows[-1], flush=True)
    return rows


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--reps", type=int, default=15, help="calls per level (interleaved)")
    p.add_argument("--only", default=",".join(CASES), help="comma list of: " + ", ".join(CASES))
    p.add_argument("--no-write", action="store_true")
    a = p.parse_args(argv)
    rows = []
    for key in a.only.split(","):
        label, build = CASES[key]
        rows += measure(label, build, a.reps if key != "workspace" else max(3, a.reps // 4))
    load = os.getloadavg()
    commit = git_commit()
    text = "\n".join([
        "# XLA optimisation level of diffship's CPU programs",
        "",
        f"Command: `python -m benchmarks compile_options{'' if argv is None else ' ' + ' '.join(argv)}` at {commit}; "
        f"{os.cpu_count()} cores, {platform.processor() or platform.machine()}, jax {jax.__version__}; "
        f"load average {load[0]:.1f} at the end. One lowered program per row group, compiled at each level in one "
        "process and called in turn (module docstring). diffship compiles at level 1 "
        "(`diffship.compiled.compiler_options`).",
        "",
        "| program | level | compile s | median call ms | fastest call ms | max abs. difference from default |",
        "|---|---|---|---|---|---|",
        *rows, ""])
    print(text)
    if not a.no_write:
        (OUT / "compile_options.md").write_text(text)
    return 0
