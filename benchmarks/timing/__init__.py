"""diffship against CasADi on one fossen3 output-error problem: how long a user waits.

One benchmark, three modes over one problem (:mod:`.problem`: the USV of ``diffship.synthetic``,
2 runs × 300 s at 10 Hz, realistic noise, 10 free parameters from a ±50 % start + 8 initial-state
offsets, written as CSV files; the CasADi peer solves the identical residual)::

    python -m benchmarks timing cold [--quick]       # cold and warm whole processes, in process, scipy, a batch
    python -m benchmarks timing single [--rounds 3]  # one fit as a user runs it, warm caches, interleaved rounds
    python -m benchmarks timing batched              # many fits: the batched LM, threads, CasADi looped, bootstrap

Each mode writes ``benchmarks/results/timing_<mode>.md`` (``cold`` also ``timing_cold.csv``;
``--quick`` writes ``*_quick.*``, kept out of git). CasADi comes with ``pip install -e ".[bench]"``.
"""

from __future__ import annotations

import importlib
import sys

#: mode → module (each has ``main(argv)``)
MODES = {"cold": "benchmarks.timing.cold", "single": "benchmarks.timing.single", "batched": "benchmarks.timing.batched"}


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] not in MODES:
        print(__doc__)
        print(f"choose a mode: {', '.join(MODES)}", file=sys.stderr)
        return 2
    sys.argv[0] = f"python -m benchmarks timing {argv[0]}"  # what argparse's usage lines name
    return importlib.import_module(MODES[argv[0]]).main(argv[1:]) or 0
