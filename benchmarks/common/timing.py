"""The timing harness every benchmark shares.

Machine load, medians with their range, whole-process wall clocks (``subprocess``, start to
exit), relative differences, the measured commit and the environment line of a report, and the
time-bounded scipy peer (MINPACK LM with 2-point finite differences over the NumPy RK4 of
``peers.Fossen3Problem``, stopped by a wall-clock guard with the best cost seen). Tolerances of
every MINPACK peer: ``casadi_peer.TOL``.
"""

from __future__ import annotations

import math
import os
import platform
import statistics
import subprocess
import time
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

ROOT = Path(__file__).resolve().parents[2]


def loadavg() -> str:
    """The 1-, 5- and 15-minute load averages, as text."""
    a, b, c = os.getloadavg()
    return f"{a:.2f} {b:.2f} {c:.2f}"


def commit() -> str:
    """The short commit of the checkout being measured (``"unknown"`` outside git)."""
    try:
        return subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def cpu_name() -> str:
    """The processor's model name (``/proc/cpuinfo``), else the machine type."""
    try:
        return next(ln.split(":", 1)[1].strip() for ln in open("/proc/cpuinfo") if ln.startswith("model name"))
    except (OSError, StopIteration):
        return platform.machine()


def med(xs):
    return statistics.median(xs) if xs else math.nan


def fmt(xs, digits=2):
    """median, with (min–max) when there are several."""
    if not xs:
        return "–"
    if len(xs) == 1:
        return f"{xs[0]:.{digits}f}"
    return f"{med(xs):.{digits}f} ({min(xs):.{digits}f}–{max(xs):.{digits}f})"


def rel(a, b):
    return abs(a - b) / max(abs(b), 1e-300)


def max_rel_params(p, q, names):
    return max(rel(p[n], q[n]) for n in names)


def timed_process(cmd, env, cwd):
    t = time.perf_counter()
    proc = subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True)
    wall = time.perf_counter() - t
    if proc.returncode not in (0, 1):
        raise RuntimeError(f"{' '.join(map(str, cmd[:4]))} ... failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
    return wall


class _TimeUp(Exception):
    pass


def scipy_fd(prob, z0, guard_s):
    """scipy least_squares lm (MINPACK, 2-point differences) over the NumPy RK4, wall-clock guard."""
    from benchmarks.common.casadi_peer import TOL  # the tolerances of every MINPACK peer (imports casadi)

    best = {"cost": math.inf, "z": np.array(z0, dtype=np.float64)}
    calls = [0]
    t0 = time.perf_counter()

    def fun(z):
        if time.perf_counter() - t0 > guard_s:
            raise _TimeUp
        r = prob.residuals(z)
        calls[0] += 1
        c = 0.5 * float(r @ r)
        if c < best["cost"]:
            best.update(cost=c, z=np.array(z, copy=True))
        return r

    try:
        res = least_squares(fun, np.asarray(z0, dtype=np.float64), method="lm", **TOL)
        out = dict(z=res.x, cost=float(res.cost), finished=res.status > 0, status=res.message)
    except _TimeUp:
        out = dict(z=best["z"], cost=best["cost"], finished=False,
                   status=f"stopped by the {guard_s:.0f} s guard (best cost seen)")
    out.update(wall=time.perf_counter() - t0, calls=calls[0])
    return out


def ratio(a, b):
    """a / b (NaN when b is not positive)."""
    return a / b if b > 0 else math.nan
