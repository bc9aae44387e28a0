"""``python -m diffship.fit``: the command-line front end of the fits (thin: parse arguments,
call the library, print, exit).

The screen shows the point first: the methods' whole-horizon errors side by side (held-out runs
first), then the parameters and each method's verdict; a method that is not usable is one line with
its reason, its notes going to the report file. With ``--out DIR`` (and, for the bundled example, by
default in :data:`DEFAULT_OUT`) the full report, the figure, the JSON and the fit file are written
there. Errors a user can fix (bad files, columns, units, parameters, divergence) are printed as one
line ``error: ...`` on stderr with exit status 2 and no traceback.
"""

from __future__ import annotations

import argparse
import math
import dataclasses
import sys
import time
from pathlib import Path

from ..checks import check_channels, check_rudder_sign, check_runs, check_yaw_direction  # noqa: F401 (also this module's)
from ..data import example_runs, load_runs, resample_runs
from ..errors import DiffshipError, FitError
from ..integrators import get_integrator
from ..metrics import evaluate
from ..models import ConstantThrust, get_model
from ..params import parse_assignments
from ..preprocess import Filter
from ..admissibility import admissibility
from ..vessel import (
    fixed_values,
    fixed_values_text,
    load_vessel,
    plausibility,
    propeller_map,
    require_particulars,
    speed_range,
)
from ..fitfile import save_fit
from ..html import write_html_report
from ..log_options import log_kwargs
from ..predict.cross import cross_validate, train_types_json
from ..predict.cross_report import cross_json, cross_text, plot_cross
from ..report import failed_methods, plot_fit, text_report, to_json_dict, write_json
from ..stopped import stopped_command
from ..usability import verdict
from .args import build_parser, starts_option
from .conditioning import thinning
from .feedback import loop_evidence
from .both import fit_both
from .output_error import OutputErrorOptions
from .hints import NextStep, next_step, next_steps
from .inputs import DEFAULT_OUT, OUT_FILES, input_problem, spec_problem
from .priors import default_priors, format_priors, load_priors, parse_priors
from .prediction_error import PredictionErrorOptions, fit_prediction_error
from .shooting import fit_multiple_shooting, parse_shooting
from .smoother import KalmanSmoother

__all__ = ["DEFAULT_OUT", "main", "build_parser"]


def _prior_options(args) -> dict:
    priors = parse_priors(args.prior)
    if args.prior_file:
        priors = load_priors(args.prior_file).merged(priors)
    return {"priors": priors if len(priors) else None, "reference_priors": not args.no_prior,
            "prior_rel_sd": args.prior_sd}


def _admissibility(args, result, train, say):
    """Admissibility of an output-error fit of a ship model, from the training runs' approach
    state, constant inputs and helm rate; ``None`` when it does not apply."""
    model = result.model
    if args.admissibility == "off" or "delta" not in model.input_names or "u" not in model.state_names:
        return None
    run = train[0]
    if "u" not in run.channels:
        return None
    n0 = max(1, int(round(2.0 / run.dt)))
    inputs = {n: float(run[n][:n0].mean()) for n in model.input_names if n != "delta" and n in run.channels}
    if len(inputs) != len(model.input_names) - 1:
        return None
    rates = [float(abs((r["delta"][1:] - r["delta"][:-1]) / r.dt).max()) for r in train if "delta" in r.channels]
    rate = max(rates) if rates else 0.0
    helm = math.degrees(rate) if rate > 0 else 2.32
    say(f"admissibility: simulating 35° turns, zigzags and a pull-out at u = {float(run['u'][:n0].mean()):.3g} m/s, "
        f"helm {helm:.3g}°/s...")
    ref = type(model)() if getattr(type(model), "REFERENCE", "") else None
    return admissibility(model, initial={"u": float(run["u"][:n0].mean())}, inputs=inputs, training=train,
                         reference=ref, free=result.free, helm_rate_deg_s=helm)


def _cross_manoeuvre(oe, train, val, say):
    """Manoeuvre validation of an output-error fit of a model with a rudder input on every ``--validate``
    run that is a standard manoeuvre (IMO metrics measured and predicted: held-out zigzags' overshoots,
    turning circles' diameters), trained types included; ``None`` when there are none."""
    if oe is None or not val or "delta" not in oe.model.input_names:
        return None
    say("manoeuvre validation: classifying the runs, simulating every held-out standard manoeuvre...")
    cv = cross_validate(oe, train, val, trained_types=True)
    return cv if cv.checks else None


