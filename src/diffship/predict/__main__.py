"""``python -m diffship.predict FIT.json --manoeuvre turning:35 zigzag:10/10 ...`` (thin: parse, call, print)."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from ..cli_options import (
    add_data_options,
    add_output_options,
    assignment,
    helm_rate,
    non_negative_int,
    out_folder_problem,
    positive_float,
)
from ..data import load_runs
from ..errors import DataError, DiffshipError
from ..log_options import add_log_options, log_kwargs
from .cross import RunType, cross_validate
from .cross_report import cross_json, cross_text, plot_cross
from .report import prediction_json, write_prediction


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m diffship.predict",
        description="Fly standard manoeuvres with a saved fit (python -m diffship.fit ... --out DIR writes "
                    "DIR/fit.json): first the training manoeuvres again beside their measured metrics, then the "
                    "asked manoeuvres: IMO metrics at model and full scale, intervals from the fit's covariance, "
                    "IMO 2002 (MSC.137(76)) criteria. Speeds, rates and times are at the fit's (model) scale; "
                    "approach speed, propeller setting, helm rate, switch delay and scale come from the fit file "
                    "(what was measured) unless given.",
        epilog="Exit status: 0 done (warnings on stderr for a fit labelled FAILED or doubtful), 2 a user error.")
    p.add_argument("fit", metavar="FIT.json", help="fit file (schema diffship.fit/1)")
    p.add_argument("--manoeuvre", "-m", nargs="+", action="extend", default=None,
                   metavar="SPEC", help="turning:ANGLE[:SIDE], zigzag:RUDDER/SWITCH[:SIDE], pullout[:ANGLE][:SIDE]; "
                   "SIDE starboard|port|+1|-1 (default starboard); default: turning:35 zigzag:10/10 zigzag:20/20 "
                   "(repeatable; items accumulate)")
    p.add_argument("--speed", type=positive_float, default=None, metavar="M/S",
                   help="approach speed [m/s] (default: the training runs' speed); the propulsion input from trim")
    p.add_argument("--rps", type=positive_float, default=None, metavar="REV/S",
                   help="propeller rate [rev/s] (input n); alone: the speed from trim")
    p.add_argument("--input", nargs="+", action="extend", type=assignment, default=[], metavar="NAME=VALUE",
                   help="the model's other constant inputs, e.g. n=10 (not delta: each manoeuvre sets the rudder; "
                        "repeatable; items accumulate)")
    p.add_argument("--scale", type=positive_float, default=None, metavar="LAMBDA",
                   help="length ratio L_full/L_model for full-scale values and criteria (default: the fit file's, "
                        "from the training data or the vessel file)")
    p.add_argument("--length", type=positive_float, default=None, metavar="M", help="ship length at the fit's scale "
                   "(default: the model's L)")
    p.add_argument("--helm-rate", type=helm_rate, default=None, metavar="DEG/S",
                   help="steering-gear rate [°/s] at the fit's scale (default: the rate measured in the training "
                        "runs, else IMO 2.32°/s × √λ)")
    p.add_argument("--delay", type=float, default=None, metavar="S",
                   help="zigzag autopilot delay [s] (default: the delay measured in the training zigzags, else 0)")
    p.add_argument("--duration", type=positive_float, default=None, metavar="S", help="simulated time per manoeuvre [s]")
    p.add_argument("--samples", type=non_negative_int, default=40,
                   help="parameter draws for the 95 %% intervals (0: none)")
    p.add_argument("--no-compare", action="store_true",
                   help="skip the first table (the training manoeuvres flown again beside their measured metrics)")
    p.add_argument("--measured", nargs="+", action="extend", default=[], metavar="RUN.csv",
                   help="measured runs to judge the fit on: every standard manoeuvre among them (zigzags' "
                        "overshoots, turning circles' diameters, ...) is simulated with its measured inputs and its "
                        "IMO metrics compared, trained types included (columns, units and rudder sign as for "
                        "python -m diffship.fit; repeatable)")
    add_data_options(p, validate=False, resample=False)
    add_output_options(p, out_help="write prediction.txt, prediction.json, prediction.png and the simulated runs (CSV)")
    add_log_options(p)  # --map (logs for --measured), --html (one self-contained report)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    t0 = time.perf_counter()
    problem = args.out and out_folder_problem(args.out)
    if problem:
        print(f"error: {problem}", file=sys.stderr)
        return 2
    try:
        from ..fitfile import load_fit
        from ..params import parse_assignments
        from .compare import compare_text, compare_training
        from .core import check_inputs, predict
        from .report import prediction_text

        fit = load_fit(args.fit)
        measured = _measured_runs(args, fit)  # before anything is flown: a bad file stops here
        inputs = parse_assignments(args.input, "--input")
        check_inputs(fit.model, inputs)
        if args.rps is not None:
            if "n" not in fit.model.input_names:
                raise DataError(f"--rps: model {fit.model.name} has no propeller-rate input n (its inputs: "
                                f"{', '.join(fit.model.input_names)}); give the approach speed with --speed")
            inputs["n"] = args.rps
        cond = dict(speed=args.speed, inputs=inputs or None, scale=args.scale, length=args.length,
                    helm_rate_deg_s=args.helm_rate, duration=args.duration)
        for w in _fit_warnings(fit):
            print(w, file=sys.stderr, flush=True)
        compare = None if args.no_compare else compare_training(fit, **cond)
        pred = predict(fit, args.manoeuvre or ["turning:35", "zigzag:10/10", "zigzag:20/20"], delay_s=args.delay,
                       samples=args.samples, **cond)
    except DiffshipError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if compare is not None:
        print(compare_text(compare) + "\n")
    print(prediction_text(pred))
    try:
        cross = _cross(args, pred, measured)
    except DiffshipError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if cross is not None:
        print("\n" + cross_text(cross))
    if args.out:
        files = write_prediction(pred, args.out)
        if cross is not None:  # the manoeuvre-validation section joins prediction.json; its own figure
            doc = {**prediction_json(pred), "cross_manoeuvre": cross_json(cross)}
            Path(files[1]).write_text(json.dumps(doc, indent=2))
            if cross.checks:
                files.append(Path(args.out) / "cross_manoeuvre.png")
                plot_cross(cross, files[-1])
        if not args.quiet:
            print(f"[{time.perf_counter() - t0:6.1f} s] wrote {', '.join(str(f) for f in files)}", file=sys.stderr)
    if args.html:
        from ..html import write_html_report

        text = prediction_text(pred) + ("\n\n" + cross_text(cross) if cross is not None else "")
        figs = lambda d: [f for f in write_prediction(pred, d)] + (  # noqa: E731
            [plot_cross(cross, d / "cross_manoeuvre.png") or d / "cross_manoeuvre.png"] if cross is not None else [])
        path = write_html_report(args.html, f"diffship prediction: {args.fit}", text, figs)
        if not args.quiet:
            print(f"[{time.perf_counter() - t0:6.1f} s] wrote {path}", file=sys.stderr)
    return 0


def _fit_warnings(fit) -> list[str]:
    from ..fitfile import fit_warnings

    return fit_warnings(fit)


def _measured_runs(args, fit):
    """The ``--measured`` runs, loaded and checked (rudder sign, the model's inputs), or ``None``."""
    if not args.measured:
        return None
    if fit.document.get("training_manoeuvres") is None:
        raise DiffshipError(f"{args.fit}: the fit file does not say which manoeuvre types it was trained on "
                            "(training_manoeuvres); refit with this version of python -m diffship.fit")
    from ..checks import check_rudder_sign

    runs = load_runs(args.measured, columns=dict(c.split("=", 1) for c in args.columns) or None,
                     degrees=args.degrees, rudder_sign=args.rudder_sign, time_unit=args.time_unit, **log_kwargs(args))
    check_rudder_sign(runs, args.rudder_sign)  # a port-positive record read as starboard stops here
    for r in runs:
        if missing := [c for c in fit.model.input_names if not r.has(c)]:
            raise DataError(f"--measured {r.metadata.get('source', r.name)}: no {', '.join(missing)} (its columns: "
                            f"{', '.join(r.channel_names)}); a manoeuvre is judged by flying the model with its "
                            f"measured inputs: map the column with --columns {missing[0]}=COLUMN or leave the run out")
    return runs


def _cross(args, pred, runs):
    """Cross-manoeuvre validation on the ``--measured`` runs; training types from the fit file."""
    if runs is None:
        return None
    from ..fitfile import load_fit

    fit = load_fit(args.fit)
    known = fit.document["training_manoeuvres"]
    return cross_validate(fit, [RunType.from_json(d) for d in known], runs,
                          samples=args.samples, length=pred.condition.length, trained_types=True)



if __name__ == "__main__":
    from ..cli_options import exit_now

    exit_now(main())
