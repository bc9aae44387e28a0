"""``python -m diffship.diagnose TRAIN.csv ... --validate VAL.csv ... --model NAME`` (thin CLI).

Same options as ``python -m diffship.fit`` (:mod:`diffship.cli_options`): data, columns, degrees,
rudder sign, vessel (with the fit's particulars rule: a model that needs the vessel's particulars
stops, before JAX is imported, without ``--vessel`` or ``--fix`` for them), channels (default:
:func:`diffship.diagnose.diagnosis.diagnosis_channels`, the same as the library's ``diagnose``:
the fit's channels and the logged positions), fix/free/init, priors, filter, solver. The base model
is fitted here by output error with those options (or started from ``--from-fit FIT.json``, whose
verdict is read and warned about) and handed to :func:`diffship.diagnose.diagnose`; the
diagnosis's workspace programs compile beside the fit
(:func:`~diffship.diagnose.diagnosis.prefetch_workspace`).

Before any run is read, :func:`input_problem` stops the command (exit status 2, one line) on a held-out
run that is also a training run, an empty ``--effects`` list, and outputs that cannot be written or
would overwrite an input (:func:`diffship.cli_options.output_problem`, as in ``python -m diffship.fit``).
After the runs are read and before the base fit, training runs that are too short for the question stop
it too. The rule: the training runs together (after ``--resample`` and ``--horizon``) hold at least
:data:`~diffship.cli_options.SAMPLES_PER_PARAMETER` (20) samples per parameter of the largest model the
diagnosis fits, the base model's free parameters and those of the candidate effect with the most.

A base fit that is not usable (its verdict, :mod:`diffship.usability`) ends the command with exit status 1, one that
cannot be carried out (every start diverges) with 2; either way the reason is the last line and the files asked for
say so (:mod:`diffship.stopped`). A usable base fit's doubts (not converged, parameters not determined or on a bound)
are notes of the diagnosis (JSON ``notes``, ``base_verdict``).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from ..cli_options import (
    add_data_options,
    add_numerics_options,
    add_output_options,
    add_parameter_options,
    add_prior_options,
    add_vessel_option,
    held_out_problem,
    input_files,
    names_of,
    output_problem,
    positive_int,
    too_short_problem,
)
from ..errors import DiffshipError
from ..log_options import add_log_options, log_kwargs
from ..particulars import MODEL_PARTICULARS, missing_message, missing_particulars

EPILOG = ("Effects: see diffship.models.effects (wind needs wind_speed and wind_dir columns). "
          "Exit status: 0 done, 1 the base fit is not usable (reason on the last line), 2 user error (message on "
          "stderr). List options may be repeated: their items accumulate.")


def build_parser() -> argparse.ArgumentParser:
    from .options import DiagnoseOptions
    p = argparse.ArgumentParser(prog="python -m diffship.diagnose", epilog=EPILOG,
                                description="Diagnose where a fitted model misses, which unmodelled effect explains it "
                                            "(selected on held-out runs) and how much of the gap it closes.")
    p.add_argument("runs", nargs="+", metavar="TRAIN.csv", help="training runs")
    p.add_argument("--model", required=True, metavar="MODEL",
                   help=f"base model: one of {', '.join(MODEL_PARTICULARS)}")
    add_data_options(p, validate_required=True)
    add_vessel_option(p)
    add_parameter_options(p, channels_help="channels of the base fit and of the diagnosis (default: the fit's "
                                           "— what the model predicts and the runs have — and the positions x0, y0 "
                                           "where every run logs them: a current or a heading bias shows in the track)")
    add_prior_options(p)
    add_numerics_options(p, filter_help="initial-state filter: butter[:Hz] (default), savgol[:s] or none")
    p.add_argument("--from-fit", default=None, metavar="FIT.json",
                   help="start the base fit from a fit file's values (its verdict is read: a FAILED or doubtful fit "
                        "is warned about)")
    p.add_argument("--skip-sign-check", action="store_true",
                   help="do not stop when the heading turns against the rudder (or yaw moment) in a run")
    p.add_argument("--effects", default="all", help="all, or a comma-separated list of effect names")
    p.add_argument("--refit-all", action="store_true",
                   help="refit every candidate, not only the screen's best (also when the first one closed the gap alone)")
    p.add_argument("--sea-state", choices=("auto", "always", "never"), default="auto",
                   help="check for a stochastic narrow-band disturbance (waves of random phase) by prediction from "
                        "the Kalman filter: when the loop is closed or the residuals are periodic (auto), always, never")
    p.add_argument("--correct-data", action="store_true",
                   help="take the data checks' findings (a heading bias against the track and u, v; the time the "
                        "motion follows the logged rudder) out of the logs before the base fit; they are reported "
                        "either way")
    p.add_argument("--greedy-steps", type=positive_int, default=DiagnoseOptions.greedy_steps, metavar="N",
                   help="effects on the greedy path at most (default %(default)s; each after the first must pass the "
                        "rule against the previous step, and the path stops under the gap gate)")
    add_output_options(p, out_help="write diagnosis.md, diagnosis.json and figures here",
                       json_help="write the JSON result here")
    add_log_options(p)  # --map (logs), --html (one self-contained report)
    return p


#: The files ``--out DIR`` writes (the figures among them where the diagnosis has them).
OUT_FILES = ("diagnosis.md", "diagnosis.json", "residuals.png", "acf_ccf.png", "regimes.png", "overlay.png",
             "waterfall.png", "data_checks.png")


def input_problem(args) -> str | None:
    """The one line that stops the command before it reads a run, or ``None``."""
    if args.effects.strip() != "all" and not [e for e in args.effects.split(",") if e.strip()]:
        from ..models.effects.registry import EFFECT_NAMES

        return (f"--effects {args.effects!r}: the effects list is empty; give all, or a comma-separated list of "
                f"effects from: {', '.join(EFFECT_NAMES)}")
    inputs = input_files(args) + ([("the --from-fit file", args.from_fit)] if args.from_fit else [])
    return held_out_problem(args.runs, args.validate) or output_problem(
        inputs, args.out, OUT_FILES, [("--json", args.json), ("--html", args.html)])


def precheck(args) -> str | None:
    """The particulars rule of ``python -m diffship.fit``, without JAX: the error line, or ``None``."""
    needs = MODEL_PARTICULARS.get(args.model)
    if needs is None or args.vessel is not None or not needs.particulars:
        return None
    missing = missing_particulars(needs.particulars, names_of(args.fix), args.free)
    return missing_message(needs.name, needs.particulars, needs.reference_vessel, missing) if missing else None


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    t0 = time.perf_counter()

    def say(msg):
        if not args.quiet:
            print(f"[{time.perf_counter() - t0:6.1f} s] {msg}", file=sys.stderr, flush=True)

    problem = input_problem(args) or precheck(args)
    if problem is not None:
        print(f"error: {problem}", file=sys.stderr)
        return 2
    from ..errors import FitError
    from ..stopped import stopped_command

    try:
        d, base = _diagnose(args, say)
    except DiffshipError as exc:
        print(f"error: {exc}", file=sys.stderr)
        if isinstance(exc, FitError):  # no base fit: the files asked for say so, none of an earlier command's is left
            stopped_command(args, str(exc), OUT_FILES, "diffship diagnose")
        return 2
    if d is None:  # the base fit's verdict (FAILED): said on the last line and in the files asked for
        why = f"no usable base fit was found ({'; '.join(base.reasons) or base.label}); the diagnosis needs one"
        stopped_command(args, why, OUT_FILES, "diffship diagnose", extra={"base_verdict": base.as_json()})
        print(f"error: {why}", file=sys.stderr)
        return 1
    from .report import to_markdown, write_json, write_report

    print(to_markdown(d))
    if args.out:
        files = write_report(d, args.out)
        say("wrote " + ", ".join(str(f) for f in files))
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)  # as the fit command's --json
        write_json(d, args.json)
        say(f"wrote {args.json}")
    if args.html:
        from ..html import write_html_report

        say(f"wrote {write_html_report(args.html, f'diffship diagnosis: {args.model}', to_markdown(d), lambda f: write_report(d, f))}")
    return 0


def _load(args, paths, held=()):
    from ..data import load_runs, resample_runs

    runs = load_runs(paths, columns=dict(c.split("=", 1) for c in args.columns) or None, degrees=args.degrees,
                     rudder_sign=args.rudder_sign, time_unit=args.time_unit, **log_kwargs(args))
    return resample_runs(runs, args.resample, held=held) if args.resample else runs


def _diagnose(args, say):
    """``(diagnosis, base fit)``, or ``(None, its verdict)`` when the base fit is not usable."""
    from ..checks import check_rudder_sign, check_runs, check_yaw_direction
    from ..errors import DataError
    from ..fit import OutputErrorOptions, fit_output_error
    from ..fit.priors import load_priors, parse_priors
    from ..fitfile import fit_warnings, load_fit
    from ..integrators import get_integrator
    from ..models import get_model
    from ..preprocess import Filter
    from ..usability import verdict
    from ..vessel import model_spec
    from .consistency import correction_note, corrected, data_checks
    from .diagnosis import DiagnoseOptions, diagnose, diagnosis_channels, prefetch_workspace

    effects = "all" if args.effects == "all" else [e.strip() for e in args.effects.split(",") if e.strip()]
    if args.free_hydrodynamic:  # every parameter that is not a vessel particular
        base = get_model(args.model)
        args.free = list(dict.fromkeys([*args.free, *(n for n in base.param_names if n not in base.PARTICULARS)]))
    model, spec, fix, init = model_spec(args.model, args.vessel, args.fix, args.init, args.free)
    if args.from_fit:
        loaded = load_fit(args.from_fit)
        _same_model(args, loaded, model)
        for w in fit_warnings(loaded):
            print(w, file=sys.stderr, flush=True)
        init = {**{n: v for n, v in loaded.params.items() if n in spec and n not in fix}, **init}
    if init:
        spec = spec.with_values(init)
    held = model.input_names if args.input_hold == "zero" else ()  # inputs held over each sample
    train, val = _load(args, args.runs, held), _load(args, args.validate, held)
    if args.horizon:  # the first seconds of each training run (held-out runs whole)
        train = [r.slice(None, r.time[0] + args.horizon) for r in train]
    check_runs(model, train, val, args.channels)
    _enough_samples(model, spec, train, effects)
    if not args.skip_sign_check:
        check_rudder_sign(train + val, args.rudder_sign)
        check_yaw_direction(train + val)
    if args.filter == "kalman":
        raise DataError("--filter kalman: the Kalman smoother is an equation-error preprocessing; the diagnosis fits "
                        "by output error (use butter[:Hz], savgol[:s] or none)")
    chans = tuple(args.channels) if args.channels else diagnosis_channels(model, train)  # as diagnose()
    priors = parse_priors(args.prior)
    if args.prior_file:
        priors = load_priors(args.prior_file).merged(priors)
    options = DiagnoseOptions(effects=effects, refit_all=args.refit_all, channels=chans,
                              greedy_steps=args.greedy_steps, correct_data=args.correct_data,
                              sea_state=args.sea_state)
    checked = None
    if args.correct_data:  # as diagnose(correct_data=True), before this command's own base fit
        checked = data_checks(train, val, min_fall=options.min_gain)
        if (note := correction_note(checked)) is not None:
            train, val = corrected(train, checked), corrected(val, checked)
            say(note)
    opts = OutputErrorOptions(max_steps=args.max_steps or options.fit_steps, estimate_x0=model.states_for_channels(chans),
                              integrator=get_integrator(args.solver, hold=args.input_hold), flt=Filter.parse(args.filter),
                              priors=priors if len(priors) else None, reference_priors=not args.no_prior,
                              prior_rel_sd=args.prior_sd, stall=options.stall)
    say(f"fitting the base model {model.name} by output error on {len(train)} runs (channels {', '.join(chans)})...")
    pre = prefetch_workspace(model, spec, train, val, chans, options, opts.integrator)  # compiled beside the fit
    try:
        fit = fit_output_error(model, train, spec=spec, channels=chans, options=opts, progress=say, n_starts=args.starts)
    except BaseException:
        if pre is not None:
            pre.cancel()
        raise
    v = verdict(fit, None, train)
    if not v.usable:
        if pre is not None:
            pre.cancel()
        return None, v
    for line in v.lines()[1:]:
        print(f"warning (base fit):{line[1:]}", file=sys.stderr)
    d = diagnose(fit.model, train, val, fit=fit, spec=spec, options=options, progress=say, checked=checked)
    return d, fit


def _enough_samples(model, spec, train, effects) -> None:
    """Stop on training runs too short for the base model and its largest candidate effect (the module's rule)."""
    from ..errors import DataError
    from ..models.effects.registry import library

    effs, _ = library(model, train, effects)
    most = max(effs, key=lambda e: len(e.param_names), default=None)
    n = len(spec.free_names) + (len(most.param_names) if most is not None else 0)
    what = f"{model.name}'s {len(spec.free_names)} free" + (f" and {most.name}'s {len(most.param_names)}"
                                                            if most is not None else "")
    if (problem := too_short_problem(sum(len(r.time) for r in train), n, what)) is not None:
        raise DataError(problem)


def _same_model(args, loaded, model) -> None:
    """``--from-fit`` must hold a fit of the ``--model`` (its values are the base fit's start)."""
    from ..errors import DataError
    from ..models.terms import base_of

    key, base = loaded.document["model"].get("registry"), base_of(loaded.model)
    same = key == args.model or (type(base) is type(model) and base.param_names == model.param_names
                                 and base.input_names == model.input_names)
    if not same:
        raise DataError(f"--from-fit {args.from_fit}: holds a fit of model {key or loaded.model.name}, not of "
                        f"--model {args.model}; give --model {key or loaded.model.name} to start from it, or a fit "
                        f"file of {args.model}")


if __name__ == "__main__":
    from ..cli_options import exit_now

    exit_now(main())
