"""``python -m diffship.fleet MANIFEST --out DIR``: fit every vessel-run of a fleet on Dask.

Exit status: 0 all fitted, 1 some vessel-runs failed (see DIR/results.parquet; rerun to retry them),
2 user error (one line on stderr).
"""

from __future__ import annotations

import argparse
import sys

from ..errors import DiffshipError


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m diffship.fleet", description=(
        "Fit many vessel-runs on Dask distributed workers (a local cluster by default). MANIFEST: a CSV or "
        "parquet table with columns vessel, runs (files or logs, ';'-separated), model, and optionally run, map, "
        "vessel_file. Results: DIR/results.parquet (one row per vessel-run) and DIR/fits/<vessel>__<run>.json; "
        "a rerun skips what is done."))
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
    return 1 if s["failed"] else 0


if __name__ == "__main__":
    sys.exit(main())  # the ordinary exit (not exit_now): Dask's own clean-up of its workers runs at exit
