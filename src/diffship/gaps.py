"""Gaps in a run's time stamps: stretches where samples are missing. NumPy only; :class:`diffship.data.Run`
calls :func:`check_gaps` on construction.

The rule: a step between consecutive time stamps longer than :data:`GAP_FACTOR` (5) times the run's median
step **and** longer than :data:`GAP_MIN_S` (1 s) is a gap. The fits simulate a run from its first sample to
its last with the inputs interpolated between samples: across a gap the interpolated rudder is not the one
the ship had, the simulation leaves the gap elsewhere than the ship did, and the fit bends its parameters to
make up for it. The factor is the one the log reader splits at (:mod:`diffship.logs.assemble`); it leaves
clock jitter alone (a 10 Hz log whose steps wander up to 0.3 s, a 1 Hz log with a missed fix or two). The
floor of 1 s keeps fast logs (50 Hz: 5 × 0.02 s = 0.1 s) from stopping at a few dropped samples, which
interpolation bridges well within a ship's time constants; a 1 Hz log stops at steps over 5 s.
"""

from __future__ import annotations

import numpy as np

from .errors import DataError

__all__ = ["GAP_FACTOR", "GAP_MIN_S", "check_gaps"]

#: A step over this many median steps (and over :data:`GAP_MIN_S`) is a gap.
GAP_FACTOR = 5.0
#: [s] steps up to this long are never gaps, whatever the sample rate.
GAP_MIN_S = 1.0


def check_gaps(where: str, time: np.ndarray) -> None:
    """Stop at the first gap in increasing time stamps ``time`` [s] (module docstring), naming where it is,
    how long it is, and the fix: split the run there into two runs."""
    d = np.diff(time)
    dt = float(np.median(d))
    big = np.flatnonzero(d > max(GAP_FACTOR * dt, GAP_MIN_S))
    if not big.size:
        return
    i = int(big[0])
    more = f"; {big.size} gaps in all, the longest {float(d[big].max()):.3g} s" if big.size > 1 else ""
    raise DataError(f"{where}: no samples for {d[i]:.3g} s between t={time[i]:.6g} s and t={time[i + 1]:.6g} s "
                    f"(rows {i} and {i + 1}; median step {dt:.3g} s{more}); a step over {GAP_FACTOR:g} median steps "
                    f"and over {GAP_MIN_S:g} s is a gap the fit cannot bridge: split the run there into two runs "
                    f"(rows up to {i} in one file, from row {i + 1} in another) and load both.")
