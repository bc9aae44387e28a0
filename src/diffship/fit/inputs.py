"""The fit command's checks of what it was given, before any run is read or any fit starts.

:func:`input_problem` returns one line for a command line that cannot give what it asks for, or
``None``: held-out runs (``--validate``) without a training run or that are also training runs
(:func:`diffship.cli_options.held_out_problem`), options that contradict each other
(``--fix`` with ``--free``, ``--init`` or ``--prior`` on the same parameter; ``--shooting multiple``
with a method that fits no output error; ``--check-sampling`` without ``--resample``), and output
paths that would overwrite an input file or cannot be written
(:func:`diffship.cli_options.output_problem`: ``--out`` an existing file or a folder that cannot be
created; ``--save``, ``--json``, ``--html`` a folder, the same file twice, or in a folder that cannot
be created). Both :func:`diffship.fit.args.precheck` (before JAX is
imported) and :func:`diffship.fit.cli.main` ask it. Once the model and the vessel have set the
parameters, and before a run is read, :func:`spec_problem` stops an ``--init`` of a parameter the fit
does not estimate (not in ``--free``, not freed by ``--free-hydrodynamic``, nor free by the model's
default): its start value would silently become the value the fit holds it at. Standard library only.
"""

from __future__ import annotations

import argparse

from ..cli_options import held_out_problem, init_problem, input_files, output_problem

__all__ = ["DEFAULT_OUT", "OUT_FILES", "input_problem", "spec_problem"]

#: Where the bundled example's fit writes its report, figure, JSON and fit file when ``--out`` is not given.
DEFAULT_OUT = "diffship_fit"

#: The files ``--out DIR`` writes.
OUT_FILES = ("report.txt", "fit.png", "report.json", "fit.json", "cross_manoeuvre.png")


def input_problem(args: argparse.Namespace) -> str | None:
    """The one line that stops the fit command before it reads a run, or ``None``."""
    return _runs_problem(args) or _option_conflict(args) or _output_problem(args)


def _runs_problem(args) -> str | None:
    if args.validate and not args.runs:
        return (f"no training run given: --validate takes every file after it as a held-out run "
                f"({', '.join(args.validate)}); put the training files before --validate, or after --, e.g. "
                "python -m diffship.fit TRAIN.csv --validate HELD.csv (the bundled example is fitted only when no "
                "file is given)")
    return held_out_problem(args.runs, args.validate)


def _items(items) -> dict[str, str]:
    """``NAME=...`` items by name (the last one of a name)."""
    return {i.partition("=")[0].strip(): i for i in items or ()}


def _option_conflict(args) -> str | None:
    fix = _items(args.fix)
    for n in args.free:
        if n in fix:
            return (f"--fix {fix[n]} and --free {n}: a parameter is either held at a value (--fix) or estimated "
                    "(--free); drop one of them")
    if (problem := init_problem(_items(args.init).values(), args.fix)) is not None:
        return problem
    for n, item in _items(args.prior).items():
        if n in fix:
            return (f"--fix {fix[n]} and --prior {item}: a prior weighs the estimate of a free parameter, and a "
                    f"fixed one keeps its value; drop one of them")
    if args.shooting.partition(":")[0] == "multiple" and args.method in ("equation-error", "prediction-error"):
        return (f"--shooting {args.shooting} and --method {args.method}: multiple shooting is a way of fitting "
                f"output error, which --method {args.method} does not run; use --method output-error or both, or "
                "drop --shooting")
    if args.check_sampling and not args.resample:
        return ("--check-sampling without --resample: it refits at the files' own rate to compare with the fit at "
                "the --resample step; add --resample DT or drop --check-sampling")
    return None


def spec_problem(args: argparse.Namespace, spec) -> str | None:
    """The one line that stops the fit command once its parameters are set (``spec``: free from ``--free`` and
    ``--free-hydrodynamic``, fixed by ``--fix`` or by the model, held at the vessel's or the model's values),
    before any run is read, or ``None``: an ``--init`` of a parameter the fit does not estimate, whose start
    value would otherwise silently become the value the fit holds it at."""
    return init_problem(_items(args.init).values(), args.fix, spec)


def _output_problem(args) -> str | None:
    inputs = input_files(args)
    out = args.out or (None if args.runs else DEFAULT_OUT)
    files = [(f"--{o}", getattr(args, o, None)) for o in ("save", "json", "html")]
    return output_problem(inputs, out, OUT_FILES, files)
