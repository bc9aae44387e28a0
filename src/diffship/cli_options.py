"""The options every diffship command line shares (fit, diagnose, predict, discover), from one place.

Each ``add_*`` function adds one group of options to an :class:`argparse.ArgumentParser` with the
same names, meanings, defaults and checks in every command:

* **data**: ``--validate``, ``--columns``, ``--degrees``, ``--rudder-sign``, ``--resample``;
* **vessel**: ``--vessel`` (a JSON file or a bundled vessel);
* **parameters**: ``--channels``, ``--fix``, ``--free``, ``--init``;
* **priors**: ``--prior``, ``--prior-file``, ``--no-prior``, ``--prior-sd``;
* **numerics**: ``--filter``, ``--solver``, ``--input-hold``, ``--starts``;
* **bootstrap**: ``--bootstrap``, ``--bootstrap-method`` (fit, discover);
* **output**: ``--out``, ``--json``, ``--quiet``.

Checks every command makes before it reads a run: :func:`output_problem` (an output path that is a
folder where a file is wanted or the reverse, that would overwrite an input file, that two outputs share
or where nothing can be written) and :func:`held_out_problem` (a held-out run that is also a training
run); once the model's parameters are set, :func:`init_problem` (an ``--init`` of a parameter the command
does not estimate); after the runs are read and before any fit, :func:`too_short_problem` (training runs
with fewer than :data:`SAMPLES_PER_PARAMETER` samples per estimated parameter).

Every command also leaves the same way: :func:`exit_now` (``fleet`` excepted: its Dask workers' clean-up
runs at the ordinary exit).

Rules: a list option may be repeated and its items accumulate (``--fix A=1 --fix B=2``
fixes both: ``action="extend"``); a malformed item (``--fix A``, ``--fix A=x``, ``--columns psi``,
an unknown channel, a file name where ``--degrees`` or ``--free`` expects a name: the option took the
run files after it) stops the command at once with argparse's one-line message and exit status 2,
before JAX or NumPy is imported. This module imports only the standard library and the plain-Python
tables (:mod:`diffship.particulars`, :mod:`diffship.channels`); a test checks it.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
from pathlib import Path
from typing import NoReturn

from .channels import CHANNEL_NAMES
from .particulars import bundled_vessels

__all__ = [
    "INTEGRATOR_NAMES",
    "add_bootstrap_options",
    "add_data_options",
    "add_numerics_options",
    "add_output_options",
    "add_parameter_options",
    "add_prior_options",
    "add_vessel_option",
    "exit_now",
    "assignment",
    "DATA_FILE_SUFFIXES",
    "channel_name",
    "column_mapping",
    "column_name",
    "helm_rate",
    "names_of",
    "non_negative_int",
    "out_folder_problem",
    "output_problem",
    "input_files",
    "held_out_problem",
    "init_problem",
    "too_short_problem",
    "SAMPLES_PER_PARAMETER",
    "parameter_name",
    "positive_float",
    "positive_int",
    "resamples",
    "prior_item",
    "RUDDER_SIGNS",
]

#: ``--solver`` choices: the keys of :data:`diffship.integrators.INTEGRATORS` (a test checks they agree).
INTEGRATOR_NAMES = ("diffrax-rk4", "diffrax-tsit5", "rk4", "tsit5")

#: Rudder sign conventions of the files (``--rudder-sign``).
RUDDER_SIGNS = ("starboard", "port")

#: Endings of the files a command reads (CSV runs, logs: :data:`diffship.logs.LOG_SUFFIXES`, vessel and prior JSON,
#: channel maps): a list option's item ending so is a file the option took from the words after it.
DATA_FILE_SUFFIXES = (".csv", ".tsv", ".txt", ".dat", ".json", ".toml", ".db3", ".mcap", ".bin", ".tlog", ".ulg",
                      ".parquet")


def _file_name(item: str, what: str) -> None:
    """Stop on a list option's item that is a file name (an existing file, or a run's or log's ending)."""
    if item.lower().endswith(DATA_FILE_SUFFIXES) or os.path.isfile(item):
        raise argparse.ArgumentTypeError(f"{item!r} is a file name, not {what}: the option takes every word after it; "
                                         "put the run files first, before the option (or after --)")