def _progress(quiet: bool):
    t0 = time.perf_counter()

    def say(msg: str) -> None:
        if not quiet:
            print(f"[{time.perf_counter() - t0:6.1f} s] {msg}", file=sys.stderr, flush=True)

    return say


def _columns(args) -> dict[str, str]:
    """``--columns`` items (checked ``NAME=COLUMN`` by :mod:`diffship.cli_options`) as a dict."""
    return dict(c.split("=", 1) for c in args.columns)


def _load(args, paths, held=()):
    """The runs (``--resample``: on its grid, the inputs ``held`` under ``--input-hold zero`` as held means)."""
    runs = load_runs(paths, columns=_columns(args) or None, degrees=args.degrees, rudder_sign=args.rudder_sign,
                     time_unit=args.time_unit, **log_kwargs(args))
    return resample_runs(runs, args.resample, held=held) if args.resample else runs


def _example(model_name: str, say, dt: float | None = None):
    """The bundled example runs (``dt``: the user's ``--resample`` step, else the example's 10 Hz)."""
    if model_name == "fossen3":
        from ..synthetic import usv_runs  # only for the bundled fossen3 example

        say("no runs given: generating the bundled fossen3 example (the water-jet USV truth with added mass, "
            "4 runs × 120 s at 10 Hz, realistic GNSS/heading/gyro noise; run usv_3 held out)")
        runs = usv_runs(4, 120.0, 0.1, noise="realistic", seed=7)
        runs = resample_runs(runs, dt) if dt else runs
        return runs[:3], runs[3:]
    if model_name not in ("nomoto1", "nomoto2"):
        raise DiffshipError(
            f"no bundled example for model {model_name} (there is one for nomoto1, nomoto2 and fossen3): "
            "give RUN.csv files, e.g. the KVLCC2 zigzags in ../shared/data/kvlcc2_hsva for mmg or vmm_*"
        )
    say("no runs given: fitting the bundled SSPA zigzag 20/20 (model test, 50 Hz; Apache-2.0, see "
        f"src/diffship/examples/README.md), resampled to {1 / (dt or 0.1):.3g} Hz")
    runs = resample_runs(example_runs("sspa_zigzag"), dt or 0.1)
    return runs, []


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 done, 1 no usable fit, 2 user error or no fit at all)."""
    args = build_parser().parse_args(argv)
    say = _progress(args.quiet)
    try:
        if (problem := input_problem(args)) is not None:  # contradictions, outputs over inputs: before any file is read
            raise DiffshipError(problem)
        return _fit(args, say)
    except DiffshipError as exc:
        print(f"error: {exc}", file=sys.stderr)
        if isinstance(exc, FitError):  # no fit: the files asked for say so, none of an earlier command's is left
            stopped_command(args, str(exc), OUT_FILES, "diffship fit")
        return 2


def _sea_estimators(args, model, train, spec, init, flt, options, shooting, results, say) -> dict:
    """Multiple-shooting output error and the prediction-error method, started like
    output error in ``fit_both``: from ``--init`` or the model's values, or the equation-error estimate."""
    out = {}
    if shooting is None and args.method != "prediction-error":
        return out
    if init:
        spec = spec.with_values(init)
    ee = results.get("equation_error")
    starts = {"the equation-error estimate": {n: ee.params[n] for n in ee.free}} if ee else {}
    est = "auto" if _x0(args, model) == "auto" else ()
    opts = dataclasses.replace(options, estimate_x0=est, flt=flt, choose="first" if init else "best")
    if shooting is not None:
        out["output_error"] = fit_multiple_shooting(model, train, spec=spec, starts=starts, channels=args.channels,
                                                    options=opts, shooting=shooting, progress=say)
    if args.method == "prediction-error":
        kinds = ("ou", "wave") if args.disturbance == "auto" else (args.disturbance,)  # auto: the likelihood chooses
        fits = {k: fit_prediction_error(model, train, spec=spec, starts=starts, channels=args.channels, options=opts,
                                        noise=PredictionErrorOptions(disturbance=k), progress=say) for k in kinds}
        out["prediction_error"] = fits[kinds[0]]
        if len(fits) > 1:
            from .ahead import choose_disturbance
            out["prediction_error"] = choose_disturbance(fits, train)
            say(out["prediction_error"].messages[-1])
    return out


