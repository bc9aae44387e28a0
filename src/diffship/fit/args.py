"""The command line of ``python -m diffship.fit``: its arguments, and the checks that need no JAX.

:func:`build_parser` is the one argument parser of the fit command. :func:`precheck` runs, before
JAX or NumPy is imported, the checks a user most often fails: a model that needs the vessel's
particulars (mass, inertia, dimensions, ...) given neither ``--vessel`` nor ``--fix`` for them stops
here, in a fraction of a second, with the same one line the full command prints
(:func:`diffship.particulars.missing_message`). Everything else is checked by :mod:`diffship.fit.cli`.
This module imports only the standard library and the plain-Python tables
(:mod:`diffship.particulars`, :mod:`diffship.channels`); ``tests/fit/test_args.py`` checks that.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

from ..channels import CHANNEL_NAMES
from ..log_options import add_log_options
from ..particulars import MODEL_PARTICULARS, bundled_vessels, missing_message, missing_particulars

__all__ = ["INTEGRATOR_NAMES", "build_parser", "precheck"]

#: ``--solver`` choices: the keys of :data:`diffship.integrators.INTEGRATORS` (a test checks they agree).
INTEGRATOR_NAMES = ("diffrax-rk4", "diffrax-tsit5", "rk4", "tsit5")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m diffship.fit",
        description="Fit a manoeuvring model to measured runs by equation error and output error. "
        "With no RUN files, fits the bundled example (SSPA zigzag for nomoto1/2, "
        "synthetic USV runs for fossen3).",
    )
    p.add_argument("runs", nargs="*", metavar="RUN.csv", help="training runs (CSV; separator detected)")
    p.add_argument("--model", default="nomoto2", choices=tuple(MODEL_PARTICULARS), metavar="MODEL",
                   help=f"one of: {', '.join(MODEL_PARTICULARS)} (default nomoto2)")
    p.add_argument("--method", default="both", choices=("output-error", "equation-error", "prediction-error", "both"),
                   help="output-error (simulation error), equation-error (baseline), prediction-error (extended "
                        "Kalman filter innovations: for data with unmeasured disturbances) or both (EE then OE); decay1/decay2 curve fits: python -m diffship.decay")
    p.add_argument("--validate", nargs="*", default=[], metavar="RUN.csv", help="held-out runs")
    p.add_argument("--fix", nargs="*", default=[], metavar="NAME=VALUE", help="hold parameters fixed")
    p.add_argument("--free", nargs="*", default=[], metavar="NAME", help="estimate parameters fixed by default")
    p.add_argument("--init", nargs="*", default=[], metavar="NAME=VALUE", help="start values for output error")
    p.add_argument("--rudder-sign", default="starboard", choices=("starboard", "port"),
                   help="sign convention of delta in the files: starboard (positive turns to starboard) or port")
    p.add_argument("--columns", nargs="*", default=[], metavar="NAME=COLUMN",
                   help="map diffship channel names to file columns, e.g. psi=heading. Channel names: "
                        + ", ".join(f"{c} [{u}]" for c, u in CHANNEL_NAMES.items()) + "; columns with other "
                        "names are kept under their own names")
    p.add_argument("--degrees", nargs="*", default=[], metavar="COLUMN", help="columns given in degrees (deg/s)")
    p.add_argument("--channels", nargs="*", default=None, metavar="NAME", help="channels fitted by output error")
    p.add_argument("--x0", default="data", choices=("estimate", "data"),
                   help="initial states in the fit: taken from the data (default: the measured, filtered state every "
                        "metric starts from, so the fit minimises what it is judged by) or estimated per run with the "
                        "parameters within each channel's noise (for a noisy first sample: a heading offset never "
                        "decays and biases the estimates)")
    p.add_argument("--weights", default="noise", choices=("noise", "spread"),
                   help="output-error channel weights: noise (two passes, noise-normalised; default) or spread (one pass)")
    p.add_argument("--solver", default="diffrax-rk4", choices=INTEGRATOR_NAMES,
                   help="integrator: diffrax-rk4 (default: diffrax's RK4 tableau, one step per sample), diffrax-tsit5 "
                        "(diffrax Tsit5, one step per sample), rk4 (hand-written RK4, faster Jacobian) or tsit5 "
                        "(diffrax Tsit5, adaptive within each sample)")
    p.add_argument("--filter", default="butter",
                   help="equation-error differentiation filter: butter[:Hz], savgol[:s], none, or kalman (extended "
                        "Kalman filter + RTS smoother over the model at its starting values, noise levels estimated; "
                        "initial states and metrics then use butter)")
    p.add_argument("--resample", type=float, default=None, metavar="DT", help="resample runs to a uniform step [s]")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="write report.txt, fit.png, report.json and the fit file fit.json here")
    p.add_argument("--save", default=None, metavar="FILE",
                   help="write the fit file (diffship.fit/1 JSON, for python -m diffship.predict) here")
    p.add_argument("--check-sampling", action="store_true",
                   help="with --resample: refit at the files' own rate and warn where the estimates move by more "
                        "than their intervals")
    p.add_argument("--skip-sign-check", action="store_true",
                   help="do not stop when the heading turns against the rudder in a run")
    p.add_argument("--json", default=None, metavar="FILE", help="write the results as JSON")
    p.add_argument("--quiet", action="store_true", help="no progress messages")
    _add_prior_arguments(p)
    _add_vessel_arguments(p)
    add_log_options(p)  # --map (logs), --html (issue 30)
    # -- estimators for sea data (issue 13) --
    p.add_argument("--shooting", default="single", metavar="single|multiple[:SEGMENT_S]",
                   help="output error by single shooting (default) or multiple shooting with segments of SEGMENT_S "
                        "seconds (default 20), finished by single shooting")
    p.add_argument("--disturbance", default="ou", choices=("ou", "white"),
                   help="prediction-error process noise: Ornstein–Uhlenbeck disturbance (default) or white")
    return p


def _add_prior_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("priors and admissibility (predictive identification)")
    g.add_argument("--prior", nargs="*", default=[], metavar="NAME=MEAN±SD",
                   help="Gaussian prior on a parameter (MAP fit); also NAME=MEAN+-SD or SD in %% of MEAN")
    g.add_argument("--prior-file", default=None, metavar="FILE",
                   help='priors from JSON {"NAME": {"mean": M, "sd": S}} (or a saved fit file\'s priors)')
    g.add_argument("--no-prior", action="store_true",
                   help="no priors from the model's reference set (on by default for mmg/KVLCC2, fossen3/USV, "
                        "fossen6/BlueROV2 when the fixed particulars are the reference vessel's)")
    g.add_argument("--prior-sd", type=float, default=0.5, metavar="REL",
                   help="relative standard deviation of the reference-set priors (default 0.5)")
    g.add_argument("--admissibility", default="auto", choices=("auto", "off"),
                   help="after the fit, simulate standard manoeuvres (35° turns, 10/10 and 20/20 zigzags, pull-out) "
                        "and check damping over a wide envelope (auto: for models with a rudder input)")




def _add_vessel_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--vessel", default=None, metavar="FILE|NAME",
                   help="vessel particulars: a JSON file or a bundled vessel (" + ", ".join(bundled_vessels()) + "); "
                        "models that need particulars (mass, inertia, dimensions, ...) stop without one")
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

    Covers the case of issue 17: a model that needs particulars, given no vessel, and ``--fix`` /
    ``--free`` not covering them. With ``--vessel`` (whose file must be read), ``--rigid-body-cg``, a
    malformed ``--fix``/``--init``, or the bundled fossen3 example (which brings its own vessel), the
    full command checks as before.
    """
    args = build_parser().parse_args(argv)
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
