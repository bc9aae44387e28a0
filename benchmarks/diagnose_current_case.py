"""The USV current case: a USV (fossen3 test truth) in a constant current, 3 training + 2 held-out runs.

The current is Vcx 0.125, Vcy 0.2165 m/s (0.25 m/s towards 60°). A diagnosis must attribute it on
the held-out runs, whose initial states follow the start rule of :mod:`diffship.diagnose.start` (a
freely estimated start lets the base model start 15–30 m off the logged position and hide the
drift). This runs the whole diagnosis (base fit, screen, refits, selection, time-variation check)
and writes what it says.

    python -m benchmarks diagnose_current_case               # 240 s runs, every library effect a candidate
    python -m benchmarks diagnose_current_case --cli         # the same runs through python -m diffship.diagnose
    python -m benchmarks diagnose_current_case --effects current,heading_bias,actuator_lag,damping_vv --null

``--cli`` writes the runs as CSV files and times the command a user runs (``python -m diffship.diagnose
TRAIN.csv ... --validate VAL.csv ... --model fossen3 --vessel usv --out DIR``) as a whole process,
figures and report included, with the compile cache of ``$DIFFSHIP_CACHE_DIR`` (a new folder: cold).

Writes ``benchmarks/results/diagnose_current_case[_null|_cli].md`` (another ``--duration`` adds
``_<duration>s``), with a machine probe (:func:`machine_probe`, about 6 s of fixed work before the timer
starts) beside the timings: the same code took 80–85 s and 111–120 s on one 2-core machine an hour
apart, so a timing is read with the probe of its run.
"""

from __future__ import annotations

import argparse
import os
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import diffship  # noqa: F401
from benchmarks.common.timing import commit as git_commit
from diffship.diagnose import DiagnoseOptions, diagnose
from diffship.models import Fossen3
from diffship.models.effects import augment
from diffship.synthetic import simulate_run, usv_excitation, usv_truth

OUT = Path(__file__).resolve().parent / "results"



def oe_jacobian_request(model, spec, runs, channels):
    """diffship's output-error forward-mode Jacobian program of ``model`` on ``runs`` (initial
    states estimated, zero offsets): ``((kernel, "jacobian", (z, data), {}), (z, data))`` — the
    :mod:`diffship.compiled` request and its arguments (the machine probe; ``compile_options.py``)."""
    import jax.numpy as jnp
    from diffship.fit.kernel import Kernel, kernel_data
    from diffship.fit.output_error import channel_spread, x0_scales
    from diffship.fit.problem import make_batch

    batch = make_batch(model, runs, channels)
    est = model.states_for_channels(channels)
    kern = Kernel(spec=spec.structural(), out_idx=tuple(model.output_names.index(c) for c in channels),
                  angle=tuple(c == "psi" for c in channels), x0_idx=tuple(model.state_names.index(s) for s in est))
    data = kernel_data(model, batch.ts, batch.us, batch.ys, batch.mask, batch.x0, channel_spread(batch),
                       x0_scale=x0_scales(model, batch, est))
    z = jnp.asarray(np.concatenate([spec.to_z(), np.zeros(len(runs) * len(est))]))
    return (kern, "jacobian", (z, data), {}), (z, data)


def machine_probe() -> str:
    """A fixed workload timed before the diagnosis, so that timings from machines (or periods of one
    machine) of different speed can be compared: diffship's own fossen3 output-error forward-mode
    Jacobian program on two runs (2 × 240 s; shapes the diagnosis never uses, so nothing it compiles
    is shared), compiled (cold with an empty cache) and called. It is the kind of program the
    diagnosis runs: in a slow period of one machine the diagnosis's own workspace Jacobian took 276 ms
    and its solve program 21.5 s to compile, against 162 ms and 13.6 s an hour earlier."""
    import jax
    from diffship.synthetic import usv_runs

    spec = Fossen3().spec().with_values(usv_truth().param_values())
    runs = usv_runs(2, 240.0, 0.1, noise="realistic", seed=99)
    (kern, _, (z, data), _), _ = oe_jacobian_request(Fossen3().with_params(spec.values()), spec, runs,
                                                     ("x0", "y0", "psi", "u", "v", "r"))
    t0 = time.perf_counter()
    jac, _ = kern.compiled("jacobian", z, data)
    t_c = time.perf_counter() - t0
    jax.block_until_ready(jac(z, data))
    t0 = time.perf_counter()
    for _ in range(10):
        jax.block_until_ready(jac(z, data))
    t_r = (time.perf_counter() - t0) / 10
    return (f"machine probe (`machine_probe()`: fixed work, smaller is faster): fossen3 Jacobian program, 2 runs × "
            f"240 s, compile {t_c:.2f} s, one call {1e3 * t_r:.1f} ms")