def _x0(args, model) -> str | tuple:
    """``--x0`` as ``fit_both``'s ``estimate_x0``: ``"auto"`` (the one initial-state rule, the default) or
    ``()`` (``--x0 data``: the data's initial states taken as exact)."""
    return () if args.x0 == "data" else "auto"


def _filters(args):
    """``(flt, ee_filter)`` of ``--filter``: the filter for initial states and metrics, and the equation-error
    preprocessing when it differs (``kalman``: EKF + RTS smoother over the model, :mod:`diffship.fit.smoother`;
    initial states and metrics then use the default Butterworth)."""
    if args.filter == "kalman":
        return Filter(), KalmanSmoother(channels=tuple(args.channels) if args.channels else None,
                                        noise=PredictionErrorOptions(
                                            disturbance="ou" if args.disturbance == "auto" else args.disturbance),
                                        options=OutputErrorOptions(integrator=get_integrator(args.solver, hold=args.input_hold)))
    return Filter.parse(args.filter), None


def _with_step(args, step: NextStep, taken: tuple) -> argparse.Namespace:
    """A copy of ``args`` with ``step`` taken (:func:`~diffship.fit.hints.next_step`); ``args`` is not changed."""
    out = argparse.Namespace(**vars(args))
    if step.option == "--free-hydrodynamic":
        out.free_hydrodynamic = True
    elif step.option == "--horizon":
        out.horizon = float(step.value)
    out.steps_taken = (*taken, step)
    return out


