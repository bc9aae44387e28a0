"""Run one case module alone: ``python -m benchmarks.cases.<module> [--quick] [--out DIR] ...``."""

from __future__ import annotations

import sys


def run_alone(cases: dict, argv=None) -> int:
    """The suite's command line restricted to ``cases`` (a later ``--cases`` on the command line wins)."""
    from benchmarks.suite import main

    argv = list(sys.argv[1:] if argv is None else argv)
    return main(["--cases", ",".join(cases)] + argv)