def _stem(a) -> str:
    """The result's name: ``diagnose_current_case`` at the default 240 s, else with ``_<duration>s``."""
    return "diagnose_current_case" + ("" if a.duration == 240.0 else f"_{a.duration:g}s")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=240.0, help="seconds per run")
    p.add_argument("--effects", default="all")
    p.add_argument("--null", action="store_true", help="the same runs without the current (nothing to attribute)")
    p.add_argument("--cli", action="store_true", help="time python -m diffship.diagnose on the runs as CSV files")
    a = p.parse_args(argv)
    truth = usv_truth() if a.null else augment(usv_truth(), "current", Vcx=0.125, Vcy=0.2165)
    runs = []
    for i in range(5):
        t, inp = usv_excitation(a.duration, 0.1, seed=7100 + i)
        runs.append(simulate_run(truth, t, inp, np.asarray(truth.initial_state({"u": 2.0})), name=f"usv{i}",
                                 noise="realistic", seed=1000 + i))
    effects = "all" if a.effects == "all" else a.effects.split(",")
    if a.cli:
        return cli(a, runs)
    probe = machine_probe()
    load0 = os.getloadavg()
    t0, c0 = time.perf_counter(), time.process_time()
    d = diagnose(Fossen3(), runs[:3], runs[3:], options=DiagnoseOptions(effects=effects),
                 progress=lambda s: print(s, file=sys.stderr, flush=True))
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    load1 = os.getloadavg()
    commit = git_commit()
    fp = d.final_model.param_values()
    L = [f"# Diagnosis of the USV current case ({a.duration:g} s runs{', NULL: no current' if a.null else ''})", "",
         f"Command: `python -m benchmarks diagnose_current_case --duration {a.duration:g}"
         + (f" --effects {a.effects}" if a.effects != "all" else "") + (" --null" if a.null else "")
         + f"` at {commit}; 2-core machine shared "
         f"with other jobs (1-min load average {load0[0]:.1f} at the start, {load1[0]:.1f} at the end; 5-min "
         f"{load1[1]:.1f}): diagnosis wall {wall:.0f} s, CPU {cpu:.0f} s (all threads; the data simulation "
         f"before it not counted).", "", probe + ".", "",
         ("Truth: fossen3 test USV, no current" if a.null else "Truth: fossen3 test USV + current Vcx 0.125, Vcy 0.2165 m/s")
         + "; 3 training + 2 held-out runs at 10 Hz, realistic noise.", "",
         f"- selected: {list(d.selected)}; possible: {list(d.possible)}",
         f"- fitted current: " + (f"Vcx {fp['Vcx']:.4f}, Vcy {fp['Vcy']:.4f} m/s" if "Vcx" in fp else "none"),
         f"- held-out E {d.E_before:.3g} → {d.E_after:.3g} (gate {d.gap_gate:.3f}), shrink {d.shrink:.2f}",
         f"- timings [s]: " + ", ".join(f"{k} {v:.0f}" for k, v in d.timings.items()), "", "Verdict:", ""]
    L += [f"> {x}  " for x in d.verdict]
    text = "\n".join(L) + "\n"
    (OUT / f"{_stem(a)}{'_null' if a.null else ''}.md").write_text(text)
    print(text)


def cli(a, runs) -> None:
    """The user's command on the same runs, timed as a whole process."""
    probe = machine_probe()
    with tempfile.TemporaryDirectory() as tmp:
        paths = []
        for r in runs:
            paths.append(str(Path(tmp) / f"{r.name}.csv"))
            r.to_dataframe().to_csv(paths[-1], index=False)
        cmd = [sys.executable, "-m", "diffship.diagnose", *paths[:3], "--validate", *paths[3:], "--model", "fossen3",
               "--vessel", "usv", "--out", str(Path(tmp) / "out"), "--json", str(Path(tmp) / "d.json")]
        if a.effects != "all":
            cmd += ["--effects", a.effects]
        load0 = os.getloadavg()
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        load1 = os.getloadavg()
        if proc.returncode != 0:
            sys.exit(f"python -m diffship.diagnose failed ({proc.returncode}): {proc.stderr[-2000:]}")
        doc = json.loads((Path(tmp) / "d.json").read_text())
    commit = git_commit()
    cache = os.environ.get("DIFFSHIP_CACHE_DIR", "the default compile cache")
    L = [f"# The USV current case through `python -m diffship.diagnose` ({a.duration:g} s runs)", "",
         f"Command: `python -m benchmarks diagnose_current_case --duration {a.duration:g} --cli` at {commit} "
         f"(compile cache {cache}); 1-min load average {load0[0]:.1f} at the start, {load1[0]:.1f} at the end.", "",
         f"- whole process (figures and report included): **{wall:.1f} s**", f"- {probe}",
         f"- selected: {doc.get('selected')}; held-out E {doc.get('validation_E_before', float('nan')):.3g} → "
         f"{doc.get('validation_E_after', float('nan')):.3g}; timings [s] {doc.get('timings_s')}; current {({k: round(v, 4) for k, v in doc.get('final_params', {}).items() if k in ('Vcx', 'Vcy')})}", ""]
    text = "\n".join(L) + "\n"
    (OUT / f"{_stem(a)}_cli.md").write_text(text)
    print(text)