def _fit(args, say) -> int:
    model = get_model(args.model)
    if args.free_hydrodynamic:  # every parameter that is not a vessel particular
        args.free = list(dict.fromkeys([*args.free, *(n for n in model.param_names if n not in model.PARTICULARS)]))
    fix = parse_assignments(args.fix, "--fix")
    init = parse_assignments(args.init, "--init")
    model, vessel, sources = _with_vessel(args, model, fix, say)
    sources.update({n: "--fix" for n in fix})  # given values say so, also where they equal the default
    flt, ee_filter = _filters(args)
    spec = model.spec()
    for n in list(fix) + list(init) + list(args.free):
        spec[n]  # unknown names fail early, with the list of valid ones
    spec = spec.free(args.free).fix(fix)
    if (problem := spec_problem(args, spec)) is not None:  # an --init of a parameter the fit holds
        raise DiffshipError(problem)
    if args.runs:
        held = model.input_names if args.input_hold == "zero" else ()
        train = _load(args, args.runs, held)
        val = _load(args, args.validate, held) if args.validate else []
    else:
        train, val = _example(args.model, say, args.resample)  # no file given (held-out runs need a training run: input_problem)
        if args.out is None:  # the main job shows its figure: written where the report says
            args.out = DEFAULT_OUT
    _vessel_checks(args, model, vessel, train + val, say)
    check_runs(model, train, val, args.channels)
    if not args.skip_sign_check:
        check_rudder_sign(train + list(val), args.rudder_sign)
        check_yaw_direction(train + list(val))
    methods = {"both": ("equation_error", "output_error"), "output-error": ("output_error",),
               "equation-error": ("equation_error",), "prediction-error": ()}[args.method]
    options = OutputErrorOptions(integrator=get_integrator(args.solver, hold=args.input_hold), weights=args.weights,
                                 positions=args.positions, **_prior_options(args),
                                 **({"max_steps": args.max_steps} if args.max_steps else {}))
    fit_runs = train
    if args.horizon:  # fit the first seconds only; metrics, verdicts and the fit file's data use whole runs
        fit_runs = [r.slice(None, r.time[0] + args.horizon) for r in train]
        say(f"--horizon {args.horizon:g}: fitting the first {args.horizon:g} s of each training run")
    thin = None
    if not args.resample:  # the rate chosen from the data and the model, said in one line
        thin = thinning(model, fit_runs, known=bool(len(default_priors(model, spec, 0.5)[0])))
        fit_runs = thin.apply(fit_runs, model.input_names, args.input_hold)
        say(thin.text)
    shooting = parse_shooting(args.shooting)
    multiple = shooting is not None and "output_error" in methods
    if args.bootstrap and ("output_error" not in methods or multiple):
        raise DiffshipError("--bootstrap: refits single-shooting output error (use --method output-error or both, "
                            "without --shooting multiple)")
    first = tuple(m for m in methods if not (multiple and m == "output_error"))
    try:
        results = fit_both(model, fit_runs, spec=spec, methods=first, init=init or None, flt=flt,
                           estimate_x0=_x0(args, model), channels=args.channels, options=options, progress=say,
                           ee_filter=ee_filter, **starts_option(args)) if first else {}
    except DiffshipError:  # equation error alone before multiple shooting: its failure was said; output error goes on
        if not multiple:
            raise
        results = {}
    results.update(_sea_estimators(args, model, fit_runs, spec, init, flt, options, shooting if multiple else None,
                                   results, say))
    say("simulating every run over its whole horizon for the metrics...")
    if thin is not None and thin.factor > 1:  # the channel scales of the logged samples: √k those of k-sample averages
        results = {m: dataclasses.replace(r, channel_scales={c: v * math.sqrt(thin.factor)
                                                             for c, v in (r.channel_scales or {}).items()})
                   for m, r in results.items()}
    ev_train, ev_val = evaluate_all(results, train, val, flt)
    oe = results.get("output_error")
    # held-out standard manoeuvres (trained types included): a miss of a trained type makes the fit not usable
    cross = _cross_manoeuvre(oe, train, val, say) if oe is not None and oe.usable else None
    # a --validate run that is one of the training runs is not held out: its manoeuvre is no prediction
    held = [r for r in val if not any(r.name == t.name and r.n == t.n for t in train)]
    verdicts = {m: verdict(r, ev_train.get(m), train, ev_val.get(m), held, manoeuvres=cross if m == "output_error"
                           and len(held) == len(val) else None) for m, r in results.items()}
    taken = tuple(getattr(args, "steps_taken", ()))
    steps = next_steps(model, spec, verdicts["output_error"].runs, horizon=args.horizon, priors=not args.no_prior,
                       free_hydrodynamic=args.free_hydrodynamic) \
        if oe is not None and not any(v.usable for v in verdicts.values()) else []
    # the options the report would name (a --horizon given stays: an override, as every option)
    if (step := None if args.as_given else next_step(steps, taken, ("--horizon",) if args.horizon else ())) is not None:
        v = verdicts["output_error"]
        say(f"output error is not usable ({v.reasons[0] if v.reasons else v.label}): refitting with {step} "
            "(--as-given: fit with the options as given)")
        return _fit(_with_step(args, step, taken), say)
    notes = ([""] + [thin.text] if thin is not None else []) + resample_notes(args, model, spec, results, flt, options,
                                                                               say)
    details = str(Path(args.out) / "report.txt") if args.out else None
    screen = text_report(model.name, results, ev_train, ev_val, train, val, verdicts=verdicts, screen=True,
                         details=details)
    report = text_report(model.name, results, ev_train, ev_val, train, val, verdicts=verdicts)
    tail = "\n\n" + fixed_values_text(spec, sources)
    # what the command adds per method goes into its own JSON entries; the FitResult is not edited
    per_method = {m: {"fixed": fixed_values(spec, sources)} for m in results}
    adm = _admissibility(args, oe, train, say) if oe is not None and verdicts["output_error"].usable else None
    if oe is not None:
        tail += "\n\n" + format_priors(oe)
        if adm is not None:
            tail += "\n\n" + adm.summary()
            per_method["output_error"]["admissibility"] = adm.as_json()
    if args.bootstrap and oe is not None:  # percentile intervals from refits of resamples
        from .bootstrap import bootstrap_report

        text, boot = bootstrap_report(oe, fit_runs, args.bootstrap, args.bootstrap_method, say, spec=spec,
                                      options=dataclasses.replace(options, flt=flt))
        tail += "\n\n" + text
        per_method["output_error"]["bootstrap"] = boot
    if cross is not None:  # held-out runs flown as manoeuvres, with their IMO metrics
        tail += "\n\n" + cross_text(cross)
        per_method["output_error"]["cross_manoeuvre"] = cross_json(cross)
    if (pe := results.get("prediction_error")) is not None and pe.usable:  # a sea state is predicted, not simulated
        from .ahead import ahead_table

        say("prediction from the Kalman filter's state: one sample and 30 s ahead, with and without the disturbance...")
        text, per_method["prediction_error"]["ahead"], _ = ahead_table(pe, train, held)
        tail += "\n\n" + text
    for m, r in results.items():  # does an input react to the model's errors (an autopilot)? said for every fit
        if m in ev_train and (loop := loop_evidence(r.model, train, ev_train[m], r.channels, m)) is not None:
            tail += f"\n\n{m.replace('_', ' ')}: {loop['text']}"
            per_method[m]["feedback"] = loop
    if notes:
        tail += "\n" + "\n".join(notes)
    if taken:  # options the command chose after fits that were not usable
        tail += ("\n\noptions chosen after a fit that was not usable (--as-given: fit with the options as given):\n"
                 + "\n".join(f"  {t}" for t in taken))
        per_method["output_error"]["steps_taken"] = [str(t) for t in taken]
    if steps:  # the options the model and data point to
        tail += "\n\nwhat to try (the fit is not usable):\n" + "\n".join(f"  {s}" for s in steps)
        per_method["output_error"]["next_steps"] = [str(s) for s in steps]
    report += tail
    print(screen + tail)
    write_outputs(args, model.name, results, ev_train, ev_val, train, val, report, say, verdicts=verdicts,
                  per_method=per_method, vessel=vessel)
    if cross is not None and cross.checks and args.out:
        plot_cross(cross, Path(args.out) / "cross_manoeuvre.png")
        say(f"wrote {Path(args.out) / 'cross_manoeuvre.png'}")
    if args.out:
        out = Path(args.out)
        print(f"\nwritten to {out}/: report.txt (the full report), fit.png (measured against simulated), "
              f"report.json, fit.json (the fit file: python -m diffship.predict {out / 'fit.json'})")
    if args.html:  # one self-contained file, the figures --out writes embedded
        def figures(d):
            plot_fit(model.name, train, val, ev_train, ev_val, d / "fit.png", failed=failed_methods(ev_train, results))
            return [d / "fit.png"] + ([plot_cross(cross, d / "cross_manoeuvre.png") or d / "cross_manoeuvre.png"]
                                      if cross is not None else [])
        say(f"wrote {write_html_report(args.html, f'diffship fit: {model.name}', report, figures)}")
    if not any(v.usable for v in verdicts.values()):
        why = "; ".join(f"{m.replace('_', ' ')}: {v.reasons[0] if v.reasons else v.label}" for m, v in verdicts.items())
        print(f"error: no usable fit was found ({why})", file=sys.stderr)
        return 1
    return 0


