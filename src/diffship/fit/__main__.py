"""``python -m diffship.fit``: fit a model to runs by equation error and output error.

The checks that need no JAX run first (:func:`diffship.fit.args.precheck`): a fit that cannot start
for want of the vessel's particulars stops in a fraction of a second, before JAX is imported.
"""

import sys

from .args import precheck

if __name__ == "__main__":
    problem = precheck(sys.argv[1:])
    if problem is not None:
        print(f"error: {problem}", file=sys.stderr)
        sys.exit(2)
    from ..cli_options import exit_now
    from .cli import main

    exit_now(main())