# -- item types: each returns the item unchanged (or converted) or raises argparse's error ------------------
def assignment(item: str) -> str:
    """``NAME=VALUE`` with a number as VALUE (``--fix``, ``--init``, ``--input``); returned as given."""
    name, sep, value = item.partition("=")
    if not sep or not name.strip():
        raise argparse.ArgumentTypeError(f"{item!r}: expected NAME=VALUE, e.g. T1=5.0")
    try:
        v = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{item!r}: {value.strip()!r} is not a number") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"{item!r}: the value must be finite")
    return f"{name.strip()}={value.strip()}"


def column_mapping(item: str) -> str:
    """``NAME=COLUMN`` (``--columns psi=heading``); returned as given."""
    name, sep, column = item.partition("=")
    if not sep or not name.strip() or not column.strip():
        raise argparse.ArgumentTypeError(f"{item!r}: expected NAME=COLUMN, e.g. psi=heading")
    return f"{name.strip()}={column.strip()}"


def prior_item(item: str) -> str:
    """``NAME=MEAN±SD`` (checked in full by :func:`diffship.fit.priors.parse_priors`); a name and ``=`` here."""
    name, sep, rest = item.partition("=")
    if not sep or not name.strip() or not rest.strip():
        raise argparse.ArgumentTypeError(f"{item!r}: expected NAME=MEAN±SD, e.g. Nrrr=-0.05±0.02")
    return item


def column_name(item: str) -> str:
    """A column name (``--degrees``), not a file name; returned as given."""
    _file_name(item, "a column")
    return item


def channel_name(item: str) -> str:
    """A channel name of :data:`diffship.channels.CHANNEL_NAMES` (``--channels``)."""
    if item not in CHANNEL_NAMES:
        raise argparse.ArgumentTypeError(f"{item!r} is not a channel; channels: {', '.join(CHANNEL_NAMES)}")
    return item


def parameter_name(item: str) -> str:
    """A parameter name (``--free``): a name, no ``=``."""
    if not item.strip() or "=" in item:
        raise argparse.ArgumentTypeError(f"{item!r}: expected a parameter name (NAME, no value), e.g. Xu")
    _file_name(item.strip(), "a parameter")
    return item.strip()


def positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (v > 0 and math.isfinite(v)):
        raise argparse.ArgumentTypeError(f"{text!r}: must be a positive number")
    return v