# -- vessel particulars: --vessel, --rigid-body-cg, --propulsion, plausibility, fixed values --
def _with_vessel(args, model, fix, say):
    """The model with its particulars from ``--vessel`` (or stop naming the missing ones)."""
    if args.rigid_body_cg:
        if not hasattr(model, "rigid_body_cg"):
            raise DiffshipError(f"--rigid-body-cg: model {model.name} has no rigid-body reference option (fossen6 has)")
        model = dataclasses.replace(model, rigid_body_cg=True)
    name = args.vessel
    if name is None and not args.runs and args.model == "fossen3":
        name = model.REFERENCE_VESSEL  # the bundled fossen3 example is the seed-002 USV
        say(f"bundled example: vessel {name} (the vessel that generated the example runs)")
    vessel = load_vessel(name) if name else None
    model, parts = require_particulars(model, vessel, fixed=fix, freed=args.free)
    sources = dict(parts.sources)
    if args.propulsion != "thrust":
        if not hasattr(model, "propulsion"):
            raise DiffshipError(f"--propulsion: model {model.name} takes no thrust input (the vmm_* models do)")
        kind, _, value = args.propulsion.partition(":")
        if kind == "propeller":
            if vessel is None:
                raise DiffshipError("--propulsion propeller needs --vessel with propeller data (diameter, kt, wake_fraction)")
            prop = propeller_map(vessel)
        elif kind == "constant":
            try:
                prop = ConstantThrust(float(value))
            except ValueError:
                raise DiffshipError(f"--propulsion {args.propulsion}: expected constant:NEWTONS, e.g. constant:1.5e5") from None
        else:
            raise DiffshipError(f"--propulsion {args.propulsion}: use thrust, propeller or constant:NEWTONS")
        model = dataclasses.replace(model, propulsion=prop)
        sources["propulsion"] = f"{args.propulsion}: " + ", ".join(
            f"{f.name}={getattr(prop, f.name)}" for f in dataclasses.fields(prop))
    if "dwP" in args.free and args.propulsion.partition(":")[0] != "propeller":
        raise DiffshipError("--free dwP: the wake-fraction correction enters only the open-water propeller map; "
                            "add --propulsion propeller (thrust from the propeller speed column n)")
    if args.rigid_body_cg:
        sources["rigid_body_cg"] = "--rigid-body-cg"
    elif hasattr(model, "rigid_body_cg") and not model.rigid_body_cg and any(fix.get(n) for n in ("xg", "yg", "zg")):
        print("warning: a CG offset is fixed but the rigid-body terms take r_g = 0 (it enters the restoring "
              "forces only); add --rigid-body-cg for the full M_RB(r_g), C_RB(ν, r_g)", file=sys.stderr)
    if vessel is not None:
        say(f"vessel {vessel.name}: {vessel.description or vessel.source}")
    return model, vessel, sources


