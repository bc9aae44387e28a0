"""``python -m diffship.fit``: the command-line front end of the fits (thin: parse arguments,
call the library, print, exit).

Errors a user can fix (bad files, columns, units, parameters, divergence) are printed as one
line ``error: ...`` on stderr with exit status 2 and no traceback.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

from ..data import example_runs, load_runs
from ..errors import DiffshipError
from ..integrators import INTEGRATORS, get_integrator
from ..metrics import evaluate
from ..models import MODELS, get_model
from ..params import parse_assignments
from ..preprocess import Filter
from ..report import plot_fit, text_report, to_json_dict, write_json
from .both import fit_both
from .output_error import OutputErrorOptions
from .prediction_error import PredictionErrorOptions, fit_prediction_error
from .problem import default_channels
from .shooting import fit_multiple_shooting, parse_shooting

__all__ = ["main", "build_parser"]


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m diffship.fit",
        description="Fit a manoeuvring model to measured runs by equation error and output error. "
        "With no RUN files, fits the bundled example (SSPA zigzag for nomoto1/2, "
        "synthetic USV runs for fossen3).",
    )
    p.add_argument("runs", nargs="*", metavar="RUN.csv", help="training runs (CSV; separator detected)")
    p.add_argument("--model", default="nomoto2", choices=tuple(MODELS), metavar="MODEL",
                   help=f"one of: {', '.join(MODELS)} (default nomoto2)")
    p.add_argument("--method", default="both", choices=("output-error", "equation-error", "prediction-error", "both"),
                   help="output-error (simulation error), equation-error (baseline), prediction-error (extended "
                        "Kalman filter innovations: for data with unmeasured disturbances) or both (EE then OE)")
    p.add_argument("--validate", nargs="*", default=[], metavar="RUN.csv", help="held-out runs")
    p.add_argument("--fix", nargs="*", default=[], metavar="NAME=VALUE", help="hold parameters fixed")
    p.add_argument("--free", nargs="*", default=[], metavar="NAME", help="estimate parameters fixed by default")
    p.add_argument("--init", nargs="*", default=[], metavar="NAME=VALUE", help="start values for output error")
    p.add_argument("--rudder-sign", default="starboard", choices=("starboard", "port"),
                   help="sign convention of delta in the files: starboard (positive turns to starboard) or port")
    p.add_argument("--columns", nargs="*", default=[], metavar="NAME=COLUMN", help="map channel names to file columns")
    p.add_argument("--degrees", nargs="*", default=[], metavar="COLUMN", help="columns given in degrees (deg/s)")
    p.add_argument("--channels", nargs="*", default=None, metavar="NAME", help="channels fitted by output error")
    p.add_argument("--x0", default="estimate", choices=("estimate", "data"),
                   help="initial states of fitted channels: estimated per run (default) or taken from the data")
    p.add_argument("--weights", default="noise", choices=("noise", "spread"),
                   help="output-error channel weights: noise (two passes, noise-normalised; default) or spread (one pass)")
    p.add_argument("--solver", default="diffrax-rk4", choices=tuple(INTEGRATORS),
                   help="integrator: diffrax-rk4 (default: diffrax's RK4 tableau, one step per sample), diffrax-tsit5 "
                        "(diffrax Tsit5, one step per sample), rk4 (hand-written RK4, faster Jacobian) or tsit5 "
                        "(diffrax Tsit5, adaptive within each sample)")
    p.add_argument("--filter", default="butter", help="equation-error differentiation filter: butter[:Hz], savgol[:s], none")
    p.add_argument("--resample", type=float, default=None, metavar="DT", help="resample runs to a uniform step [s]")
    p.add_argument("--out", default=None, metavar="DIR", help="write report.txt, fit.png (and fit.json) here")
    p.add_argument("--json", default=None, metavar="FILE", help="write the results as JSON")
    p.add_argument("--quiet", action="store_true", help="no progress messages")
    # -- estimators for sea data (issue 13) --
    p.add_argument("--shooting", default="single", metavar="single|multiple[:SEGMENT_S]",
                   help="output error by single shooting (default) or multiple shooting with segments of SEGMENT_S "
                        "seconds (default 20), finished by single shooting")
    p.add_argument("--disturbance", default="ou", choices=("ou", "white"),
                   help="prediction-error process noise: Ornstein–Uhlenbeck disturbance (default) or white")
    return p


def _progress(quiet: bool):
    t0 = time.perf_counter()

    def say(msg: str) -> None:
        if not quiet:
            print(f"[{time.perf_counter() - t0:6.1f} s] {msg}", file=sys.stderr, flush=True)

    return say


def _load(args, paths):
    columns = {k: v for k, v in (c.split("=", 1) if "=" in c else (c, "") for c in args.columns)}
    bad = [k for k, v in columns.items() if not v]
    if bad:
        raise DiffshipError(f"--columns {bad[0]}: expected NAME=COLUMN, e.g. --columns psi=heading")
    runs = load_runs(paths, columns=columns or None, degrees=args.degrees, rudder_sign=args.rudder_sign)
    if args.resample:
        runs = [r.resample(args.resample) for r in runs]
    return runs


def _example(model_name: str, say):
    if model_name == "fossen3":
        from ..synthetic import usv_runs  # only for the bundled fossen3 example

        say("no runs given: generating the bundled fossen3 example (seed-002 USV truth with added mass, "
            "4 runs × 120 s at 10 Hz, realistic GNSS/heading/gyro noise; run usv_3 held out)")
        runs = usv_runs(4, 120.0, 0.1, noise="realistic", seed=7)
        return runs[:3], runs[3:]
    if model_name not in ("nomoto1", "nomoto2"):
        raise DiffshipError(
            f"no bundled example for model {model_name} (there is one for nomoto1, nomoto2 and fossen3): "
            "give RUN.csv files, e.g. the KVLCC2 zigzags in ../shared/data/kvlcc2_hsva for mmg or vmm_*"
        )
    say("no runs given: fitting the bundled SSPA zigzag 20/20 (model test, 50 Hz; Apache-2.0, see "
        "src/diffship/examples/README.md), resampled to 10 Hz")
    runs = [r.resample(0.1) for r in example_runs("sspa_zigzag")]
    return runs, []


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 done, 1 no fit converged, 2 user error)."""
    args = build_parser().parse_args(argv)
    say = _progress(args.quiet)
    try:
        return _fit(args, say)
    except DiffshipError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


