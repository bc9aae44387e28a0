"""The fit command's checks of what it was given, before any file is read or any fit starts.

:func:`input_problem` returns one line for a command line that cannot give what it asks for, or
``None``: held-out runs (``--validate``) without a training run, options that contradict each other
(``--fix`` with ``--free``, ``--init`` or ``--prior`` on the same parameter; ``--shooting multiple``
with a method that fits no output error; ``--check-sampling`` without ``--resample``), and output
paths that would overwrite an input file or cannot be written (``--out`` an existing file or a
folder that cannot be created; ``--save``, ``--json``, ``--html`` a folder, the same file twice, or
in a folder that cannot be created). Both :func:`diffship.fit.args.precheck` (before JAX is
imported) and :func:`diffship.fit.cli.main` ask it. Standard library only.
"""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

__all__ = ["DEFAULT_OUT", "OUT_FILES", "input_problem"]

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
    return None


def _items(items) -> dict[str, str]:
    """``NAME=...`` items by name (the last one of a name)."""
    return {i.partition("=")[0].strip(): i for i in items or ()}


def _option_conflict(args) -> str | None:
    fix = _items(args.fix)
    for n in args.free:
        if n in fix:
            return (f"--fix {fix[n]} and --free {n}: a parameter is either held at a value (--fix) or estimated "
                    "(--free); drop one of them")
    for n, item in _items(args.init).items():
        if n in fix:
            return (f"--fix {fix[n]} and --init {item}: a fixed parameter is not estimated and takes no start value; "
                    f"drop --init {n}, or drop --fix {n} to estimate it from {item.partition('=')[2]}")
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


def _same(a: str, b: str) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.realpath(a) == os.path.realpath(b)


def _folder_problem(folder: Path) -> str | None:
    """Why files cannot be written in ``folder`` (created if missing), or ``None``: found by creating the
    missing folders and a temporary file there, and removing what was created."""
    missing, p = [], folder
    while not os.path.lexists(p) and p != p.parent:
        missing.append(p)
        p = p.parent
    if not p.is_dir():
        return f"{p} is not a folder"
    made = []
    try:
        for d in reversed(missing):
            d.mkdir()
            made.append(d)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        return f"cannot {'create' if missing else 'write in'} {folder} ({exc.strerror or exc})"
    finally:
        for d in reversed(made):
            d.rmdir()
    return None


def _output_problem(args) -> str | None:
    inputs = [("the training run", p) for p in args.runs] + [("the held-out run", p) for p in args.validate]
    inputs += [(f"the {o} file", v) for o, v in (("--prior-file", args.prior_file), ("--vessel", args.vessel),
                                                   ("--map", getattr(args, "map", None))) if v and os.path.isfile(v)]
    out = args.out or (None if args.runs else DEFAULT_OUT)
    if out is not None:
        if os.path.lexists(out) and not os.path.isdir(out):
            return (f"--out {out} is an existing file, not a folder: --out names the folder that receives "
                    f"{', '.join(OUT_FILES[:4])}; give a new or an existing folder")
        for f in OUT_FILES:
            if (inp := next((i for i in inputs if _same(str(Path(out) / f), i[1])), None)) is not None:
                return f"--out {out} would write {f} over {inp[0]} {inp[1]}; give --out another folder"
        if (why := _folder_problem(Path(out))) is not None:
            return f"--out {out}: {why}; give a folder that can be written"
    files = [(f"--{o}", v) for o in ("save", "json", "html") if (v := getattr(args, o, None))]
    for k, (opt, path) in enumerate(files):
        if (inp := next((i for i in inputs if _same(path, i[1])), None)) is not None:
            return f"{opt} {path} is {inp[0]} {inp[1]}: writing it would overwrite that input; give {opt} another path"
        if os.path.isdir(path):
            return f"{opt} {path} is a folder: give a file name"
        if (other := next((o for o, q in files[:k] if _same(path, q)), None)) is not None:
            return f"{other} and {opt} both name {path}: give each output its own file"
        if (why := _folder_problem(Path(path).parent)) is not None:
            return f"{opt} {path}: {why}; give a path that can be written"
    return None
