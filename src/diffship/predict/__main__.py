"""``python -m diffship.predict FIT.json --manoeuvre turning:35 zigzag:10/10 ...`` (thin: parse, call, print)."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from ..data import load_runs
from ..errors import DiffshipError
from ..log_options import add_log_options, log_kwargs
from ..params import parse_assignments
from .core import predict
from .cross import RunType, cross_validate
from .cross_report import cross_json, cross_text, plot_cross
from .report import prediction_json, prediction_text, write_prediction


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m diffship.predict",
        description="Fly standard manoeuvres with a saved fit (python -m diffship.fit ... --out DIR writes "
                    "DIR/fit.json): IMO metrics at model and full scale, intervals from the fit's covariance, "
                    "IMO 2002 (MSC.137(76)) criteria. Speeds, rates and times are at the fit's (model) scale.")
    p.add_argument("fit", metavar="FIT.json", help="fit file (schema diffship.fit/1)")
    p.add_argument("--manoeuvre", "-m", nargs="+", default=["turning:35", "zigzag:10/10", "zigzag:20/20"],
                   metavar="SPEC", help="turning:ANGLE[:SIDE], zigzag:RUDDER/SWITCH[:SIDE], pullout[:ANGLE][:SIDE]; "
                   "SIDE starboard|port|+1|-1 (default starboard); default: turning:35 zigzag:10/10 zigzag:20/20")
    p.add_argument("--speed", type=float, default=None, metavar="M/S",
                   help="approach speed [m/s] (default: the training runs' speed); the propulsion input from trim")
    p.add_argument("--rps", type=float, default=None, metavar="REV/S",
                   help="propeller rate [rev/s] (input n); alone: the speed from trim")
    p.add_argument("--input", nargs="*", default=[], metavar="NAME=VALUE", help="other constant inputs")
    p.add_argument("--scale", type=float, default=None, metavar="LAMBDA",
                   help="length ratio L_full/L_model for full-scale values and criteria (default: the fit file's)")
    p.add_argument("--length", type=float, default=None, metavar="M", help="ship length at the fit's scale "
                   "(default: the model's L)")
    p.add_argument("--helm-rate", type=float, default=None, metavar="DEG/S",
                   help="steering-gear rate [°/s] at the fit's scale (default: IMO 2.32°/s × √λ)")
    p.add_argument("--delay", type=float, default=0.0, metavar="S", help="zigzag autopilot delay [s] (default 0)")
    p.add_argument("--duration", type=float, default=None, metavar="S", help="simulated time per manoeuvre [s]")
    p.add_argument("--samples", type=int, default=40, help="parameter draws for the 95 %% intervals (0: none)")
    p.add_argument("--measured", nargs="*", default=[], metavar="RUN.csv",
                   help="measured runs to judge the fit on (cross-manoeuvre validation): runs of manoeuvre types "
                        "the fit was not trained on are simulated with their measured inputs and their IMO metrics "
                        "compared (columns and units as for python -m diffship.fit; starboard-positive rudder)")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="write prediction.txt, prediction.json, prediction.png and the simulated runs (CSV)")
    p.add_argument("--quiet", action="store_true")
    add_log_options(p)  # --map (logs for --measured), --html (issue 30)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    t0 = time.perf_counter()
    try:
        inputs = parse_assignments(args.input, "--input")
        if args.rps is not None:
            inputs["n"] = args.rps
        pred = predict(args.fit, args.manoeuvre, speed=args.speed, inputs=inputs or None, scale=args.scale,
                       length=args.length, helm_rate_deg_s=args.helm_rate, delay_s=args.delay,
                       duration=args.duration, samples=args.samples)
    except DiffshipError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(prediction_text(pred))
    try:
        cross = _cross(args, pred)
    except DiffshipError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if cross is not None:
        print("\n" + cross_text(cross))
    if args.out:
        files = write_prediction(pred, args.out)
        if cross is not None:  # the cross-manoeuvre section joins prediction.json; its own figure
            doc = {**prediction_json(pred), "cross_manoeuvre": cross_json(cross)}
            Path(files[1]).write_text(json.dumps(doc, indent=2))
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


def _cross(args, pred):
    """Cross-manoeuvre validation on ``--measured`` runs; training types from the fit file."""
    if not args.measured:
        return None
    from ..fitfile import load_fit

    fit = load_fit(args.fit)
    known = fit.document.get("training_manoeuvres")
    if known is None:
        raise DiffshipError(f"{args.fit}: the fit file does not say which manoeuvre types it was trained on "
                            "(training_manoeuvres); refit with this version of python -m diffship.fit")
    return cross_validate(fit, [RunType.from_json(d) for d in known], load_runs(args.measured, **log_kwargs(args)),
                          samples=args.samples, length=pred.condition.length)



if __name__ == "__main__":
    sys.exit(main())