def _sea_estimators(args, model, train, spec, init, flt, options, shooting, results, say) -> dict:
    """Multiple-shooting output error and the prediction-error method (issue 13), started like
    output error in ``fit_both``: from ``--init`` or the model's values, or the equation-error estimate."""
    out = {}
    if shooting is None and args.method != "prediction-error":
        return out
    if init:
        spec = spec.with_values(init)
    ee = results.get("equation_error")
    starts = {"the equation-error estimate": {n: ee.params[n] for n in ee.free}} if ee else {}
    chans = tuple(args.channels) if args.channels else default_channels(model, train)
    est = model.states_for_channels(chans) if args.x0 == "estimate" else ()
    opts = dataclasses.replace(options, estimate_x0=est, flt=flt, choose="first" if init else "best")
    if shooting is not None:
        out["output_error"] = fit_multiple_shooting(model, train, spec=spec, starts=starts, channels=args.channels,
                                                    options=opts, shooting=shooting, progress=say)
    if args.method == "prediction-error":
        out["prediction_error"] = fit_prediction_error(
            model, train, spec=spec, starts=starts, channels=args.channels, options=opts,
            noise=PredictionErrorOptions(disturbance=args.disturbance), progress=say)
    return out


def _fit(args, say) -> int:
    model = get_model(args.model)
    fix = parse_assignments(args.fix, "--fix")
    init = parse_assignments(args.init, "--init")
    flt = Filter.parse(args.filter)
    spec = model.spec()
    for n in list(fix) + list(init):
        spec[n]  # unknown names fail early, with the list of valid ones
    spec = spec.free(args.free).fix(fix)
    if args.runs:
        train = _load(args, args.runs)
        val = _load(args, args.validate) if args.validate else []
    else:
        train, val = _example(args.model, say)
        if args.validate:
            val = _load(args, args.validate)
    methods = {"both": ("equation_error", "output_error"), "output-error": ("output_error",),
               "equation-error": ("equation_error",), "prediction-error": ()}[args.method]
    options = OutputErrorOptions(integrator=get_integrator(args.solver), weights=args.weights)
    shooting = parse_shooting(args.shooting)
    multiple = shooting is not None and "output_error" in methods
    results = fit_both(model, train, spec=spec, methods=tuple(m for m in methods if not (multiple and m == "output_error")),
                       init=init or None, flt=flt, estimate_x0="fitted" if args.x0 == "estimate" else (),
                       channels=args.channels, options=options, progress=say) if methods else {}
    results.update(_sea_estimators(args, model, train, spec, init, flt, options, shooting if multiple else None,
                                   results, say))
    say("simulating every run over its whole horizon for the metrics...")
    ev_train, ev_val = {}, {}
    for m, r in results.items():
        x0 = r.initial_states if m == "output_error" else None
        ev_train[m] = evaluate(r.model, train, x0, flt=flt, integrator=r.integrator)
        if val:
            ev_val[m] = evaluate(r.model, val, flt=flt, integrator=r.integrator)
    report = text_report(model.name, results, ev_train, ev_val, train, val)
    print(report)
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "report.txt").write_text(report + "\n")
        plot_fit(model.name, train, val, ev_train, ev_val, out / "fit.png")
        write_json(to_json_dict(model.name, results, ev_train, ev_val), out / "fit.json")
        say(f"wrote {out / 'report.txt'}, {out / 'fit.png'} and {out / 'fit.json'}")
    if args.json:
        write_json(to_json_dict(model.name, results, ev_train, ev_val), args.json)
        say(f"wrote {args.json}")
    if not any(r.converged for r in results.values()):
        print("error: no fit converged (see the statuses above)", file=sys.stderr)
        return 1
    return 0