def _vessel_checks(args, model, vessel, runs, say) -> None:
    """Plausibility warnings before any compute (always printed), and inputs taken as constants."""
    for n, v in model.INPUT_DEFAULTS.items():
        lacking = [r.name for r in runs if not r.has(n)]
        if lacking:
            say(f"input {n} absent from {', '.join(lacking)}: taken as {v:g} (model {model.name}: free decay)")
    warnings = plausibility(vessel, runs, model) if vessel is not None else []
    if vessel is None and hasattr(model, "convention_warnings") and speed_range(runs) is not None:
        warnings = [f"warning: {w}" for w in model.convention_warnings(*speed_range(runs))]
    for w in warnings:
        if w.startswith("warning") or not args.quiet:
            print(w, file=sys.stderr, flush=True)
# ----------------------------------------------------------------------------------------
# checks before any compute, metrics, outputs (fit -> fit file -> prediction)
# ----------------------------------------------------------------------------------------
def evaluate_all(results, train, val, flt):
    """Metrics with the one initial-state rule for training and validation runs (:mod:`diffship.initial`):
    each run's start estimated within its sensor noise on the fit's channels with the fit's channel scales,
    the parameters held, as :func:`diffship.metrics.evaluate` does."""
    ev_train, ev_val = {}, {}
    for m, r in results.items():
        kw = dict(flt=flt, integrator=r.integrator, fitted=r.channels, scales=r.channel_scales)
        ev_train[m] = evaluate(r.model, train, **kw)
        if val:
            ev_val[m] = evaluate(r.model, val, **kw)
    return ev_train, ev_val


