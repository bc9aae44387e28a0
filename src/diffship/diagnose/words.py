r"""Where the model misses, in a naval architect's words.

:mod:`.where` measures the validation error per channel, phase, region and run in noise-floor
units; this module says it in the terms a manoeuvring report uses:

* **Channels first by what a naval architect reads** — heading [°], yaw rate [°/s], speed
  [m/s and % of the mean speed U], sway velocity (drift), then the track [m, and ship lengths
  where the model has ``Lpp``] — each with its RMS error, its ratio to the noise floor and what
  the error *is*: for heading, yaw rate and sway the **swing ratio** (standard deviation of the
  simulated signal over the measured one, about its mean: < 1 the model turns too little), for
  speed the **mean speed error** (> 0: the model keeps too much speed, i.e. under-predicts the
  speed loss in turns).
* **Zigzag overshoots** (:func:`overshoots`): for runs whose steering input is a zigzag (two or
  more reversals between steady ± levels), the overshoot angle after each check — the heading
  change from the moment the rudder is reversed to the extreme heading before the swing turns
  (ITTC 7.5-04-02-01) — measured and simulated with the measured rudder. Open loop, so the
  checks happen at the measured times for both.
* **Phases** by their manoeuvring names (:data:`PHASE_WORDS`) and the worst **operating region**
  (speed, drift angle, yaw rate, rudder angle quartile) with its range in user units.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

__all__ = ["PHASE_WORDS", "overshoots", "channel_words", "region_words", "where_in_words", "ORDER"]

#: The manoeuvre phases of :func:`~.where.phases` in a manoeuvring report's words.
PHASE_WORDS = {
    "approach": "on the approach (before the first rudder order)",
    "transient": "while the rudder moves (execute and check)",
    "steady_turn": "in the turn with the rudder held",
    "counter_steer": "while checking the swing (rudder against the yaw)",
    "straight": "running straight (rudder near amidships)",
}

#: Channel order of the summary: what a naval architect reads first.
ORDER = ("psi", "r", "u", "v", "x0", "y0")
NAMES = {"psi": "heading", "r": "yaw rate", "u": "surge speed", "v": "sway velocity", "x0": "track north (x)",
         "y0": "track east (y)"}
REGION_NAMES = {"U": ("speed", "m/s", 1.0), "abs_beta": ("drift angle", "°", 180 / math.pi),
                "abs_r": ("yaw rate", "°/s", 180 / math.pi), "abs_steer": ("steering input", "", 1.0)}
DEG = 180.0 / math.pi


def _unwrap(y: np.ndarray) -> np.ndarray:
    return np.unwrap(np.asarray(y, dtype=float))


def reversals(s: np.ndarray) -> list[int]:
    """Sample indices where a zigzag steering input ``s`` is reversed (the checks): the last zero
    crossing (of ``s`` minus its approach level) before the input reaches half its amplitude on the
    other side. Empty unless the input spends at least half the time near ± its amplitude (a zigzag)."""
    s = np.asarray(s, dtype=float)
    s = s - np.median(s[: max(3, s.size // 50)])
    amp = float(np.max(np.abs(s)))
    if amp <= 0 or np.mean(np.abs(s) > 0.8 * amp) < 0.5:
        return []
    state, out, last_zero = 0, [], 0
    for k in range(1, s.size):
        if np.sign(s[k]) != np.sign(s[k - 1]):
            last_zero = k
        if abs(s[k]) > 0.5 * amp:
            new = int(np.sign(s[k]))
            if state and new != state:
                out.append(last_zero)
            state = new
    return out


def overshoots(t: np.ndarray, s: np.ndarray, psi: np.ndarray, n: int = 2) -> list[float]:
    """The first ``n`` overshoot angles [rad] of a zigzag: after each check k, the largest heading
    change beyond ψ(t_k) in the direction the ship was swinging, before the next check."""
    ks = reversals(s)
    psi = _unwrap(psi)
    out = []
    for i, k in enumerate(ks[:n]):
        end = ks[i + 1] if i + 1 < len(ks) else psi.size
        if end - k < 3:
            break
        d = psi[k:end] - psi[k]
        swing = np.sign(psi[k] - psi[max(k - 5, 0)]) or 1.0
        out.append(float(max(np.max(swing * d), 0.0)))
    return out


def _swing_ratio(sim: np.ndarray, meas: np.ndarray) -> float:
    m = float(np.std(meas))
    return float(np.std(sim) / m) if m > 0 else float("nan")


def channel_words(runs: Sequence, simulated: dict, rmse: dict[str, float], floor: dict[str, float],
                  angles=("psi",), lpp: float | None = None) -> list[dict]:
    """Per channel (in :data:`ORDER`): RMS error in user units, ratio to the floor, and what the
    error is (swing ratio, mean speed error). ``simulated``: run name → channel → array."""
    out = []
    U = [np.hypot(np.asarray(r["u"]), np.asarray(r["v"]) if r.has("v") else 0.0) for r in runs if r.has("u")]
    U_mean = float(np.mean(np.concatenate(U))) if U else float("nan")
    for c in [c for c in ORDER if c in rmse] + [c for c in rmse if c not in ORDER]:
        meas = [(_unwrap(r[c]) if c in angles else np.asarray(r[c], float)) for r in runs]
        sim = [(_unwrap(simulated[r.name][c]) if c in angles else np.asarray(simulated[r.name][c], float)) for r in runs]
        k, unit = (DEG, "°") if c == "psi" else (DEG, "°/s") if c == "r" else (1.0, "m/s") if c in ("u", "v") else \
            (1.0, "m") if c in ("x0", "y0") else (1.0, "")
        w = {"channel": c, "name": NAMES.get(c, c), "rmse": float(rmse[c] * k), "unit": unit,
             "ratio_to_floor": float(rmse[c] / floor[c]) if floor.get(c) else float("nan")}
        if c in ("psi", "r", "v"):
            # swing about each run's own mean (a heading's mean is the course)
            w["swing_ratio"] = float(np.mean([_swing_ratio(s - s.mean(), m - m.mean()) for s, m in zip(sim, meas)]))
        if c == "u":
            w["mean_error"] = float(np.mean(np.concatenate([s - m for s, m in zip(sim, meas)])))
            w["percent_of_U"] = float(100 * rmse[c] / U_mean) if U_mean > 0 else float("nan")
        if c in ("x0", "y0") and lpp:
            w["ship_lengths"] = float(rmse[c] / lpp)
        out.append(w)
    return out


def _phrase(w: dict) -> str:
    p = f"{w['name']} {w['rmse']:.3g} {w['unit']} RMS ({w['ratio_to_floor']:.3g}× its floor"
    if "swing_ratio" in w and math.isfinite(w["swing_ratio"]):
        sr = w["swing_ratio"]
        p += f"; the model's swings are {100 * sr:.0f} % of the measured" + (
            " — it turns too little" if sr < 0.95 and w["channel"] in ("psi", "r") else
            " — it turns too much" if sr > 1.05 and w["channel"] in ("psi", "r") else "")
    if "mean_error" in w:
        me = w["mean_error"]
        p += f", {w['percent_of_U']:.2g} % of U; mean {me:+.2g} m/s" + (
            ": the model keeps too much speed (under-predicts the speed loss)" if me > 0.5 * w["rmse"] else
            ": the model loses too much speed" if me < -0.5 * w["rmse"] else "")
    if "ship_lengths" in w:
        p += f", {w['ship_lengths']:.2g} L"
    return p + ")"


def region_words(per_region: dict) -> str:
    """The worst quartile bin of speed, drift angle and yaw rate, in user units."""
    best = None
    for key, bins in per_region.items():
        if key not in REGION_NAMES or key == "abs_steer" or not bins:
            continue
        b = max(bins, key=lambda b: b["E"])
        spread = max(x["E"] for x in bins) / max(min(x["E"] for x in bins), 1e-300)
        if best is None or spread > best[0]:
            best = (spread, key, b)
    if best is None:
        return ""
    _, key, b = best
    name, unit, k = REGION_NAMES[key]
    return f"worst at {name} {k * b['low']:.3g}–{k * b['high']:.3g} {unit}".rstrip()


def where_in_words(words: list[dict], zigzag: dict, per_phase: dict, per_region: dict,
                   periodic: dict | None = None) -> str:
    """One sentence: channels (heading, rate, speed first), overshoots, worst phase and region, and
    a periodic residual the rudder does not drive (:mod:`.periodic`)."""
    parts = [_phrase(w) for w in words]
    s = "; ".join(parts)
    os_ = [(k, v) for k, v in zigzag.items() if v.get("measured")]
    if os_:
        m = np.array([v["measured"][:2] + [np.nan] * (2 - len(v["measured"][:2])) for _, v in os_], dtype=float)
        p = np.array([v["model"][:2] + [np.nan] * (2 - len(v["model"][:2])) for _, v in os_], dtype=float)
        lab = ("first", "second")
        bits = [f"{lab[i]} overshoot {np.nanmean(m[:, i]):.3g}° measured, {np.nanmean(p[:, i]):.3g}° by the model"
                for i in range(2) if np.any(np.isfinite(m[:, i]) & np.isfinite(p[:, i]))]
        if bits:
            s += "; zigzag " + ", ".join(bits) + f" (mean of {len(os_)} run(s))"
    if per_phase:
        worst = max(per_phase, key=lambda q: per_phase[q]["E"])
        s += f"; worst {PHASE_WORDS.get(worst, worst)}"
    reg = region_words(per_region)
    if reg:
        s += f", {reg}"
    if periodic:
        s += (f"; a periodic residual at {periodic['period_s']:.3g} s in {', '.join(periodic['channels'])}, not driven "
              "by the steering (a wave-like disturbance?)")
    return s