def _whole(text: str, least: int, words: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if v < least:
        raise argparse.ArgumentTypeError(f"{text!r}: must be {words}")
    return v


def positive_int(text: str) -> int:
    return _whole(text, 1, "at least 1")


def non_negative_int(text: str) -> int:
    return _whole(text, 0, "0 or more")


def out_folder_problem(path: str, option: str = "--out") -> str | None:
    """Why ``path`` cannot be the output folder (a file is in its place or above it), or ``None``."""
    for p in (Path(path), *Path(path).parents):
        if p.exists():
            return None if p.is_dir() else (f"{option} {path}: {p} is a file, not a folder; give a folder (it is "
                                              "created where missing) or move the file")
    return None


def same_file(a: str, b: str) -> bool:
    """Whether paths ``a`` and ``b`` name one file (the same file, or the same resolved path if one is missing)."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.realpath(a) == os.path.realpath(b)


def folder_problem(folder: Path) -> str | None:
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


def input_files(args: argparse.Namespace) -> list[tuple[str, str]]:
    """``(what, path)`` of the files a command reads: its training and held-out runs, and the files given to
    ``--prior-file``, ``--vessel`` and ``--map`` (where they are files: a bundled vessel or map is a name)."""
    inputs = [("the training run", p) for p in args.runs] + [("the held-out run", p) for p in args.validate]
    return inputs + [(f"the {o} file", v) for o, v in (("--prior-file", getattr(args, "prior_file", None)),
                                                         ("--vessel", getattr(args, "vessel", None)),
                                                         ("--map", getattr(args, "map", None)))
                     if v and os.path.isfile(v)]


def output_problem(inputs, out: str | None = None, out_files=(), files=()) -> str | None:
    """Why a command's outputs cannot be written as given, or ``None``, found before anything is read.

    ``inputs``: ``(what, path)`` of the files the command reads ("the training run", ...); ``out``: the
    ``--out`` folder, which receives ``out_files``; ``files``: ``(option, path)`` of single-file outputs
    (``--json``, ``--save``, ``--html``). Refused: ``--out`` an existing file or a folder that cannot be
    created, or whose files would overwrite an input; a file output that is an input, a folder, named twice,
    or in a folder that cannot be created."""
    if out is not None:
        if os.path.lexists(out) and not os.path.isdir(out):
            return (f"--out {out} is an existing file, not a folder: --out names the folder that receives "
                    f"{', '.join(out_files[:4])}; give a new or an existing folder")
        for f in out_files:
            if (inp := next((i for i in inputs if same_file(str(Path(out) / f), i[1])), None)) is not None:
                return f"--out {out} would write {f} over {inp[0]} {inp[1]}; give --out another folder"
        if (why := folder_problem(Path(out))) is not None:
            return f"--out {out}: {why}; give a folder that can be written"
    files = [(o, v) for o, v in files if v]
    for k, (opt, path) in enumerate(files):
        if (inp := next((i for i in inputs if same_file(path, i[1])), None)) is not None:
            return f"{opt} {path} is {inp[0]} {inp[1]}: writing it would overwrite that input; give {opt} another path"
        if os.path.isdir(path):
            return f"{opt} {path} is a folder: give a file name"
        if (other := next((o for o, q in files[:k] if same_file(path, q)), None)) is not None:
            return f"{other} and {opt} both name {path}: give each output its own file"
        if (why := folder_problem(Path(path).parent)) is not None:
            return f"{opt} {path}: {why}; give a path that can be written"
    return None


def held_out_problem(runs, validate) -> str | None:
    """Why the held-out runs cannot judge a fit to the training runs, or ``None``: one of them is a training
    run (the same file, resolved), whose fit it would only repeat."""
    for held in validate or ():
        if (train := next((r for r in runs if same_file(r, held)), None)) is not None:
            same = held if held == train else f"{held} (the same file as {train})"
            return (f"--validate {same} is also a training run: a held-out run must be one the fit never saw, or "
                    "it cannot show how the model predicts new data; give another run to --validate, or drop it "
                    "from the training runs")
    return None


def init_problem(init_items, fix_items=(), spec=None) -> str | None:
    """Why an ``--init NAME=VALUE`` item gives no start value, or ``None``: ``NAME`` is also given to ``--fix``
    (known from the command line alone), or, with ``spec`` (the command's parameters, free and fixed as
    ``--free``, ``--free-hydrodynamic`` and ``--fix`` set them, held at the vessel's or the model's values;
    anything with ``free_names`` and ``spec[name].value``), ``NAME`` is not estimated. A start value for a
    parameter the fit holds would silently become the value it is held at: a different model, unasked."""
    fixed = {i.partition("=")[0].strip(): i for i in fix_items or ()}
    for item in init_items or ():
        name, _, value = (t.strip() for t in item.partition("="))
        if name in fixed:
            return (f"--fix {fixed[name]} and --init {item}: a fixed parameter is not estimated and takes no start "
                    f"value; drop --init {name}, or drop --fix {name} to estimate it from {value}")
        if spec is not None and name in spec and name not in spec.free_names:
            return (f"--init {item}: {name} is not estimated (it is held at {spec[name].value:g}); --init gives start "
                    f"values to estimated parameters: add --free {name} to estimate it from {value}, or --fix "
                    f"{name}={value} to hold it there")
    return None


#: Samples the training runs must hold together (time steps, all runs, after ``--resample``) per parameter
#: the command estimates in its largest model: fewer, and the estimates are not determined by the data.
SAMPLES_PER_PARAMETER = 20


def too_short_problem(n_samples: int, n_params: int, what: str) -> str | None:
    """Why training runs of ``n_samples`` samples together are too short to estimate ``n_params`` parameters
    (``what``: the parameters named), or ``None``: fewer than :data:`SAMPLES_PER_PARAMETER` per parameter."""
    need = SAMPLES_PER_PARAMETER * n_params
    if n_samples >= need:
        return None
    return (f"the training runs hold {n_samples} samples together, too few to estimate {n_params} parameters "
            f"({what}): at least {SAMPLES_PER_PARAMETER} samples per parameter, {need}, are needed; give longer "
            "or more training runs (or a smaller --resample step)")


def helm_rate(text: str) -> float:
    """A steering-gear rate [°/s], positive."""
    return positive_float(text)


def _list(p, *flags, type, metavar, help, default=None):
    """A repeatable list option: items accumulate over repetitions; at least one item each time."""
    p.add_argument(*flags, nargs="*", action="extend", type=type, metavar=metavar,
                   default=[] if default is None else default, help=help + " (repeatable; items accumulate)")


# -- groups ------------------------------------------------------------------------------------------------
def add_data_options(p: argparse.ArgumentParser, *, validate: bool = True, validate_required: bool = False,
                     resample: bool = True) -> None:
    """Held-out runs, column mapping, degree columns, rudder sign convention, resampling."""
    g = p.add_argument_group("data (CSV runs; SI units, radians, NED/FRD, heading clockwise from north)")
    if validate:
        g.add_argument("--validate", nargs="+", action="extend", metavar="RUN.csv", required=validate_required,
                       default=[], help="held-out runs, scored but never fitted (repeatable; items accumulate)")
    _list(g, "--columns", type=column_mapping, metavar="NAME=COLUMN",
          help="map diffship channel names to file columns, e.g. psi=heading. Channel names: "
               + ", ".join(f"{c} [{u}]" for c, u in CHANNEL_NAMES.items())
               + "; columns with other names are kept under their own names")
    _list(g, "--degrees", type=column_name, metavar="COLUMN", help="columns given in degrees (deg/s)")
    g.add_argument("--time-unit", default="s", choices=("s", "ms", "us"),
                   help="unit of a numeric time column: s (default), ms or us (converted to seconds); date-time "
                        "stamps are read as seconds from the first")
    g.add_argument("--rudder-sign", default="starboard", choices=RUDDER_SIGNS,
                   help="sign convention of delta in the files: starboard (positive turns to starboard; default) "
                        "or port")
    if resample:
        g.add_argument("--resample", type=positive_float, default=None, metavar="DT",
                       help="resample runs to a uniform step [s]")
        g.add_argument("--horizon", type=positive_float, default=None, metavar="S",
                       help="fit only the first S seconds of each training run (long zigzags: the later part drifts "
                            "with unmodelled effects); the metrics still simulate every run over its whole length")


def add_vessel_option(p: argparse.ArgumentParser) -> None:
    """``--vessel FILE|NAME``: the particulars rule of every command (a model that needs particulars
    stops without a vessel or ``--fix`` for them)."""
    p.add_argument("--vessel", default=None, metavar="FILE|NAME",
                   help="vessel particulars: a JSON file or a bundled vessel (" + ", ".join(bundled_vessels())
                        + "); models that need particulars (mass, inertia, dimensions, ...) stop without one "
                        "unless --fix gives them")


def add_parameter_options(p: argparse.ArgumentParser, *, init: bool = True, channels_help: str | None = None) -> None:
    """``--channels``, ``--fix``, ``--free``, ``--init``."""
    g = p.add_argument_group("parameters and channels")
    g.add_argument("--channels", nargs="+", action="extend", type=channel_name, default=None, metavar="NAME",
                   help=(channels_help or "channels fitted by output error (default: what the model predicts and "
                         "the runs have, positions x0, y0 left out)") + " (repeatable; items accumulate)")
    _list(g, "--fix", type=assignment, metavar="NAME=VALUE", help="hold parameters fixed")
    _list(g, "--free", type=parameter_name, metavar="NAME", help="estimate parameters fixed by default")
    g.add_argument("--free-hydrodynamic", action="store_true",
                   help="estimate every parameter that is not a vessel particular (mmg: the 33 hull, rudder, "
                        "interaction and wake coefficients of diffship.studies.kvlcc2), each held by its reference "
                        "prior where the model has one")
    if init:
        _list(g, "--init", type=assignment, metavar="NAME=VALUE", help="start values for output error")


def add_prior_options(p: argparse.ArgumentParser) -> argparse._ArgumentGroup:
    """Gaussian priors (MAP fits): ``--prior``, ``--prior-file``, ``--no-prior``, ``--prior-sd``."""
    g = p.add_argument_group("priors and admissibility (predictive identification)")
    _list(g, "--prior", type=prior_item, metavar="NAME=MEAN±SD",
          help="Gaussian prior on a parameter (MAP fit); also NAME=MEAN+-SD or SD in %% of MEAN")
    g.add_argument("--prior-file", default=None, metavar="FILE",
                   help='priors from JSON {"NAME": {"mean": M, "sd": S}} (or a saved fit file\'s priors)')
    g.add_argument("--no-prior", action="store_true",
                   help="no priors from the model's reference set (on by default for mmg/KVLCC2, fossen3/USV, "
                        "fossen6/BlueROV2 when the fixed particulars are the reference vessel's)")
    g.add_argument("--prior-sd", type=positive_float, default=0.5, metavar="REL",
                   help="relative standard deviation of the reference-set priors (default 0.5)")
    return g


def add_numerics_options(p: argparse.ArgumentParser, *, filter_help: str | None = None) -> None:
    """``--filter``, ``--solver``, ``--input-hold``, ``--max-steps``, ``--starts``."""
    g = p.add_argument_group("numerics")
    g.add_argument("--filter", default="butter", metavar="butter[:Hz]|savgol[:s]|none|kalman",
                   help=filter_help or "differentiation / initial-state filter: butter[:Hz] (default), savgol[:s], "
                                       "none, or kalman (extended Kalman filter + RTS smoother)")
    g.add_argument("--solver", default="diffrax-rk4", choices=INTEGRATOR_NAMES,
                   help="integrator: diffrax-rk4 (default: diffrax's RK4 tableau, one step per sample), diffrax-tsit5 "
                        "(diffrax Tsit5, one step per sample), rk4 (hand-written RK4, faster Jacobian) or tsit5 "
                        "(diffrax Tsit5, adaptive within each sample)")
    g.add_argument("--input-hold", default="linear", choices=("linear", "zero"),
                   help="what the logged inputs did between samples: linear (first-order hold, default: a sampled "
                        "continuous signal) or zero (held until the next sample: a digital command)")
    g.add_argument("--max-steps", type=positive_int, default=None, metavar="N",
                   help="Levenberg–Marquardt steps per output-error pass (default 200)")
    g.add_argument("--starts", type=positive_int, default=None, metavar="N",
                   help="output error from N starts (the model's values, the equation-error estimate, spread "
                        "starts); the lowest cost is kept and the report says how many reached it")


def resamples(text: str) -> int:
    """``--bootstrap N``: 0 (off) or at least 2 resamples."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--bootstrap needs a whole number of resamples, got {text!r}") from None
    if n != 0 and n < 2:
        raise argparse.ArgumentTypeError(f"--bootstrap needs at least 2 resamples, got {n}")
    return n


