"""Effects injected exactly into measured runs (the real HSVA zigzags of ``withheld_real`` and ``drift_truth``)."""

from __future__ import annotations

import numpy as np

from diffship.data import Run

__all__ = ["inject_current"]


def inject_current(run: Run, vx: float, vy: float, label: str = "water_drift") -> Run:
    """``run`` in basin water moving at ``(vx, vy)`` m/s (NED) from its first sample: positions + v_c·t,
    over-ground u, v + Rᵀ(ψ) v_c (exact: a uniform current leaves the hydrodynamics in the water frame
    unchanged); a new Run."""
    t = np.asarray(run.time, dtype=float)
    ch = {c: np.asarray(run[c], dtype=float).copy() for c in run.channels}
    tt = t - t[0]
    ch["x0"] = ch["x0"] + vx * tt
    ch["y0"] = ch["y0"] + vy * tt
    psi = ch["psi"]
    ch["u"] = ch["u"] + np.cos(psi) * vx + np.sin(psi) * vy
    ch["v"] = ch["v"] - np.sin(psi) * vx + np.cos(psi) * vy
    for c, v in (("x0dot", vx), ("y0dot", vy)):
        if c in ch:
            ch[c] = ch[c] + v
    return Run(run.name, t, ch, {**run.metadata, "injected": label})
