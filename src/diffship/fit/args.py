"""The command line of ``python -m diffship.fit``: its arguments, and the checks that need no JAX.

:func:`build_parser` is the one argument parser of the fit command. :func:`precheck` runs, before
JAX or NumPy is imported, the checks a user most often fails: a model that needs the vessel's
particulars (mass, inertia, dimensions, ...) given neither ``--vessel`` nor ``--fix`` for them stops
here, in a fraction of a second, with the same one line the full command prints
(:func:`diffship.particulars.missing_message`); so do held-out runs without a training run, options that
contradict each other and outputs that would overwrite an input (:mod:`diffship.fit.inputs`). Everything
else is checked by :mod:`diffship.fit.cli`. This module imports only the standard library and the
plain-Python tables (:mod:`diffship.particulars`, :mod:`diffship.channels`) and checks
(:mod:`diffship.fit.inputs`); ``tests/fit/test_args.py`` checks that.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

from ..cli_options import (
    INTEGRATOR_NAMES,
    add_bootstrap_options,
    add_data_options,
    add_numerics_options,
    add_output_options,
    add_parameter_options,
    add_prior_options,
    add_vessel_option,
)
from ..log_options import add_log_options
from ..particulars import MODEL_PARTICULARS, missing_message, missing_particulars
from .inputs import input_problem

__all__ = ["INTEGRATOR_NAMES", "build_parser", "precheck", "starts_option"]

def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m diffship.fit",
        description="Fit a manoeuvring model to measured runs by equation error and output error. "
        "With no RUN files, fits the bundled example (SSPA zigzag for nomoto1/2, "
        "synthetic USV runs for fossen3).",
        epilog="Exit status: 0 a usable fit; 1 no method produced a usable fit (the reason is the last line); "
               "2 a user error (one line on stderr). List options may be repeated: their items accumulate.",
    )
    p.add_argument("runs", nargs="*", metavar="RUN.csv", help="training runs (CSV; separator detected)")
    p.add_argument("--model", default="nomoto2", choices=tuple(MODEL_PARTICULARS), metavar="MODEL",
                   help=f"one of: {', '.join(MODEL_PARTICULARS)} (default nomoto2)")
    p.add_argument("--method", default="both", choices=("output-error", "equation-error", "prediction-error", "both"),
                   help="output-error (simulation error), equation-error (baseline), prediction-error (extended "
                        "Kalman filter innovations: for data with unmeasured disturbances) or both (EE then OE); decay1/decay2 curve fits: python -m diffship.decay")
    add_data_options(p)
    add_parameter_options(p)
    p.add_argument("--x0", default="estimate", choices=("estimate", "data"),
                   help="initial states: estimate (default): every run's initial state is an unknown of the fit, held "
                        "within its sensor noise by its first sample (states no channel measures free); the metrics "
                        "and held-out runs use the same rule with the parameters held (diffship.initial); data: "
                        "the filtered first sample taken as exact (a noisy first sample biases every estimate; the "
                        "report says what it costs)")
    p.add_argument("--positions", default="test", choices=("test", "off"),
                   help="measured positions (x0, y0) with the channels left at their default: test (default): the "
                        "fit without them is refitted with them, and the refit kept where a Hausman test finds the "
                        "two agree (where the model misses, a position's drift decides the fit); off: not fitted "
                        "(one fit, faster). --channels naming them fits them anyway")
    p.add_argument("--as-given", action="store_true",
                   help="fit with the options as given; without it a fit that is not usable is refitted with the "
                        "first option its report names (--free-hydrodynamic, then --horizon S), each step said and "
                        "listed in the report")
    p.add_argument("--weights", default="noise", choices=("noise", "spread"),
                   help="output-error channel weights: noise (default: each channel's residual RMS times the square "
                        "root of its correlation time, re-estimated to the likelihood's optimum) or spread (one pass)")
    add_numerics_options(p, filter_help=(
        "equation-error differentiation filter: butter[:Hz], savgol[:s], none, or kalman (extended "
        "Kalman filter + RTS smoother over the model at its starting values, noise levels estimated; "
        "initial states and metrics then use butter)"))
    add_output_options(p, out_help="write report.txt, fit.png, report.json and the fit file fit.json here",
                       json_help="write the results as JSON")
    p.add_argument("--save", default=None, metavar="FILE",
                   help="write the fit file (diffship.fit/1 JSON, for python -m diffship.predict) here")
    p.add_argument("--check-sampling", action="store_true",
                   help="with --resample: refit at the files' own rate and warn where the estimates move by more "
                        "than their intervals")
    p.add_argument("--skip-sign-check", action="store_true",
                   help="do not stop when the heading turns against the rudder (or yaw moment) in a run")
    g = add_prior_options(p)
    g.add_argument("--admissibility", default="auto", choices=("auto", "off"),
                   help="after the fit, simulate standard manoeuvres (35° turns, 10/10 and 20/20 zigzags, pull-out) "
                        "and check damping over a wide envelope (auto: for models with a rudder input)")
    add_bootstrap_options(p)
    _add_vessel_arguments(p)
    add_log_options(p)  # --map (logs), --html (one self-contained report)
    # -- estimators for sea data --
    p.add_argument("--shooting", default="single", metavar="single|multiple[:SEGMENT_S]",
                   help="output error by single shooting (default) or multiple shooting with segments of SEGMENT_S "
                        "seconds (default 20), finished by single shooting")
    p.add_argument("--disturbance", default="ou", choices=("ou", "wave", "walk", "white", "auto"),
                   help="prediction-error process noise: Ornstein–Uhlenbeck disturbance (default), a narrow-band wave "
                        "(period and damping estimated: at sea), a random walk, white, or auto (fit ou and wave, keep "
                        "the lower Akaike criterion of the filter's likelihood; twice the time)")
    return p


def _add_vessel_arguments(p: argparse.ArgumentParser) -> None:
    add_vessel_option(p)
    p.add_argument("--rigid-body-cg", action="store_true",
                   help="fossen6: use the CG offset in the rigid-body inertia and Coriolis terms (full M_RB(r_g))")
    p.add_argument("--propulsion", default="thrust", metavar="thrust|propeller|constant:N",
                   help="vmm_*: thrust from the measured 'thrust' column [N] (default), from the propeller speed column "
                        "'n' [1/s] through the vessel's open-water curve (propeller), or a constant [N]")




def _names(items: Sequence[str]) -> list[str] | None:
    """Parameter names of ``NAME=VALUE`` items, or ``None`` if any item is malformed (the full command
    reports it, with its own message)."""
    out = []
    for item in items:
        name, sep, value = item.partition("=")
        try:
            float(value)
        except ValueError:
            return None
        if not sep or not name.strip():
            return None
        out.append(name.strip())
    return out


def precheck(argv: Sequence[str] | None = None) -> str | None:
    """The error line for a fit that cannot start, found without JAX; ``None`` when the full command
    must decide. Argument errors exit here as in the full command (argparse, status 2).

    Covers :func:`diffship.fit.inputs.input_problem` (held-out runs without a training run, contradictory
    options, outputs that would overwrite an input or cannot be written) and the common case: a model that
    needs particulars, given no vessel, and ``--fix`` / ``--free`` not covering them. With ``--vessel``
    (whose file must be read), ``--rigid-body-cg``, a malformed ``--fix``/``--init``, or the bundled fossen3
    example (which brings its own vessel), the full command checks as before.
    """
    args = build_parser().parse_args(argv)
    if (problem := input_problem(args)) is not None:  # contradictory options, outputs over inputs
        return problem
    needs = MODEL_PARTICULARS[args.model]
    if args.vessel is not None or args.rigid_body_cg or not needs.particulars:
        return None
    if not args.runs and args.model == "fossen3":
        return None  # the bundled example's vessel
    fixed, init = _names(args.fix), _names(args.init)
    if fixed is None or init is None:
        return None
    missing = missing_particulars(needs.particulars, fixed, args.free)
    if not missing:
        return None
    return missing_message(needs.name, needs.particulars, needs.reference_vessel, missing)


def starts_option(args) -> dict:
    """``--starts N`` for the fit driver; ``{}`` when not given."""
    return {} if args.starts is None else {"n_starts": args.starts}
