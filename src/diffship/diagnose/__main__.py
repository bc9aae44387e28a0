"""``python -m diffship.diagnose TRAIN.csv ... --validate VAL.csv ... --model NAME`` (thin CLI)."""

from __future__ import annotations

import argparse
import sys
import time

from ..errors import DiffshipError
from ..log_options import add_log_options, log_kwargs
from ..models.effects import EFFECT_NAMES

EPILOG = (f"Effects: {', '.join(EFFECT_NAMES)} (wind needs wind_speed and wind_dir columns). "
          "Exit status: 0 done, 2 user error (message on stderr).")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m diffship.diagnose", epilog=EPILOG,
                                description="Diagnose where a fitted model misses, which unmodelled effect explains it "
                                            "(selected on held-out runs) and how much of the gap it closes.")
    p.add_argument("runs", nargs="+", metavar="TRAIN.csv", help="training runs")
    p.add_argument("--validate", nargs="+", required=True, metavar="VAL.csv", help="held-out validation runs")
    p.add_argument("--model", required=True, help="base model name (e.g. fossen3, nomoto1, nomoto2)")
    p.add_argument("--fix", nargs="*", default=[], metavar="NAME=VALUE", help="hold base parameters fixed")
    p.add_argument("--rudder-sign", default="starboard", choices=("starboard", "port"))
    p.add_argument("--columns", nargs="*", default=[], metavar="NAME=COLUMN")
    p.add_argument("--degrees", nargs="*", default=[], metavar="COLUMN")
    p.add_argument("--resample", type=float, default=None, metavar="DT")
    p.add_argument("--effects", default="all", help="all, or a comma-separated list of effect names")
    p.add_argument("--refit-all", action="store_true", help="refit every candidate, not only the screen's best")
    p.add_argument("--out", default=None, metavar="DIR", help="write diagnosis.md, diagnosis.json and figures here")
    p.add_argument("--json", default=None, metavar="FILE", help="write the JSON result here")
    p.add_argument("--quiet", action="store_true")
    add_log_options(p)  # --map (logs), --html (issue 30)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    t0 = time.perf_counter()

    def say(msg):
        if not args.quiet:
            print(f"[{time.perf_counter() - t0:6.1f} s] {msg}", file=sys.stderr, flush=True)

    try:
        from ..data import load_runs
        from ..models import get_model
        from ..params import parse_assignments
        from .diagnosis import DiagnoseOptions, diagnose
        from .report import to_markdown, write_json, write_report

        effects = "all" if args.effects == "all" else [e.strip() for e in args.effects.split(",") if e.strip()]
        options = DiagnoseOptions(effects=effects, refit_all=args.refit_all)
        model = get_model(args.model)
        fix = parse_assignments(args.fix, "--fix")
        spec = model.spec()
        spec = spec.fix(fix) if fix else spec
        columns = dict(c.split("=", 1) for c in args.columns if "=" in c)
        kw = dict(columns=columns or None, degrees=args.degrees, rudder_sign=args.rudder_sign, **log_kwargs(args))
        train, val = load_runs(args.runs, **kw), load_runs(args.validate, **kw)
        if args.resample:
            train = [r.resample(args.resample) for r in train]
            val = [r.resample(args.resample) for r in val]
        d = diagnose(model, train, val, spec=spec, options=options, progress=say)
    except DiffshipError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(to_markdown(d))
    if args.out:
        files = write_report(d, args.out)
        say("wrote " + ", ".join(str(f) for f in files))
    if args.json:
        write_json(d, args.json)
        say(f"wrote {args.json}")
    if args.html:
        from ..html import write_html_report

        say(f"wrote {write_html_report(args.html, f'diffship diagnosis: {args.model}', to_markdown(d), lambda f: write_report(d, f))}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
