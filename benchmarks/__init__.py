"""diffship's benchmarks: measured speed and accuracy, one result per benchmark in ``results/``.

One entry point (from the repository root, with diffship installed)::

    python -m benchmarks                      # list the benchmarks
    python -m benchmarks NAME [ARGS ...]      # run one; NAME --help for its options
    python -m benchmarks suite --quick        # the suite at CI size (a few minutes)

Layout:

* :mod:`benchmarks.registry` — every benchmark by name (one line each);
* :mod:`benchmarks.suite` — the suite of cases (:mod:`benchmarks.cases`, one module per case) with
  its recorder (:mod:`benchmarks.record`) and report (:mod:`benchmarks.report`);
* :mod:`benchmarks.common` — helpers shared by the benchmarks: the calls into diffship's fitting API,
  the NumPy/SciPy and CasADi peers, the timing harness;
* :mod:`benchmarks.timing` — diffship against CasADi on one fit: cold process, one fit, batches;
* :mod:`benchmarks.independent` — a NumPy-only generator of hidden-effect scenarios (no diffship
  inside: importing it never imports diffship);
* one module (or package) per other benchmark.

See ``benchmarks/README.md`` for what is measured and how, and ``benchmarks/results/README.md`` for
the results and the command that regenerates each.
"""
