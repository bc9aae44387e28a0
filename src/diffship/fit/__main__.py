"""``python -m diffship.fit``: fit a model to runs by equation error and output error."""

import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())
