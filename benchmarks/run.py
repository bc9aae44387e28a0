"""The benchmark suite's historical command, kept as a thin shim over :func:`benchmarks.suite.main`.

    PYTHONPATH=src .venv/bin/python benchmarks/run.py [--quick] [--cases nomoto,fossen3] [--report-only] [--out DIR]

is the same as ``python -m benchmarks ...``. See ``benchmarks/__init__.py`` for the layout.
"""

import sys
from pathlib import Path

if __name__ == "__main__":
    sys.path[0] = str(Path(__file__).resolve().parents[1])  # run as a script: import `benchmarks` from the repo root
    from benchmarks.suite import main

    sys.exit(main())
