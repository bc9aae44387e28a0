"""``python -m benchmarks [--quick] [--cases ...] [--report-only] [--out DIR]``: run the suite."""

import sys

from benchmarks.suite import main

sys.exit(main())
