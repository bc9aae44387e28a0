"""Unit checks of a run's columns, before anything is computed: degrees passed as radians, radians declared as
degrees, and time stamps in milliseconds or microseconds (or stated in too small a unit), every problem of a run
in one :class:`UnitsError` (which :func:`diffship.data.load_runs` joins over files, so one message names every
file and column).
NumPy only; :class:`diffship.data.Run` calls :func:`check_units` on construction.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from .errors import DataError

__all__ = ["MAX_LOG_RATE_HZ", "TIME_UNITS", "UnitsError", "check_units", "psi_unwrap"]


def psi_unwrap(psi: np.ndarray) -> tuple[np.ndarray, bool]:
    """Unwrap a heading; a jump of ~360 marks degree data (returns ``(unwrapped, in_degrees)``)."""
    jumps = np.abs(np.diff(psi))
    in_degrees = bool(np.any((jumps > 300.0) & (jumps < 360.5)))
    return np.unwrap(psi, period=360.0 if in_degrees else 2 * np.pi), in_degrees


class UnitsError(DataError):
    """Unit problems of one run: ``columns`` to declare in degrees, ``time_unit`` the time stamps
    seem to be in (``"ms"``, ``"us"``) or ``None``, ``drop_degrees`` columns declared in degrees that are radians
    already; ``detail`` the problems without the fix, so :func:`load_runs` joins those of every file under one fix."""

    def __init__(self, message: str, columns: Sequence[str] = (), time_unit: str | None = None,
                 drop_degrees: Sequence[str] = (), detail: str | None = None) -> None:
        super().__init__(message)
        self.columns = tuple(columns)
        self.time_unit = time_unit
        self.drop_degrees = tuple(drop_degrees)
        self.detail = message if detail is None else detail


#: Time units ``Run.from_dataframe(time_unit=...)`` / ``--time-unit`` converts to seconds.
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6}


#: The fastest sampling taken for a ship's log [Hz]: time stamps stated in ms or µs that give a faster one are in a
#: larger unit (seconds given as ms read a 50 Hz log as 50 kHz).
MAX_LOG_RATE_HZ = 1000.0
_UNIT_WORDS = {"s": "seconds", "ms": "milliseconds", "us": "microseconds", "µs": "microseconds"}


def _stated_unit_problem(time: np.ndarray, time_unit: str) -> tuple[str, str] | None:
    """``(unit, words)`` when the time stamps, converted from the stated ``time_unit`` (ms, µs), are sampled
    faster than :data:`MAX_LOG_RATE_HZ`: ``unit`` the next larger one that gives that rate or slower (else s)."""
    if TIME_UNITS.get(time_unit, 1.0) >= 1.0 or time.size < 2:
        return None
    dt = float(np.median(np.diff(time)))
    if not (dt > 0 and dt * MAX_LOG_RATE_HZ < 1.0):
        return None
    step = dt / TIME_UNITS[time_unit]  # in the column's own numbers
    unit = next((u for u in ("ms", "s") if TIME_UNITS[u] > TIME_UNITS[time_unit]
                 and step * TIME_UNITS[u] * MAX_LOG_RATE_HZ >= 1.0), "s")
    return unit, (f"read as {_UNIT_WORDS[time_unit]} (time unit {time_unit}), the time stamps' median step "
                  f"{step:.6g} is {dt:.3g} s, a sampling rate of {1.0 / dt:.6g} Hz; a ship's log is sampled at "
                  f"{MAX_LOG_RATE_HZ:g} Hz or slower, so the time column looks like {_UNIT_WORDS[unit]}")


def _rate_ratios(time: np.ndarray, ch: Mapping[str, np.ndarray]) -> list[tuple[float, str, str]]:
    """``(ratio, what, against)`` for each rate the channels carry twice: the heading's rate against the measured
    yaw rate r (when r varies and the two correlate, |ρ| > 0.7) and the track's speed against the surge speed u
    (when the ship moves). Both are 1 when the time stamps were read in their own unit; stamps in a unit 1000 times
    smaller than the one they were read as (ms read as s) scale every rate by 10⁻³, in a unit 1000 times larger
    (s read as ms) by 10³."""
    ratios = []
    if "psi" in ch and "r" in ch and np.std(ch["r"]) > 1e-3:
        g = np.gradient(np.unwrap(ch["psi"]), time)
        r = ch["r"]
        if np.std(g) > 0 and abs(np.corrcoef(g, r)[0, 1]) > 0.7:
            ratios.append((abs(float(g @ r / (r @ r))), "the heading's rate", "the measured yaw rate r"))
    if "x0" in ch and "y0" in ch and "u" in ch and np.mean(np.abs(ch["u"])) > 1e-2:
        sog = np.hypot(np.gradient(ch["x0"], time), np.gradient(ch["y0"], time))
        ratios.append((float(np.median(sog)) / float(np.mean(np.abs(ch["u"]))), "the track's speed (x0, y0)",
                       "the surge speed u"))
    return ratios


def _stated_unit_by_rates(time: np.ndarray, ch: Mapping[str, np.ndarray], time_unit: str) -> tuple[str, str] | None:
    """``(unit, words)`` when time stamps stated in ms or µs make the rates 10³ or 10⁶ times what the measured
    ones give (:func:`_rate_ratios`, the windows of :func:`_time_unit_problem` mirrored): the stamps are that many
    times too close, so the column is in the larger unit (seconds stated as ms read a 1 Hz log as 1000 Hz, at
    :data:`MAX_LOG_RATE_HZ`, which :func:`_stated_unit_problem` lets pass)."""
    scale = TIME_UNITS.get(time_unit, 1.0)
    if scale >= 1.0 or time.size < 2:
        return None
    for ratio, what, against in _rate_ratios(time, ch):
        for factor, low, high in ((1e3, 3e-4, 3e-3), (1e6, 3e-7, 3e-6)):
            unit = next((u for u in ("ms", "s") if np.isclose(TIME_UNITS[u], scale * factor)), None)
            if unit is not None and ratio > 0 and low < 1.0 / ratio < high:
                return unit, (f"read as {_UNIT_WORDS[time_unit]} (time unit {time_unit}), {what} is {ratio:.4g} "
                              f"times {against}: the time stamps are {factor:g} times too close, so the time "
                              f"column looks like {_UNIT_WORDS[unit]}")
    return None


def _time_unit_problem(time: np.ndarray, ch: Mapping[str, np.ndarray]) -> str | None:
    """``"ms"`` or ``"us"`` when the time stamps look like milliseconds or microseconds: the heading's
    rate against the measured yaw rate (or the track's speed against the measured surge speed) is
    10⁻³ or 10⁻⁶ of what seconds give; without those channels, a median step of 5 or more "seconds"
    (a 200 Hz to 0.2 Hz log in ms) on whole numbers."""
    dt = float(np.median(np.diff(time)))
    ratios = [ratio for ratio, _, _ in _rate_ratios(time, ch)]
    for ratio in ratios:
        if 3e-4 < ratio < 3e-3:
            return "ms"
        if 3e-7 < ratio < 3e-6:
            return "us"
    if ratios:
        return None
    whole = bool(np.all(np.abs(time - np.round(time)) < 1e-9))
    if dt >= 5000.0 and whole:
        return "us"
    if dt >= 5.0 and whole:
        return "ms"
    return None


#: Steering angles (rudder, water-jet nozzle): at most a few tens of degrees.
_RUDDERS = ("delta", "nozzle", "delta_n")
#: A rudder declared in degrees whose largest |value| stays under 1° [rad] while the heading turns through more
#: than 10° [rad] was in radians already: a ship does not turn through 10° on a rudder held under 1°.
_RUDDER_TINY, _TURNED = float(np.radians(1.0)), float(np.radians(10.0))


def _radians_declared_degrees(ch: Mapping[str, np.ndarray], degrees: Sequence[str]) -> list[tuple[str, str]]:
    """``(channel, what)`` for each rudder-like channel converted from degrees (``degrees``) that is at most
    1° (and not all zero) while the heading, unwrapped, turns through more than 10°: a 35° zigzag logged in
    radians and declared degrees is a rudder of 0.61° that a fit answers with an absurd gain, so it is named."""
    if "psi" not in ch:
        return []
    turned = float(np.ptp(psi_unwrap(ch["psi"])[0]))
    out = []
    for c in _RUDDERS:
        top = float(np.max(np.abs(ch[c]))) if c in ch and c in degrees else 0.0
        if 0.0 < top < _RUDDER_TINY and turned > _TURNED:
            deg = float(np.degrees(top))  # the largest |value| in the source's numbers
            out.append((c, f"the ship turned through {np.degrees(turned):.3g}° with '{c}' at most {deg:.3g}° "
                           f"(read as degrees): column '{c}' looks like radians already ({deg:.3g} rad is "
                           f"{np.degrees(deg):.3g}°)"))
    return out


def check_units(where: str, time: np.ndarray, ch: Mapping[str, np.ndarray], time_unit: str = "s",
                degrees: Sequence[str] = ()) -> None:
    """Conservative heuristics that catch degrees passed as radians, time stamps in ms or µs, time stamps
    stated in a unit too small (``time_unit``, the unit they were converted from: seconds stated as ms, by the
    sampling rate or by the rates), and rudder channels in radians declared in degrees (``degrees``, the
    channels converted from degrees); every problem of the run in one error (:class:`UnitsError`)."""
    problems: list[tuple[str, str]] = []  # (channel, what)
    stated = _stated_unit_problem(time, time_unit) or _stated_unit_by_rates(time, ch, time_unit)
    tunit = stated[0] if stated is not None else _time_unit_problem(time, ch)
    if stated is not None:
        problems.append(("time", stated[1]))
    elif tunit is not None:
        dt = float(np.median(np.diff(time)))
        problems.append(("time", f"the time stamps look like {'milliseconds' if tunit == 'ms' else 'microseconds'} "
                                 f"(median step {dt:.6g}; heading rate against yaw rate, or track against speed, "
                                 f"off by {'1000' if tunit == 'ms' else '10⁶'})"))
    for c, limit, unit in (("delta", 1.0, "rad"), ("nozzle", 1.0, "rad"),
                           ("r", 3.0, "rad/s"), ("p", 3.0, "rad/s"), ("q", 3.0, "rad/s")):
        if c in ch and np.max(np.abs(ch[c])) > limit:
            i = int(np.argmax(np.abs(ch[c])))
            problems.append((c, f"column '{c}' looks like degrees (|value| up to {abs(ch[c][i]):.4g} at row {i}, "
                                f"more than {limit} {unit})"))
    if "psi" in ch:
        psi = ch["psi"]
        unwrapped, wraps_at_360 = psi_unwrap(psi)
        big = np.max(np.abs(psi)) > 2 * np.pi + 0.5
        looks_0_360 = psi.min() >= -0.5 and psi.max() <= 360.5 and psi.max() > 7.0
        if big and (wraps_at_360 or (looks_0_360 and abs(psi[0]) > 2 * np.pi + 0.5)):
            problems.append(("psi", f"column 'psi' looks like degrees (values from {psi.min():.4g} "
                                    f"to {psi.max():.4g})"))
        elif "r" in ch and np.std(ch["r"]) > 1e-4 and not any(c == "r" for c, _ in problems):
            r = ch["r"]
            g = np.gradient(unwrapped, time)
            if np.std(g) > 0 and np.corrcoef(g, r)[0, 1] > 0.7:
                slope = float(g @ r / (r @ r))
                if 30.0 < slope < 100.0:
                    problems.append(("psi", f"column 'psi' looks like degrees while 'r' is in rad/s "
                                            f"(d psi/dt = {slope:.3g} r)"))
                if 0.01 < slope < 0.03:
                    problems.append(("r", f"column 'r' looks like deg/s while 'psi' is in rad "
                                          f"(d psi/dt = {slope:.3g} r, about 1/57.3)"))
    drops = [] if any(c == "psi" for c, _ in problems) else _radians_declared_degrees(ch, degrees)
    if problems or drops:
        degs = list(dict.fromkeys(c for c, _ in problems if c != "time"))
        fixes = []
        if degs:
            fixes.append(f"degrees=[{', '.join(repr(c) for c in degs)}] (CLI: --degrees {' '.join(degs)})")
        if tunit is not None:
            fixes.append(f"time_unit={tunit!r} (CLI: --time-unit {tunit}{', the default' if tunit == 's' else ''})")
        dropped = [c for c, _ in drops]
        tail = ([f"pass {' and '.join(fixes)}"] if fixes else []) + (
            [f"drop {' '.join(dropped)} from --degrees (Python: from degrees=...)"] if dropped else [])
        detail = f"{where}: " + "; ".join(w for _, w in problems + drops)
        raise UnitsError(f"{detail}; {' and '.join(tail)}, or check_units=False if the values really are SI (s, rad).",
                         degs, tunit, dropped, detail)
