"""diffship benchmark suite: output error vs equation error vs the tools users would pick instead.

Run all cases (from the repository root)::

    PYTHONPATH=src .venv/bin/python -m benchmarks [--quick] [--cases nomoto,fossen3] [--report-only] [--out DIR]
    PYTHONPATH=src .venv/bin/python benchmarks/run.py [...]          # the same command, as a script
    PYTHONPATH=src .venv/bin/python -m benchmarks.cases.nomoto --quick   # one case module alone

Layout:

* :mod:`benchmarks.suite` — the case registry and the command line (``main``);
* :mod:`benchmarks.record` — the recorder (every number into ``all_numbers*.csv``), timing and
  peak-memory helpers, the per-method accuracy rows shared by all cases;
* :mod:`benchmarks.report` — figures and the ``report*.md`` writer;
* :mod:`benchmarks.fitapi` — every call into diffship's fitting API (one place to edit when its
  signatures change);
* :mod:`benchmarks.peers` — the NumPy/SciPy peers (scipy ``least_squares`` over NumPy RK4,
  NumPy OLS on inverse dynamics, STLSQ/SINDy);
* :mod:`benchmarks.cases` — one module per case (nomoto, fossen3, vmm, rov, sspa, kvlcc2).

See ``benchmarks/README.md`` for what is measured and how.
"""

import diffship  # noqa: F401  (enables float64 before any array is made)
