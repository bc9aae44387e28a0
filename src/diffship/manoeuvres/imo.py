r"""IMO manoeuvring metrics of a Run, measured or simulated.

**Metrics** (IMO Resolution MSC.137(76) "Standards for ship manoeuvrability" and
MSC/Circ.1053 "Explanatory notes"), all from a Run's ``time``, ``psi``, ``delta`` (and
``x0``, ``y0`` for the turning circle):

* *first execute*: the rudder order. In data it is the last sample before the rudder has
  moved half-way to its first order at which it had moved less than 10 % of that order;
  :math:`\psi_0` is the heading there.
* zigzag (:func:`zigzag_metrics`): with :math:`h = s(\psi - \psi_0)` (``s = ±1`` the side of
  the first rudder order) the *k-th execute* (k ≥ 2) is the first time ``h`` reaches
  ``±ψ_s`` (alternating sign), found with hysteresis between the two thresholds so that
  heading noise cannot trigger twice. The *k-th overshoot angle* (k ≥ 1) is the largest heading
  deviation beyond ``ψ_s`` between the (k+1)-th and the (k+2)-th execute: ``max h − ψ_s`` for
  odd k, ``−min h − ψ_s`` for even k. The *initial turning time* is the time from the first to
  the second execute, the *time to check yaw* the time from the second execute to the first
  heading extremum. The heading is smoothed with a centred moving average (``smooth_s``)
  before peaks are taken; an extremum at the end of the record is not reported.
* turning circle (:func:`turning_metrics`): with the midship track expressed in the frame
  of the approach course at the first execute, *advance* is the distance travelled along
  the original course until the heading has changed by 90°, *transfer* the distance
  travelled perpendicular to it at 90°, *tactical diameter* the perpendicular distance at
  180° (heading crossings interpolated linearly between samples), and the *steady turning
  diameter* the diameter of a least-squares circle through the track once the heading has
  changed by more than 270° (at least 180° of arc; NaN otherwise).
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from ..data import Run
from ..errors import DataError

__all__ = ["ZigzagMetrics", "TurningMetrics", "zigzag_metrics", "turning_metrics", "pullout_metrics", "imo_metrics",
           "first_execute", "check_turn_direction", "side_sign", "side_name", "rudder_release"]


def side_sign(side: str | float | int) -> float:
    """The one first-rudder-side convention: ``+1`` starboard, ``−1`` port.

    Accepts ``"starboard"``/``"port"`` (also ``"s"``/``"p"``, any case) and ``+1``/``−1``.
    """
    if isinstance(side, str):
        key = side.strip().lower()
        if key in ("starboard", "s", "stb", "+1", "1"):
            return 1.0
        if key in ("port", "p", "-1"):
            return -1.0
    elif isinstance(side, (int, float, np.integer, np.floating)) and float(side) in (1.0, -1.0):
        return float(side)
    raise DataError(f"first rudder side must be 'starboard' (+1) or 'port' (-1), got {side!r}")


def side_name(side: str | float | int) -> str:
    """``"starboard"`` or ``"port"`` for any accepted side (see :func:`side_sign`)."""
    return "starboard" if side_sign(side) > 0 else "port"


def _smooth(y: np.ndarray, dt: float, window_s: float) -> np.ndarray:
    k = int(round(window_s / dt))
    if k < 2:
        return y
    k += 1 - k % 2
    w = np.ones(k) / k
    pad = k // 2
    ypad = np.concatenate([np.full(pad, y[0]), y, np.full(pad, y[-1])])
    return np.convolve(ypad, w, mode="valid")


def first_execute(run: Run) -> tuple[int, float]:
    """Index of the first rudder execute and the side (+1 starboard, −1 port).

    The execute is the moment the rudder is *ordered* (IMO MSC/Circ.1053: advance and transfer
    are measured from it). A record holds the rudder angle, which follows the order at the
    steering gear's rate, so the order time is found by extrapolating the rudder's ramp — the
    line through its 10 % and 50 % crossings of the first rudder amplitude — back to the
    rudder's starting angle; the index is the sample nearest that time (never after the 10 %
    crossing). Taking the 10 % crossing itself puts the execute 1–1.5 s late at a helm rate of
    2.3°/s and shortens the advance by about 2 % (``benchmarks/results/coverage_metrics.md``).
    """
    run.require(("delta",), "finding the first rudder execute")
    d = np.asarray(run["delta"], dtype=np.float64)
    d = d - d[0]
    amp = float(np.max(np.abs(d)))
    if amp < math.radians(0.5):
        raise DataError(f"run '{run.name}': the rudder never moves by more than 0.5 deg; no manoeuvre to measure")
    half = int(np.argmax(np.abs(d) >= 0.5 * amp))
    side = float(np.sign(d[half]))
    small = np.nonzero(np.abs(d[: half + 1]) <= 0.1 * amp)[0]
    i10 = int(small[-1]) if small.size else 0
    t = np.asarray(run.time, dtype=np.float64)
    a, b = abs(d[i10]), abs(d[half])
    if half > i10 and b > a:
        t_order = t[i10] - a * (t[half] - t[i10]) / (b - a)
        i10 = min(i10, int(np.argmin(np.abs(t - t_order))))
    return i10, side


def check_turn_direction(run: Run, min_change_deg: float = 2.0) -> dict[str, Any] | None:
    """Does the heading turn the way the rudder says (starboard-positive δ turns to starboard)?

    From the first rudder execute to the first time the rudder is reversed or returned to
    neutral (or the end of the record), the heading change must have the sign of the first
    rudder order. Returns ``None`` where the record says nothing (rudder never moves, heading
    change below ``min_change_deg``), else ``{"agrees": bool, "heading_change_deg", "side",
    "text"}``.
    """
    if not run.has("delta", "psi"):
        return None
    try:
        i0, side = first_execute(run)
    except DataError:
        return None
    d = np.asarray(run["delta"], dtype=np.float64) - float(run["delta"][0])
    order = side * d
    peak = float(np.max(order[i0:]))
    later = np.nonzero(order[i0:] >= 0.5 * peak)[0]
    i_on = i0 + int(later[0]) if later.size else i0
    back = np.nonzero(order[i_on:] < 0.25 * peak)[0]
    i_end = i_on + int(back[0]) if back.size else run.n - 1
    psi = np.unwrap(np.asarray(run["psi"], dtype=np.float64))
    h = math.degrees(side * (psi[i_end] - psi[i0]))
    if abs(h) < min_change_deg:
        return None
    agrees = h > 0
    name = side_name(side)
    text = (f"first rudder order to {name} (δ {math.degrees(d[i_on]):+.1f}° at t = {run.time[i_on]:.1f} s, "
            f"starboard-positive) and the heading changes by {side * h:+.1f}° "
            f"({'to ' + name if agrees else 'the other way'}) before the rudder is reversed")
    return {"agrees": bool(agrees), "heading_change_deg": float(side * h), "side": name, "text": text}


def rudder_release(run: Run, i_start: int = 0, tol_deg: float = 0.5) -> int | None:
    """Index of the first sample after ``i_start`` at which the rudder has returned to within
    ``tol_deg`` of its value before the first execute (released), or ``None``.

    A turning-circle record that continues after the rudder is released (a pull-out, or the
    approach to the next test) must not enter the steady-diameter fit.
    """
    d = np.asarray(run["delta"], dtype=np.float64)
    base = float(d[0])
    order = np.abs(d - base)
    amp = float(np.max(order[i_start:])) if run.n > i_start else 0.0
    if amp < math.radians(2 * tol_deg):
        return None
    i_on = i_start + int(np.argmax(order[i_start:] >= 0.9 * amp))
    back = np.nonzero(order[i_on:] <= math.radians(tol_deg))[0]
    return i_on + int(back[0]) if back.size else None


def _crossing_time(t, h, i, level):
    """Linear interpolation of the time between samples i−1 and i where h crosses level."""
    if i == 0:
        return float(t[0])
    h0, h1 = h[i - 1], h[i]
    f = 0.0 if h1 == h0 else (level - h0) / (h1 - h0)
    return float(t[i - 1] + np.clip(f, 0.0, 1.0) * (t[i] - t[i - 1]))


@dataclasses.dataclass(frozen=True)
class ZigzagMetrics:
    """Zigzag metrics of one run (angles in degrees, times in seconds)."""

    run: str
    rudder_deg: float
    switch_deg: float
    first_rudder: str
    t_execute: float  #: first execute (rudder order)
    psi0_deg: float  #: heading at the first execute
    execute_times: tuple[float, ...]  #: 2nd, 3rd, ... executes (heading reaches ±ψ_s)
    overshoots_deg: tuple[float, ...]  #: 1st, 2nd, ... overshoot angles
    peak_times: tuple[float, ...]  #: times of the heading extrema
    initial_turning_time: float  #: first to second execute
    time_to_check: float  #: second execute to the first heading extremum

    @property
    def first_overshoot(self) -> float:
        return self.overshoots_deg[0] if self.overshoots_deg else math.nan

    @property
    def second_overshoot(self) -> float:
        return self.overshoots_deg[1] if len(self.overshoots_deg) > 1 else math.nan

    def as_dict(self) -> dict[str, Any]:
        return {**dataclasses.asdict(self), "first_overshoot": self.first_overshoot,
                "second_overshoot": self.second_overshoot}


def zigzag_metrics(run: Run, *, switch_deg: float | None = None, rudder_deg: float | None = None,
                   smooth_s: float = 1.0) -> ZigzagMetrics:
    """IMO zigzag metrics of a measured or simulated Run (definitions in the module docstring).

    ``switch_deg`` (heading change at which the rudder is reversed) defaults to the run's
    metadata ``switch_heading_deg``; ``rudder_deg`` to ``rudder_angle_deg`` or the largest
    rudder angle in the record. A switch angle must be positive (:class:`DataError` otherwise); a run whose
    heading never reaches it (no heading change) has no executes and NaN metrics.
    """
    run.require(("psi", "delta"), "zigzag metrics")
    switch_deg = switch_deg if switch_deg is not None else run.metadata.get("switch_heading_deg")
    if switch_deg is None:
        raise DataError(f"run '{run.name}': give switch_deg (the heading change at which the rudder is reversed); "
                        "it is not in the run's metadata")
    if rudder_deg is None:
        rudder_deg = run.metadata.get("rudder_angle_deg", float(np.degrees(np.max(np.abs(run["delta"])))))
    s = float(switch_deg)
    if not (math.isfinite(s) and s > 0):
        raise DataError(f"run '{run.name}': switch angle {s:g}° is not a zigzag's; give switch_deg > 0 (the heading "
                        "change at which the rudder is reversed)")
    t = np.asarray(run.time, dtype=np.float64)
    i0, side = first_execute(run)
    psi = _smooth(np.unwrap(np.asarray(run["psi"], dtype=np.float64)), run.dt, smooth_s)
    psi0 = float(psi[i0])
    h = np.degrees(side * (psi - psi0))
    executes, crossing_idx = [], []
    sign, i = 1.0, i0
    while i < len(h):  # hysteresis: look for +s, then −s, then +s, ...
        hit = np.nonzero(sign * h[i:] >= s)[0]
        if not hit.size:
            break
        i = i + int(hit[0])
        executes.append(_crossing_time(t, sign * h, i, s))
        crossing_idx.append(i)
        sign = -sign
        i += 1  # the next threshold is the other one (s > 0): never the same sample again
    overshoots, peaks = [], []
    for k, i_start in enumerate(crossing_idx):
        sgn = 1.0 if k % 2 == 0 else -1.0
        i_end = crossing_idx[k + 1] if k + 1 < len(crossing_idx) else len(h)
        seg = sgn * h[i_start:i_end]
        j = int(np.argmax(seg))
        if i_start + j >= len(h) - 1 or (k + 1 >= len(crossing_idx) and seg[-1] >= seg[j] - 0.05):
            break  # extremum not reached before the end of the record
        overshoots.append(float(seg[j] - s))
        peaks.append(float(t[i_start + j]))
    t_exec = float(t[i0])
    return ZigzagMetrics(
        run=run.name, rudder_deg=float(rudder_deg), switch_deg=s,
        first_rudder="starboard" if side > 0 else "port", t_execute=t_exec, psi0_deg=math.degrees(psi0),
        execute_times=tuple(executes), overshoots_deg=tuple(overshoots), peak_times=tuple(peaks),
        initial_turning_time=(executes[0] - t_exec) if executes else math.nan,
        time_to_check=(peaks[0] - executes[0]) if peaks else math.nan,
    )


@dataclasses.dataclass(frozen=True)
class TurningMetrics:
    """Turning-circle metrics of one run (lengths in metres, times in seconds)."""

    run: str
    first_rudder: str
    t_execute: float
    advance: float
    transfer: float
    tactical_diameter: float
    steady_diameter: float
    time_to_90: float
    time_to_180: float
    length: float | None = None  #: ship length used for the ``*_L`` values, if given

    def in_lengths(self) -> dict[str, float]:
        """Advance, transfer and diameters divided by the ship length."""
        if not self.length:
            raise DataError(f"run '{self.run}': pass length= to turning_metrics to get values in ship lengths")
        keys = ("advance", "transfer", "tactical_diameter", "steady_diameter")
        return {k: getattr(self, k) / self.length for k in keys}

    def as_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def _circle_fit(x: np.ndarray, y: np.ndarray) -> float:
    """Diameter of the algebraic (Kåsa) least-squares circle through the points."""
    A = np.stack([x, y, np.ones_like(x)], axis=1)
    b = x * x + y * y
    c, *_ = np.linalg.lstsq(A, b, rcond=None)
    xc, yc = c[0] / 2.0, c[1] / 2.0
    return float(2.0 * math.sqrt(c[2] + xc * xc + yc * yc))


def turning_metrics(run: Run, *, length: float | None = None, smooth_s: float = 0.0, t_end: float | None = None,
                    detect_release: bool = True) -> TurningMetrics:
    """IMO turning-circle metrics of a Run with ``time, x0, y0, psi, delta`` (see module docstring).

    Only the record up to ``t_end`` [s] is used; by default (``detect_release``) also only up to
    the rudder's return to neutral (:func:`rudder_release`), so a record that goes on after the
    rudder is released still gives the steady diameter of the turn.
    """
    run.require(("x0", "y0", "psi", "delta"), "turning-circle metrics")
    stop = None
    if t_end is not None:
        stop = float(t_end)
    if detect_release:
        i_rel = rudder_release(run, first_execute(run)[0])
        if i_rel is not None:
            stop = float(run.time[i_rel]) if stop is None else min(stop, float(run.time[i_rel]))
    if stop is not None:
        if stop <= run.t0 + 2 * run.dt:
            raise DataError(f"run '{run.name}': t_end = {stop:g} s leaves no turning-circle record")
        run = run.slice(None, stop)
    t = np.asarray(run.time, dtype=np.float64)
    i0, side = first_execute(run)
    psi = _smooth(np.unwrap(np.asarray(run["psi"], dtype=np.float64)), run.dt, smooth_s)
    psi0 = float(psi[i0])
    h = np.degrees(side * (psi - psi0))
    dx, dy = run["x0"] - run["x0"][i0], run["y0"] - run["y0"][i0]
    along = math.cos(psi0) * dx + math.sin(psi0) * dy
    across = side * (-math.sin(psi0) * dx + math.cos(psi0) * dy)

    def at(level):
        hit = np.nonzero(h[i0:] >= level)[0]
        if not hit.size:
            return math.nan, math.nan, math.nan
        i = i0 + int(hit[0])
        tc = _crossing_time(t, h, i, level)
        return tc, float(np.interp(tc, t, along)), float(np.interp(tc, t, across))

    t90, adv, trans = at(90.0)
    t180, _, tact = at(180.0)
    sel = h >= 270.0
    steady = math.nan
    if np.any(sel) and h[sel].max() - 270.0 >= 180.0:
        steady = _circle_fit(np.asarray(dx)[sel], np.asarray(dy)[sel])
    t_exec = float(t[i0])
    return TurningMetrics(run=run.name, first_rudder="starboard" if side > 0 else "port", t_execute=t_exec,
                          advance=adv, transfer=trans, tactical_diameter=tact, steady_diameter=steady,
                          time_to_90=t90 - t_exec, time_to_180=t180 - t_exec, length=length)


def pullout_metrics(run: Run, *, t_release: float | None = None, average_s: float = 10.0) -> dict[str, float]:
    """Pull-out: yaw rate just before the rudder returns to zero and the residual rate at the end [rad/s].

    A residual rate that does not decay towards zero (and has the sign of the turn) indicates
    a directionally unstable ship (MSC/Circ.1053).
    """
    run.require(("r",), "pull-out metrics")
    t_release = t_release if t_release is not None else run.metadata.get("t_release")
    if t_release is None:
        raise DataError(f"run '{run.name}': give t_release (time the rudder is returned to zero)")
    t, r = run.time, run["r"]
    before = (t >= t_release - average_s) & (t < t_release)
    end = t >= t[-1] - average_s
    return {"r_turn": float(np.mean(r[before])), "r_residual": float(np.mean(r[end]))}


def imo_metrics(run: Run, kind: str | None = None, **kw) -> ZigzagMetrics | TurningMetrics | dict[str, float]:
    """Metrics of a Run by manoeuvre kind (``"zigzag"``, ``"turning_circle"``, ``"pull_out"``);
    the kind defaults to the run's metadata ``manoeuvre``."""
    kind = kind or run.metadata.get("manoeuvre")
    if kind == "zigzag":
        return zigzag_metrics(run, **kw)
    if kind == "turning_circle":
        return turning_metrics(run, **kw)
    if kind == "pull_out":
        return pullout_metrics(run, **kw)
    raise DataError(f"run '{run.name}': unknown manoeuvre kind {kind!r}; pass kind='zigzag', 'turning_circle' "
                    "or 'pull_out'")
