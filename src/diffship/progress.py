"""Progress of long computations: a heartbeat while a compiled program runs.

A Levenberg–Marquardt solve is one compiled XLA program: from the host it is a single call that
can take minutes on long runs (an MMG fit of four 20 Hz zigzags). :func:`heartbeat` runs a
background thread that reports the elapsed time every ``every`` seconds while the call runs (XLA
releases the interpreter, so the thread gets its turn), and :func:`per_start` reports each start
of a multi-start solve as it finishes, with its steps, cost and time per step. Neither touches the
compiled program: the numbers a fit reaches are the same with and without progress, and the
programs stay exportable between processes (:mod:`diffship.compiled`: no host callbacks inside).
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Iterator

__all__ = ["heartbeat", "per_start"]


@contextlib.contextmanager
def heartbeat(say: Callable[[str], None] | None, label: str, every: float = 10.0) -> Iterator[None]:
    """Within the block, ``say(f"{label}: still running, {t:.0f} s")`` every ``every`` seconds."""
    if say is None or every <= 0:
        yield
        return
    stop = threading.Event()
    t0 = time.perf_counter()

    def beat():
        while not stop.wait(every):
            say(f"{label}: still running, {time.perf_counter() - t0:.0f} s")
    thread = threading.Thread(target=beat, daemon=True, name="diffship-heartbeat")
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()


def per_start(say: Callable[[str], None] | None, label: str, n: int) -> Callable[[int, int, float, float], None]:
    """``done(i, steps, cost, seconds)``: reports start ``i`` (of ``n``) as finished."""
    count = [0]
    lock = threading.Lock()

    def done(i: int, steps: int, cost: float, seconds: float) -> None:
        if say is None:
            return
        with lock:
            count[0] += 1
            k = count[0]
        per = f", {1000 * seconds / steps:.0f} ms/step" if steps else ""
        say(f"{label}: start {i + 1} done ({k}/{n}): {steps} steps, cost {cost:.6g}, {seconds:.1f} s{per}")
    return done
