"""``python -m benchmarks [NAME [ARGS ...]]``: run one benchmark; without NAME, list them."""

import importlib
import sys

from benchmarks.registry import BENCHMARKS


def main(argv: list[str]) -> int:
    if not argv or argv[0] in ("-h", "--help", "list"):
        width = max(map(len, BENCHMARKS))
        print("python -m benchmarks NAME [ARGS ...]  (NAME --help for its options)\n")
        print("\n".join(f"  {n:<{width}}  {what}" for n, (_, what) in BENCHMARKS.items()))
        return 0
    if argv[0] not in BENCHMARKS:
        print(f"error: no benchmark {argv[0]!r}; choose from {', '.join(BENCHMARKS)}", file=sys.stderr)
        return 2
    sys.argv[0] = f"python -m benchmarks {argv[0]}"  # what argparse's usage lines name
    return importlib.import_module(BENCHMARKS[argv[0]][0]).main(argv[1:]) or 0


sys.exit(main(sys.argv[1:]))
