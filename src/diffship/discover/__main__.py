"""``python -m diffship.discover TRAIN.csv ... --validate HELD.csv ... --model fossen3`` (thin: parse, call,
print). Errors a user can fix are one line ``error: ...`` with exit status 2, and so is a base fit that cannot be
carried out (every start diverges; the files asked for then say so, :mod:`diffship.stopped`). The selected model
is judged as ``python -m diffship.fit`` judges a fit (:func:`diffship.usability.verdict`: FAILED, not converged,
unidentifiable): its verdict comes first in the report, in the JSON (``usable``, ``verdict`` of ``selected`` and
``base``) and in the fit file, and a selected model that is not usable ends the command with exit status 1, the
reason on the last line.

Before any run is read, outputs that cannot be written or would overwrite an input
(:func:`diffship.cli_options.output_problem`, as in ``python -m diffship.fit``) and a held-out run that is
also a training run stop the command. After the runs are read and before any fit, training runs too short
for the search stop it: the training runs together (after ``--resample``) must hold at least
:data:`~diffship.cli_options.SAMPLES_PER_PARAMETER` (20) samples per parameter of the largest candidate,
the base model's free parameters and ``--max-terms`` terms.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from ..cli_options import (add_bootstrap_options, add_data_options, add_numerics_options, add_output_options,
                           add_parameter_options, add_prior_options, add_vessel_option, held_out_problem, input_files,
                           output_problem, positive_int, too_short_problem)
from ..errors import DiffshipError, FitError
from ..log_options import add_log_options, log_kwargs
from ..stopped import stopped_command

__all__ = ["OUT_FILES", "build_parser", "main"]

#: The files ``--out DIR`` writes.
OUT_FILES = ("report.txt", "report.json", "discover.png", "fit.json")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m diffship.discover",
                                description="Find the terms a 3-DOF model's equations need: equation-error screen "
                                            "of a term library, output-error refit of every candidate structure, "
                                            "ranking on output residuals, confirmation on held-out runs.")
    p.add_argument("runs", nargs="+", metavar="RUN.csv", help="training runs")
    p.add_argument("--model", default="fossen3", choices=("fossen3",), help="base model (default fossen3)")
    add_data_options(p)
    add_parameter_options(p)
    add_numerics_options(p)
    add_output_options(p, out_help="write report.txt, discover.png, report.json and the fit file fit.json here",
                       json_help="write the results as JSON")
    p.add_argument("--save", default=None, metavar="FILE", help="write the discovered model's fit file here")
    add_prior_options(p)
    add_vessel_option(p)
    p.add_argument("--library", default="symmetric", metavar="NAME|TERMS",
                   help="term library: symmetric (default), all, or term names/expressions separated by commas "
                        "(N_v_r, 'Y: r|r|')")
    p.add_argument("--max-terms", type=int, default=4, metavar="N", help="most terms in a candidate (default 4)")
    p.add_argument("--candidates", type=positive_int, default=6, metavar="N",
                   help="most structures refitted by output error, the base included (default 6)")
    p.add_argument("--criterion", default="bic", choices=("bic", "aic"))
    p.add_argument("--x0", default="estimate", choices=("estimate", "data"),
                   help="initial states in every fit: estimated per run within each channel's noise (default: an "
                        "initial-state error of a slow mode lasts for much of a run and candidate terms absorb "
                        "it) or taken from the data (the filtered first samples)")
    add_bootstrap_options(p, what="the discovered model")
    add_log_options(p)  # --map (logs), --html, as in fit, diagnose and predict
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return _run(args)
    except DiffshipError as exc:
        print(f"error: {exc}", file=sys.stderr)
        if isinstance(exc, FitError):  # no fit: the files asked for say so, none of an earlier command's is left
            stopped_command(args, str(exc), OUT_FILES, "diffship discover")
        return 2


def _run(args) -> int:
    if args.max_terms < 1:
        raise DiffshipError(f"--max-terms {args.max_terms}: give at least 1")
    problem = held_out_problem(args.runs, args.validate) or output_problem(
        input_files(args), args.out, OUT_FILES, [("--save", args.save), ("--json", args.json), ("--html", args.html)])
    if problem is not None:
        raise DiffshipError(problem)
    from ..models.terms import library_terms

    library_terms(args.library)  # unknown names fail here, before JAX work
    from ..data import load_runs, resample_runs
    from ..fit import OutputError
    from ..fitfile import save_fit
    from ..integrators import get_integrator
    from ..preprocess import Filter
    from ..vessel import model_spec
    from .discovery import discover
    from .report import discovery_json, discovery_text, plot_discovery

    t0 = time.perf_counter()

    def say(msg: str) -> None:
        if not args.quiet:
            print(f"[{time.perf_counter() - t0:6.1f} s] {msg}", file=sys.stderr, flush=True)

    model, spec, fix, init = model_spec(args.model, args.vessel, args.fix, args.init, args.free)
    spec = spec.with_values(init)
    cols = dict(c.split("=", 1) for c in args.columns) or None
    kw = dict(columns=cols, degrees=args.degrees, rudder_sign=args.rudder_sign, time_unit=args.time_unit,
              **log_kwargs(args))
    train = load_runs(args.runs, **kw)
    val = load_runs(args.validate, **kw) if args.validate else []
    if args.resample:
        held = model.input_names if args.input_hold == "zero" else ()  # inputs held over each sample
        train, val = resample_runs(train, args.resample, held=held), resample_runs(val, args.resample, held=held)
    n_free = len(spec.free_names)
    if (problem := too_short_problem(sum(len(r.time) for r in train), n_free + args.max_terms,
                                     f"{model.name}'s {n_free} free and {args.max_terms} terms, --max-terms")):
        raise DiffshipError(problem)
    opts = OutputError(integrator=get_integrator(args.solver, hold=args.input_hold), reference_priors=not args.no_prior,
                       prior_rel_sd=args.prior_sd, **({"max_steps": args.max_steps} if args.max_steps else {}))
    flt = Filter.parse(args.filter) if args.filter != "kalman" else Filter()
    d = discover(model.with_params(spec.values()), train, val, spec=spec, library=args.library,
                 max_terms=args.max_terms, max_candidates=args.candidates, criterion=args.criterion, options=opts,
                 flt=flt, n_starts=args.starts or 1, x0=args.x0, progress=say)
    from ..usability import verdict

    verdicts = {k: verdict(c.result, c.train, train, c.validation, val) for k, c in (("selected", d.selected),
                                                                                    ("base", d.base))}
    text = discovery_text(d, model.name, verdicts["selected"])
    doc = discovery_json(d, model.name, verdicts)
    if args.bootstrap:  # percentile intervals of the discovered model from refits of resamples
        from ..fit.bootstrap import bootstrap_report

        block, doc["selected"]["bootstrap"] = bootstrap_report(d.selected.result, train, args.bootstrap,
                                                               args.bootstrap_method, say)
        text += "\n" + block
    print(text)
    dump = lambda obj, path: Path(path).write_text(json.dumps(obj, indent=2, default=float))  # noqa: E731
    extra = {"discover": {"terms": list(d.selected.terms), "confirmed": d.confirmed},
             "usable": verdicts["selected"].usable, "verdict": verdicts["selected"].as_json(),
             "metrics": {"train": doc["selected"]["train"], "validation": doc["selected"]["validation"],
                         "validation_runs": [r.name for r in val]}}
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "report.txt").write_text(text + "\n")
        dump(doc, out / "report.json")
        plot_discovery(d, model.name, train, val, out / "discover.png")
        save_fit(d.selected.result, out / "fit.json", train, registry=args.model, extra=extra)
    if args.save:
        save_fit(d.selected.result, args.save, train, registry=args.model, extra=extra)
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)  # as the fit command's --json
        dump(doc, args.json)
    if args.html:  # one self-contained file with the figure --out writes
        from ..html import write_html_report

        def figures(folder):
            plot_discovery(d, model.name, train, val, folder / "discover.png")
            return [folder / "discover.png"]
        say(f"wrote {write_html_report(args.html, f'diffship discover: {model.name}', text, figures)}")
    if not verdicts["selected"].usable:  # as python -m diffship.fit: the reason on the last line, exit status 1
        v = verdicts["selected"]
        print(f"error: no usable fit was found (selected model: {v.reasons[0] if v.reasons else v.label})",
              file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    from ..cli_options import exit_now

    exit_now(main())