def add_bootstrap_options(p: argparse.ArgumentParser, *, what: str = "the output-error fit") -> None:
    """``--bootstrap N`` and ``--bootstrap-method``: percentile intervals from N refits."""
    g = p.add_argument_group("bootstrap")
    g.add_argument("--bootstrap", type=resamples, default=0, metavar="N",
                   help=f"refit {what} on N resamples (in one batch) and report 95 %% percentile intervals beside "
                        "the covariance ones (text and JSON)")
    g.add_argument("--bootstrap-method", default="blocks", choices=("blocks", "runs"),
                   help="resampling: moving blocks of each run's residuals (default) or whole runs (needs >= 2)")


def add_output_options(p: argparse.ArgumentParser, *, out_help: str, json_help: str | None = None) -> None:
    """``--out DIR``, ``--json FILE``, ``--quiet``."""
    p.add_argument("--out", default=None, metavar="DIR", help=out_help)
    if json_help is not None:
        p.add_argument("--json", default=None, metavar="FILE", help=json_help)
    p.add_argument("--quiet", action="store_true", help="no progress messages")


def names_of(items) -> list[str]:
    """Parameter names of checked ``NAME=VALUE`` items."""
    return [i.partition("=")[0].strip() for i in items]


def exit_now(code: int | None) -> NoReturn:
    """Leave the command with exit status ``code`` (``None`` is 0) once stdout and stderr are flushed.

    The process ends at once (:func:`os._exit`) instead of through the interpreter's teardown, which
    frees every compiled XLA program and module one by one: 1.1 s after a diagnosis of the USV
    current case (``benchmarks/diagnose_current_case.py``) (measured from the last ``atexit`` handler to the process's end), on a command that
    has written and closed all its files by then. Under a tracer or profiler (coverage, ``python -m
    cProfile``) the ordinary :func:`sys.exit`, so that they write their results; an exception leaving
    ``main`` never reaches here and ends the process the ordinary way."""
    code = 0 if code is None else int(code)
    if sys.gettrace() is not None or sys.getprofile() is not None:
        sys.exit(code)
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe (``| head``) or stream: nothing left to say there
            pass
    os._exit(code)
