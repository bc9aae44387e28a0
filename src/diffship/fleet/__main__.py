"""``python -m diffship.fleet MANIFEST --out DIR``: fit every vessel-run of a fleet on Dask.

Exit status: 0 every vessel-run of the manifest has a usable fit; 1 some have none: failed without a fit
(rerun to retry them) or fitted with a verdict FAILED (the verdict of ``python -m diffship.fit``,
:mod:`diffship.usability`; a rerun does not refit them, the same data give the same fit); 2 user error (one
line on stderr). Why "some" and not "none usable" as in ``python -m diffship.fit``: the fleet's status says
whether *some* vessel-runs are left without a result (one failure among many gives 1, as the fleet guide
says), and per vessel-run it keeps the fit command's convention: a vessel-run for which the fit command would
exit 1 (no usable fit) is left without a usable result, as a failed one is, so the fleet exits 1. Fits that
are usable with a warning (not converged, unidentifiable, a parameter on its bound) keep 0, as the fit
command's do, and are named on the summary's ``warning:`` line; the ``NOT USABLE:`` line names the others with
their reason, and DIR/results.parquet holds every verdict (its columns: :mod:`diffship.fleet.engine`).
"""

from __future__ import annotations

import argparse
import sys

from ..errors import DiffshipError


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m diffship.fleet", description=(
        "Fit many vessel-runs on Dask distributed workers (a local cluster by default). MANIFEST: a CSV or "
        "parquet table with columns vessel, runs (files or logs, ';'-separated), model, and optionally run, map, "
        "vessel_file. Results: DIR/results.parquet (one row per vessel-run, with its fit's verdict: columns verdict, "
        "usable, reason, unidentified, on_bound) and DIR/fits/<vessel>__<run>.json (fit files with the verdict); "
        "a rerun skips what is fitted. Exit status 1 when some vessel-run has no usable fit (named on the NOT "
        "USABLE line)."))
    p.add_argument("manifest", metavar="MANIFEST")
    p.add_argument("--out", required=True, metavar="DIR", help="results folder (reused by a rerun)")
    p.add_argument("--workers", type=int, default=2, help="local worker processes, one thread each (default 2)")
    p.add_argument("--address", default=None, metavar="HOST:PORT",
                   help="an existing Dask scheduler (e.g. tcp://10.0.0.5:8786) instead of a local cluster")
    p.add_argument("--batch", type=int, default=8, help="vessel-runs per task (default 8)")
    p.add_argument("--retries", type=int, default=0,
                   help="times a task whose worker died is retried elsewhere (default 0: recorded as failed, "
                        "left for the rerun)")
    p.add_argument("--threads", type=int, default=None,
                   help="threads per worker for a fit's starts (default: the cores shared out among the local "
                        "workers; with --address, one per core)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.workers < 1 or args.batch < 1 or args.retries < 0 or (args.threads is not None and args.threads < 1):
        print("error: --workers, --batch and --threads must be at least 1, --retries at least 0", file=sys.stderr)
        return 2
    try:
        from .engine import run_fleet

        s = run_fleet(args.manifest, args.out, workers=args.workers, address=args.address, batch=args.batch,
                      retries=args.retries, progress=not args.quiet, threads=args.threads)
    except DiffshipError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"fleet: {s['done']} fitted, {s['failed']} failed, {s['skipped']} skipped (done before) of {s['total']} "
          f"vessel-runs in {s['seconds']:.1f} s; table {s['table']}")
    print(summary_lines(s))
    return 1 if s["not_usable"] else 0


def _listed(items: list[tuple], most: int = 20) -> str:
    text = ", ".join(f"{i[0]} ({': '.join(i[1:])})" if i[-1] else f"{i[0]} ({i[1]})" for i in items[:most])
    return text + (f", and {len(items) - most} more (see the table)" if len(items) > most else "")


def summary_lines(s) -> str:
    """The verdict lines of a fleet's summary: the count of every label, then the vessel-runs that are not
    usable (``NOT USABLE:``) and those usable with a warning (``warning:``), each with its reason."""
    v = s["verdicts"]
    bad = len(s["not_usable"])
    head = (f"verdicts: {v['usable']} usable, {v['FAILED']} FAILED"
            + (f" ({s['no_fit']} without a fit)" if s["no_fit"] else "")
            + f", {v['not converged']} not converged, {v['unidentifiable']} unidentifiable; "
            + (f"{bad} of {s['total']} vessel-runs NOT USABLE" if bad else f"all {s['total']} vessel-runs usable"))
    lines = [head]
    if bad:
        lines.append("NOT USABLE: " + _listed(s["not_usable"]))
    if s["warned"]:
        lines.append("warning: " + _listed(s["warned"]))
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())  # the ordinary exit (not exit_now): Dask's own clean-up of its workers runs at exit
