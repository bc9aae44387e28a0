"""Gap diagnosis on real data: where the 3-DOF MMG model misses on the KVLCC2 HSVA zigzags.

Trains the MMG model (published KVLCC2 L7 values as start, the free set of
:mod:`diffship.studies.kvlcc2`) on four starboard-first zigzags and diagnoses it on three
held-out zigzags (both port-first runs and a 15°/5° run). Reads the data from
``../shared/data/kvlcc2_hsva`` (not redistributable, never copied into the repository).

Usage::

    python -m benchmarks diagnose_kvlcc2 [--model mmg|nomoto2] [--horizon 60] [--dt 0.1] [--base published|study]

Writes ``benchmarks/results/diagnose_kvlcc2_<model>_<base>.md`` / ``.json`` and figures beside them.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import diffship  # noqa: F401
from diffship.data import kvlcc2_runs
from diffship.diagnose import DiagnoseOptions, diagnose
from diffship.diagnose.report import to_markdown, write_json, plot_all
from diffship.models import get_model

TRAIN = ("Z_10_05", "Z_20_05", "Z_35_05", "Z_20_10_S")
VALIDATE = ("Z_10_10_P", "Z_20_10_P", "Z_15_05")
OUT = Path(__file__).resolve().parent / "results"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", default="mmg")
    p.add_argument("--horizon", type=float, default=60.0, help="seconds of each run used [s]")
    p.add_argument("--dt", type=float, default=0.1)
    p.add_argument("--effects", default="all")
    p.add_argument("--base", default="published", choices=("published", "study"),
                   help="published: the model's published values, its default free set refitted (the first look); "
                        "study (mmg): the MAP fit of diffship.studies.kvlcc2 (33 coefficients under priors, "
                        "the propeller wake's manoeuvring correction and rudder interaction included) as the base, "
                        "its ten core hull coefficients refitted in the diagnosis (the second look)")
    a = p.parse_args(argv)
    runs = {r.metadata["test"]: r for r in kvlcc2_runs()}
    prep = {k: r.resample(a.dt).slice(None, r.t0 + a.horizon) for k, r in runs.items()}
    train, val = [prep[k] for k in TRAIN], [prep[k] for k in VALIDATE]
    t0 = time.perf_counter()
    effects = "all" if a.effects == "all" else a.effects.split(",")
    model, spec, note = get_model(a.model), None, "published values, default free set"
    if a.base == "study":
        from diffship.studies.kvlcc2 import TEN_FREE, kvlcc2_study

        study = kvlcc2_study(train=TRAIN, validate=VALIDATE, dt=a.dt, horizon=a.horizon, progress=print)
        model = study.fit.model
        spec = model.spec().only_free(list(TEN_FREE))
        note = (f"base: the KVLCC2 study's MAP fit ({len(study.fit.free)} coefficients under priors, "
                f"{'converged' if study.fit.converged else 'NOT converged: ' + study.fit.status}), "
                f"its ten core coefficients refitted")
    d = diagnose(model, train, val, spec=spec, options=DiagnoseOptions(effects=effects), progress=print)
    secs = time.perf_counter() - t0
    OUT.mkdir(exist_ok=True)
    stem = OUT / f"diagnose_kvlcc2_{a.model}_{a.base}"
    text = to_markdown(d)
    head = (f"Command: `python -m benchmarks diagnose_kvlcc2 --model {a.model} --horizon {a.horizon:g} --dt {a.dt:g} "
            f"--base {a.base}`; {note}; "
            f"train {', '.join(TRAIN)}; validate {', '.join(VALIDATE)}; {a.horizon:g} s per run at {a.dt:g} s; "
            f"{secs:.0f} s wall time.\n\n")
    stem.with_suffix(".md").write_text(head + text)
    write_json(d, stem.with_suffix(".json"))
    fig_dir = OUT / f"{stem.name}_figures"
    fig_dir.mkdir(exist_ok=True)
    plot_all(d, fig_dir)
    print(head + text)