def resample_notes(args, model, spec, results, flt, options, say) -> list[str]:
    """With ``--resample``: refit output error at the files' own rate and say if the estimates
    move by more than their intervals (sampling-rate sensitivity, e.g. Nomoto K/T on the SSPA zigzag)."""
    oe = results.get("output_error")
    if not args.resample or oe is None or not args.runs:
        return []
    if not args.check_sampling:
        rate = 1.0 / load_runs(args.runs[:1], columns=_columns(args) or None, degrees=args.degrees,
                               rudder_sign=args.rudder_sign, check_units=False, time_unit=args.time_unit, **log_kwargs(args))[0].dt
        return ["", f"note: the runs were resampled from {rate:.3g} Hz to {1 / args.resample:g} Hz (--resample). The "
                "fit's likelihood counts effective samples, so the rate alone does not move the answer; dynamics "
                "faster than the new step, or the interpolation, can. Add --check-sampling to refit at the files' "
                "rate and compare."]
    say(f"--resample {args.resample:g}: refitting at the files' own sample rate to check the sensitivity...")
    raw = load_runs(args.runs, columns=_columns(args) or None, degrees=args.degrees, rudder_sign=args.rudder_sign,
                    time_unit=args.time_unit, **log_kwargs(args))
    try:
        ref = fit_both(model, raw, spec=spec.with_values(oe.params), methods=("output_error",), init=None,
                       flt=flt, estimate_x0=_x0(args, model), channels=args.channels,
                       options=options)["output_error"]
    except DiffshipError as exc:
        return [f"note: the refit at the files' own sample rate failed ({exc}); sampling sensitivity unknown"]
    rate = 1.0 / raw[0].dt
    lines, moved = [], []
    for n in oe.free:
        a, b = oe.params[n], ref.params[n]
        sa, sb = oe.stderr.get(n, float("nan")), ref.stderr.get(n, float("nan"))
        z = abs(a - b) / max((sa * sa + sb * sb) ** 0.5, 1e-300)
        lines.append(f"  {n:>10s}  {a: .5g} ± {sa:.2g}  vs  {b: .5g} ± {sb:.2g}  ({z:.1f} σ)")
        if not z <= 2.0:
            moved.append(n)
    head = (f"WARNING: sampling-rate sensitivity: resampled to {1 / args.resample:g} Hz vs the files' {rate:.3g} Hz "
            f"the estimates of {', '.join(moved)} differ by more than 2 combined standard errors; the intervals "
            "above do not cover this (unmodelled dynamics or filtering show up at one rate and not the other)"
            if moved else f"sampling-rate check: the estimates at {1 / args.resample:g} Hz and at the files' "
            f"{rate:.3g} Hz agree within 2 combined standard errors")
    return ["", head, *lines]


def write_outputs(args, model_name, results, ev_train, ev_val, train, val, report, say, *, verdicts=None,
                  per_method=None, vessel=None) -> None:
    """``--out DIR``: report.txt, fit.png, report.json and the fit file fit.json; ``--json``, ``--save``.

    The fit file is the output-error fit where it is usable, else the first usable method's, else the
    output-error one; it records the verdict (``usable``, ``verdict``) so that ``predict`` and
    ``diagnose`` warn about a failed or doubtful fit."""
    verdicts = verdicts or {}
    doc = to_json_dict(model_name, results, ev_train, ev_val, verdicts=verdicts, per_method=per_method)
    usable = [m for m in results if m in verdicts and verdicts[m].usable]
    pick = "output_error" if "output_error" in usable else (usable[0] if usable else
                                                              ("output_error" if "output_error" in results
                                                               else next(iter(results))))
    best = results[pick]
    extra = {"metrics": {"train": doc["methods"][pick]["train"],
                         "validation": doc["methods"][pick]["validation"],
                         "validation_runs": [r.name for r in val]}}
    if pick in verdicts:
        extra["usable"] = verdicts[pick].usable
        extra["verdict"] = verdicts[pick].as_json()
    if vessel is not None:  # predict takes the scale and approach speed from here unless given
        extra["vessel"] = {"name": vessel.name, "scale": float(vessel.scale), "length_m": vessel.length,
                           "approach_speed": vessel.approach_speed, "full_scale_length_m": vessel.full_scale_length}
    if "delta" in best.model.input_names:
        length = getattr(best.model, "L", None)
        extra["training_manoeuvres"] = train_types_json(train, length=float(length) if length is not None else None)
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "report.txt").write_text(report + "\n")
        failed = tuple(m for m in results if m in verdicts and not verdicts[m].usable) or failed_methods(ev_train, results)
        plot_fit(model_name, train, val, ev_train, ev_val, out / "fit.png", failed=failed)
        write_json(doc, out / "report.json")
        save_fit(best, out / "fit.json", train, registry=args.model, extra=extra)
        say(f"wrote {out / 'report.txt'}, {out / 'fit.png'}, {out / 'report.json'} and the fit file {out / 'fit.json'}")
    if args.save:
        save_fit(best, args.save, train, registry=args.model, extra=extra)
        say(f"wrote the fit file {args.save} (python -m diffship.predict {args.save} --manoeuvre ...)")
    if args.json:
        write_json(doc, args.json)
        say(f"wrote {args.json}")
