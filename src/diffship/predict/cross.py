r"""Cross-manoeuvre validation: a model trained on some manoeuvre types, judged on the others.

A fit reproduces its training runs; what it is for is predicting manoeuvres it never saw.
:func:`cross_validate` takes a fitted model (a :class:`~diffship.fit.FitResult` or a
:class:`~diffship.fitfile.LoadedFit`), the training runs and held-out measured runs, and

1. **classifies** every run from its rudder record (:func:`classify_run`): the rudder signal is
   cut into *plateaus* (stretches of at least ``hold_s`` seconds within ``tol`` of one level,
   :math:`\text{tol} = \max(1°, 0.1\,|\delta|_{\max})`) and the sequence of levels decides

   * **zigzag**: ≥ 2 non-zero plateaus alternating in sign with equal magnitudes (±20 %), reversed at one heading
     change of 0.5° or more; the rudder angle is their median magnitude, the switch heading the median heading
     change (since the first rudder order) at which the rudder left each plateau; both snapped to the standard
     angles (rudder 5, 10, ..., 35° within max(1°, 10 %); switch: the largest of 1, 5, 10, ..., 35° not above the
     observed heading change, within 2.5°, since the heading is read a sample or an autopilot delay late), else
     rounded to 0.5°; the side from the first execute (:func:`diffship.manoeuvres.first_execute`);
   * **turning circle**: one non-zero level held to the end of the record;
   * **pull-out**: one non-zero level, then back to zero for the rest of the record;
   * **spiral**: ≥ 3 distinct non-zero levels, each held at least ``spiral_hold_s``, in a
     monotone (or down-and-up) staircase;
   * **other**: anything else (a rudder that never moves by 0.5°, random steps, ...);

2. for every held-out run of a type **not** in the training set (with ``trained_types``: every
   standard one), simulates it with the fitted model — a zigzag **closed loop**, flown by the
   zigzag autopilot as a prediction is (the run's first side and execute time, helm rate and
   switch delay measured in it), every other type **open loop with the run's measured inputs** —
   from its initial state estimated on the run's
   first seconds (the one initial-state rule of :func:`diffship.metrics.evaluate`,
   :func:`diffship.metrics.start_state`) and computes the same IMO metrics on
   the measured and the predicted run (:mod:`diffship.manoeuvres.imo`): advance, transfer,
   tactical and steady turning diameter and steady yaw rate of a turning circle; overshoots,
   initial turning time and time to check yaw of a zigzag; yaw rate before release and residual
   rate of a pull-out; steady yaw rate per step of a spiral;
3. where the fit has a finite covariance, ``samples`` parameter draws are simulated together
   (vmapped, :func:`diffship.predict.sampling.simulate_draws`) and the 2.5–97.5 percentiles of each
   metric are its 95 % interval (parameter uncertainty only);
4. **flags** a metric whose measured value lies outside the interval *and* whose error exceeds a
   tolerance (:data:`TOLERANCES`: 5 % for lengths and rates, 10 % for times, 1.5° for overshoots), and a
   metric whose 95 % interval is wider than :data:`UNDETERMINED` tolerances on either side (the fit does not
   determine it: a prediction anywhere in such an interval validates nothing);
   the run (and the validation) fails when any metric is flagged.

Held-out runs of a trained type are listed but not judged here (they are ordinary validation
runs). References: ITTC Recommended Procedure 7.5-02-06-01 (free-running tests) and IMO
MSC.137(76) / MSC/Circ.1053 for the manoeuvres and metric definitions.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from ..data import Run
from ..errors import DataError, ModelError
from ..manoeuvres import first_execute, pullout_metrics, rudder_release, turning_metrics, zigzag_metrics
from ..preprocess import Filter
from ..metrics import start_state
from ..simulate import model_inputs
from ..steering import rudder_moves
from .autopilot import switch_delay
from .sampling import draw_parameters, fly_draws, manoeuvre_law, simulate_draws

__all__ = [
    "METRIC_UNITS",
    "TOLERANCES",
    "CrossValidation",
    "MetricCheck",
    "RunCheck",
    "RunType",
    "classify_run",
    "cross_validate",
    "train_types_json",
]

KINDS = ("zigzag", "turning_circle", "pull_out", "spiral", "other")
#: unit of each metric as reported (SI lengths and times, degrees for angles and rates)
METRIC_UNITS = {"advance": "m", "transfer": "m", "tactical_diameter": "m", "steady_diameter": "m",
                "r_steady": "deg/s", "first_overshoot": "deg", "second_overshoot": "deg",
                "initial_turning_time": "s", "time_to_check": "s", "r_turn": "deg/s", "r_residual": "deg/s"}
#: (relative, absolute) tolerance per metric unit before a miss is flagged
TOLERANCES = {"m": (0.05, 0.0), "s": (0.10, 0.0), "deg": (0.0, 1.5), "deg/s": (0.05, 0.02)}
#: The largest time step [s] a zigzag is flown again with (:func:`_closed_loop`): the autopilot's switch is then late
#: by at most this, not by part of the run's sample interval.
REPLAY_DT = 0.05
#: A metric whose 95 % interval reaches further than this many tolerances from its prediction is not determined
UNDETERMINED = 5.0


@dataclasses.dataclass(frozen=True)
class RunType:
    """Manoeuvre type of a run as read from its rudder record (see :func:`classify_run`)."""

    kind: str
    rudder_deg: float = math.nan
    switch_deg: float = math.nan
    side: float = 0.0
    levels_deg: tuple[float, ...] = ()
    reason: str = ""

    def as_json(self) -> dict:
        def num(v):
            return None if not math.isfinite(v) else float(v)

        return {"kind": self.kind, "label": self.label, "rudder_deg": num(self.rudder_deg),
                "switch_deg": num(self.switch_deg), "side": self.side, "levels_deg": list(self.levels_deg),
                "reason": self.reason}

    @classmethod
    def from_json(cls, d: dict) -> RunType:
        def num(v):
            return math.nan if v is None else float(v)

        return cls(str(d["kind"]), num(d.get("rudder_deg")), num(d.get("switch_deg")), float(d.get("side", 0.0)),
                   tuple(d.get("levels_deg", ())), str(d.get("reason", "")))

    @property
    def label(self) -> str:
        side = {1.0: " starboard", -1.0: " port"}.get(self.side, "")
        if self.kind == "zigzag":
            return f"zigzag {self.rudder_deg:g}/{self.switch_deg:g}{side} first"
        if self.kind in ("turning_circle", "pull_out"):
            return f"{self.kind.replace('_', ' ').replace('pull out', 'pull-out')} {self.rudder_deg:g}°{side}"
        return self.kind


def _plateaus(t: np.ndarray, d_deg: np.ndarray, tol: float, hold_s: float) -> list[tuple[int, int, float]]:
    """(first, last, level) of the stretches of at least ``hold_s`` within ``tol`` of their start level."""
    out, i, n = [], 0, len(d_deg)
    while i < n:
        j = i
        ref = d_deg[i]
        while j + 1 < n and abs(d_deg[j + 1] - ref) <= tol:
            j += 1
        if t[j] - t[i] >= hold_s:
            lvl = float(np.median(d_deg[i:j + 1]))
            if out and abs(out[-1][2] - lvl) <= tol:
                out[-1] = (out[-1][0], j, float(np.median(d_deg[out[-1][0]:j + 1])))
            else:
                out.append((i, j, lvl))
        i = j + 1
    return out


def _ramp_start(raw: np.ndarray, a: int, b: int, level: float) -> int:
    """Last sample of the plateau ``a..b`` (at ``level``) before the raw rudder signal leaves it for
    good: three samples in a row beyond max(0.2°, 5 × its scatter on the plateau)."""
    thr = max(0.2, 5.0 * float(np.std(raw[a:b + 1] - level)) if b > a + 2 else 0.2)
    far = np.abs(raw[a:] - level) > thr
    run3 = far[:-2] & far[1:-1] & far[2:] if far.size > 2 else far
    hits = np.nonzero(run3)[0]
    return a + max(int(hits[0]) - 1, 0) if hits.size else b


_RUDDERS = (5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 35.0)
_SWITCHES = (1.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 35.0)
#: A run of alternating rudder plateaus is a zigzag only where its reversals come at one heading change: their
#: spread (largest minus smallest) at most this [deg] or this share of their median, whichever is larger; and
#: that change (their median) at least ZIGZAG_MIN_SWITCH_DEG (the smallest standard switch angle is 1°).
ZIGZAG_SPREAD_DEG, ZIGZAG_SPREAD_REL, ZIGZAG_MIN_SWITCH_DEG = 3.0, 0.3, 0.5


def _standard(x: float, values: tuple[float, ...], rel: float) -> float:
    """The nearest standard angle when within max(1°, rel·x), else ``x`` rounded to 0.5°."""
    best = min(values, key=lambda v: abs(v - x))
    return best if abs(best - x) <= max(1.0, rel * x) else round(2.0 * x) / 2.0


def _round(x: float) -> float:
    return float(round(x)) if abs(x - round(x)) < 0.3 else round(x, 1)


def classify_run(run: Run, *, hold_s: float = 3.0, spiral_hold_s: float = 30.0) -> RunType:
    """Manoeuvre type of ``run`` from its ``delta`` record (and ``psi`` for a zigzag's switch heading).

    Rules in the module docstring. Angles in the result are degrees; ``side`` +1 when the first
    rudder order is to starboard (positive δ), −1 to port.
    """
    if not run.has("delta"):
        return RunType("other", reason="no rudder channel 'delta'")
    t = np.asarray(run.time, dtype=np.float64)
    raw = d = np.degrees(np.asarray(run["delta"], dtype=np.float64))
    k = max(1, round(1.0 / run.dt))
    if k > 1:  # 1 s moving average against sensor noise
        d = np.convolve(np.concatenate([np.full(k // 2, d[0]), d, np.full(k - 1 - k // 2, d[-1])]), np.ones(k) / k,
                        "valid")
    base = float(np.median(d[: max(2, k)]))  # a trim angle on the approach; a first step is not one
    base = base if abs(base) < 3.0 else 0.0
    amp = float(np.max(np.abs(d - base)))
    if amp < 0.5:
        return RunType("other", reason="the rudder never moves by more than 0.5°")
    tol = max(1.0, 0.1 * amp)
    pl = _plateaus(t, d - base, tol, hold_s)
    nz = [(a, b, lv) for a, b, lv in pl if abs(lv) > tol]
    if not nz:
        return RunType("other", reason=f"no rudder level held for {hold_s:g} s")
    side = float(np.sign(nz[0][2]))
    levels = tuple(round(lv, 1) for _, _, lv in nz)
    ends_at_end = pl[-1][1] >= len(t) - 1 - k
    mags = np.abs([lv for _, _, lv in nz])
    alternating = len(nz) >= 2 and all(np.sign(nz[i][2]) != np.sign(nz[i + 1][2]) for i in range(len(nz) - 1))
    if alternating and mags.max() <= 1.2 * mags.min():
        try:
            i0, execute_side = first_execute(run)
        except DataError:
            i0, execute_side = 0, side
        if not run.has("psi"):
            return RunType("zigzag", _round(float(np.median(mags))), math.nan, side, levels,
                           "alternating rudder of equal magnitude (no heading to read the switch angle)")
        psi = np.unwrap(np.asarray(run["psi"], dtype=np.float64))
        h = np.abs(np.degrees(psi[[_ramp_start(raw, a, b, lv + base) for a, b, lv in nz[:-1]]] - psi[i0]))
        rudder, sw = _standard(float(np.median(mags)), _RUDDERS, 0.1), float(np.median(h))
        if sw < ZIGZAG_MIN_SWITCH_DEG or (len(h) >= 2 and float(np.ptp(h)) > max(ZIGZAG_SPREAD_DEG,
                                                                                ZIGZAG_SPREAD_REL * sw)):
            # reversals at different heading changes (or none) follow a clock or an operator, not the heading
            return RunType("other", math.nan, math.nan, side, levels,
                           f"alternating rudder of equal magnitude, but reversed at heading changes {np.min(h):.3g}–"
                           f"{np.max(h):.3g}° (a zigzag reverses at one, of {ZIGZAG_MIN_SWITCH_DEG:g}° or more): "
                           "not a zigzag")
        # the heading is read when the rudder leaves its plateau, a sample or an autopilot delay
        # after the switch: the largest standard switch angle not above it, within 2.5°
        std = [a for a in _SWITCHES if a <= sw + 0.3 and sw - a <= 2.5]
        sw = max(std) if std else round(2.0 * sw) / 2.0
        side = execute_side
        return RunType("zigzag", rudder, sw, side, levels,
                       f"{len(nz)} rudder plateaus alternating in sign, |δ| {mags.min():.3g}–{mags.max():.3g}°, "
                       f"heading change at the reversals {np.min(h):.3g}–{np.max(h):.3g}°")
    if len(nz) == 1:
        a, b, lv = nz[0]
        if b >= len(t) - 1 - k:
            return RunType("turning_circle", _round(abs(lv)), math.nan, side, levels,
                           f"rudder {lv:+.3g}° from t = {t[a]:.1f} s to the end of the record")
        if ends_at_end and abs(pl[-1][2]) <= tol and pl[-1][0] > b:
            return RunType("pull_out", _round(abs(lv)), math.nan, side, levels,
                           f"rudder {lv:+.3g}° held {t[b] - t[a]:.0f} s, then back to zero to the end")
    long = [(a, b, lv) for a, b, lv in nz if t[b] - t[a] >= spiral_hold_s]
    if len(long) >= 3 and len(long) == len(nz):
        s = np.sign(np.diff([lv for _, _, lv in long]))
        turns = int(np.sum(s[1:] != s[:-1]))
        if turns <= 1 and len({round(lv) for _, _, lv in long}) >= 3:
            return RunType("spiral", math.nan, math.nan, side, levels,
                           f"{len(long)} rudder steps of ≥ {spiral_hold_s:g} s in a staircase")
    return RunType("other", math.nan, math.nan, side, levels,
                   f"rudder levels {', '.join(f'{lv:+.3g}' for lv in levels)}° fit no standard manoeuvre")


def train_types_json(runs: Sequence[Run], length: float | None = None) -> list[dict]:
    """The manoeuvre type of each training run, for the fit file (``training_manoeuvres``), with its
    measured metrics (``measured``: :func:`run_metrics`) and, for a zigzag, the measured delay between
    the heading reaching the switch angle and the rudder's reversal (``switch_delay_s``,
    :func:`diffship.predict.autopilot.switch_delay`), so that ``python -m diffship.predict`` reproduces each training manoeuvre
    beside what was measured."""
    out = []
    for r in runs:
        rt = classify_run(r)
        d = {"run": r.name, **rt.as_json()}
        if rt.kind != "other":
            try:
                d["measured"] = {k: float(v) for k, v in run_metrics(r, rt, length).items()}
            except (DataError, ModelError):
                pass
        if rt.kind == "zigzag":
            d["switch_delay_s"] = switch_delay(r, rt.switch_deg)
        out.append(d)
    return out


# ----------------------------------------------------------------------------------------
# metrics of one run of a given type (measured and predicted alike)
# ----------------------------------------------------------------------------------------
def run_metrics(run: Run, rt: RunType, length: float | None = None) -> dict[str, float]:
    """The metrics of ``run`` for its type ``rt`` (units :data:`METRIC_UNITS`; NaN where undefined)."""
    nan = math.nan
    if rt.kind == "turning_circle":
        out = {}
        if run.has("x0", "y0"):
            tm = turning_metrics(run, length=length)
            out.update(advance=tm.advance, transfer=tm.transfer, tactical_diameter=tm.tactical_diameter,
                       steady_diameter=tm.steady_diameter)
        if run.has("r"):
            r = np.asarray(run["r"])
            out["r_steady"] = abs(math.degrees(float(np.mean(r[-max(2, run.n // 8):]))))
        return out
    if rt.kind == "zigzag":
        zm = zigzag_metrics(run, switch_deg=rt.switch_deg, rudder_deg=rt.rudder_deg)
        return {"first_overshoot": zm.first_overshoot, "second_overshoot": zm.second_overshoot,
                "initial_turning_time": zm.initial_turning_time, "time_to_check": zm.time_to_check}
    if rt.kind == "pull_out" and run.has("r"):
        i_rel = rudder_release(run, first_execute(run)[0])
        if i_rel is None:
            return {"r_turn": nan, "r_residual": nan}
        pm = pullout_metrics(run, t_release=float(run.time[i_rel]), average_s=min(10.0, 0.1 * run.duration))
        return {"r_turn": abs(math.degrees(pm["r_turn"])), "r_residual": math.degrees(pm["r_residual"])
                * float(np.sign(pm["r_turn"]) or 1.0)}
    if rt.kind == "spiral" and run.has("r"):
        d = np.degrees(np.asarray(run["delta"]))
        out = {}
        for lv in rt.levels_deg:
            sel = np.nonzero(np.abs(d - lv) <= 1.0)[0]
            if sel.size > 4:
                tail = sel[sel >= sel[0] + (sel.size * 3) // 4]
                out[f"r_steady_{lv:+g}deg"] = math.degrees(float(np.mean(np.asarray(run["r"])[tail])))
        return out
    return {}


@dataclasses.dataclass(frozen=True)
class MetricCheck:
    """One metric of one held-out run: measured, predicted, 95 % interval, error and verdict."""

    name: str
    unit: str
    measured: float
    predicted: float
    interval: tuple[float, float] | None
    error: float  #: predicted − measured
    relative_error: float  #: error / |measured| (NaN where measured is 0 or NaN)
    flagged: bool

    @property
    def outside_tolerance(self) -> bool:
        """The prediction misses by more than the tolerance with the measured value outside its interval."""
        return _flag(self.unit, self.measured, self.predicted, self.interval, undetermined=False)

    @property
    def inside(self) -> bool | None:
        if self.interval is None or not all(map(math.isfinite, self.interval)):
            return None
        return self.interval[0] <= self.measured <= self.interval[1]


@dataclasses.dataclass(frozen=True)
class RunCheck:
    """A held-out run: its type, the metrics and the draws used for the intervals."""

    run: str
    type: RunType
    metrics: tuple[MetricCheck, ...]
    draws_used: int
    draws_failed: int
    predicted: Run | None
    measured: Run
    note: str = ""

    @property
    def flagged(self) -> bool:
        return any(m.flagged for m in self.metrics) or self.predicted is None


@dataclasses.dataclass(frozen=True)
class CrossValidation:
    """What :func:`cross_validate` returns (text, JSON and figure: :mod:`diffship.predict.cross_report`)."""

    model_name: str
    train_types: tuple[RunType, ...]
    train_runs: tuple[str, ...]
    checks: tuple[RunCheck, ...]
    skipped: tuple[tuple[str, str], ...]  #: (run, why) held-out runs not judged here
    interval_method: str

    @property
    def train_kinds(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(t.kind for t in self.train_types))

    @property
    def passed(self) -> bool:
        return bool(self.checks) and not any(c.flagged for c in self.checks)


def _flag(unit: str, measured: float, predicted: float, interval, undetermined: bool = True) -> bool:
    if not math.isfinite(measured):
        return False
    if not math.isfinite(predicted):
        return True
    rel, ab = TOLERANCES.get(unit, (0.05, 0.0))
    tol = max(rel * abs(measured), ab)
    too_far = abs(predicted - measured) > tol
    outside = interval is None or not (interval[0] <= measured <= interval[1])
    wide = (undetermined and interval is not None and all(map(math.isfinite, interval))
            and max(predicted - interval[0], interval[1] - predicted) > UNDETERMINED * tol)
    return bool((too_far and outside) or wide)


def _fit_parts(fit):
    """(model, free names, covariance or None, integrator) of a FitResult or a LoadedFit."""
    names = tuple(getattr(fit, "covariance_names", None) or fit.free)
    cov = fit.covariance
    if cov is not None and (np.shape(cov) != (len(names), len(names)) or not np.all(np.isfinite(cov))):
        cov = None
    return fit.model, names, cov, fit.integrator


def cross_validate(fit, train: Sequence[Run] | Sequence[RunType], heldout: Sequence[Run], *, samples: int = 100,
                   seed: int = 0, flt: Filter | None = None, length: float | None = None,
                   trained_types: bool = False) -> CrossValidation:
    """Judge ``fit`` on the held-out runs whose manoeuvre type is not among the training runs' types.

    Args:
        fit (FitResult | LoadedFit): a :class:`~diffship.fit.FitResult` or :class:`~diffship.fitfile.LoadedFit`.
        train: the training runs (classified here) or their :class:`RunType` s (e.g. from a fit file).
        heldout: measured runs to predict (open loop with their measured inputs).
        samples: parameter draws for the 95 % intervals (0: none; needs a finite covariance).
        length: ship length [m] for the turning metrics (default the model's ``L``).
        trained_types: also judge held-out runs of the trained types (a held-out zigzag of a
            zigzag-trained fit: its overshoots measured and predicted), labelled as such.
    """
    model, names, cov, integ = _fit_parts(fit)
    if "delta" not in model.input_names:
        raise ModelError(f"model {model.name} has no rudder input 'delta': manoeuvre types cannot be compared")
    ttypes = tuple(t if isinstance(t, RunType) else classify_run(t) for t in train)
    tnames = tuple(t.label if isinstance(t, RunType) else t.name for t in train)
    trained = {t.kind for t in ttypes}
    length = length or (float(model.L) if hasattr(model, "L") else None)
    draws = np.zeros((0, len(names)))
    if cov is not None and samples > 0:
        draws = draw_parameters(model, names, np.asarray([float(getattr(model, n)) for n in names]), cov, samples, seed)
        method = (f"{len(draws)} parameter draws from N(θ̂, Σ) of the {len(names)} free parameters, simulated "
                  "vmapped with the measured inputs; 95 % interval = 2.5–97.5 percentiles (parameter uncertainty only)")
    else:
        method = "no intervals (no finite covariance)" if samples > 0 else "no intervals (samples=0)"
    checks, skipped = [], []
    for run in heldout:
        rt = classify_run(run)
        if rt.kind in trained and not trained_types:
            skipped.append((run.name, f"{rt.label}: a trained manoeuvre type (an ordinary validation run)"))
            continue
        if rt.kind == "other":
            skipped.append((run.name, f"not a standard manoeuvre ({rt.reason})"))
            continue
        checks.append(_check(model, names, draws, integ, run, rt, flt or Filter(), length,
                             getattr(fit, "channels", None), getattr(fit, "channel_scales", None)))
    return CrossValidation(model.name, ttypes, tnames, tuple(checks), tuple(skipped), method)


def _as_run(model, run: Run, ys: np.ndarray, name: str) -> Run:
    ch = {c: ys[:, j] for j, c in enumerate(model.output_names)}
    for n in model.input_names:
        if run.has(n):
            ch[n] = np.asarray(run[n])
    return Run(name, run.time, ch, {"simulated": True, "model": model.name}, check_units=False)


def _closed_loop(model, names, thetas, integ, run: Run, rt: RunType, x0: np.ndarray) -> list[Run | None]:
    """A zigzag flown again closed loop by the model (one run per row of ``thetas``): the run's own start
    (``x0``), first side and execute time, angles, constant inputs (their means), helm rate
    (:func:`diffship.steering.rudder_moves`) and switch delay (:func:`diffship.predict.autopilot.switch_delay`) — as a prediction is
    flown, so the overshoots compare with the measured ones (open loop, the measured rudder reverses when
    the *measured* heading reached the switch angle, and only the first overshoot would compare)."""
    i0, side = first_execute(run)
    moves = [m[2] for m in rudder_moves(run)]
    rate = float(np.median(moves)) if moves else 15.0
    initial = {n: float(v) for n, v in zip(model.state_names, x0)}
    inputs = {n: float(np.mean(run[n])) for n in model.input_names if n != "delta" and run.has(n)}
    law = manoeuvre_law(model, "zigzag", rudder_deg=float(rt.rudder_deg), side=float(side),
                        t_execute=float(run.time[i0] - run.time[0]), initial=initial,
                        switch_deg=float(rt.switch_deg), delay_s=switch_delay(run, rt.switch_deg))
    # flown on a grid fine enough that the autopilot's switch is not late by part of a sample: the measured delay is
    # interpolated between samples (it already holds the record's own sampling lateness), so a replay checking
    # the heading only at the run's samples would add that lateness again (a 15/15 MMG zigzag sampled at 2 Hz, the
    # true model flown again: first overshoot 25.9° against the measured 24.4°; at a fine step 24.1°); the flown
    # runs are then taken at the run's own sampling, so that both metrics read the same grid
    k = max(1, math.ceil(run.dt / REPLAY_DT - 1e-9))
    flown = fly_draws(model, names, thetas, law, initial=initial, inputs=inputs, duration=run.duration, dt=run.dt / k,
                      rudder_rate_deg_s=rate, integrator=integ, metadata={"manoeuvre": "zigzag"})
    return [f if f is None or k == 1 else f.resample(run.dt) for f in flown]


def _check(model, names, draws, integ, run: Run, rt: RunType, flt: Filter, length, fitted=None,
           scales=None) -> RunCheck:
    us = model_inputs(model, run)
    # the one initial-state rule (:mod:`diffship.initial`), on the fit's channels with its channel scales
    x0 = start_state(model, run, flt, integrator=integ, channels=fitted or None, scales=scales or None)
    theta0 = np.asarray([[float(getattr(model, n)) for n in names]])
    closed = rt.kind == "zigzag" and "psi" in model.state_names and run.has("psi") and bool(names)
    if closed:
        flown = _closed_loop(model, names, theta0, integ, run, rt, x0)
        ok0 = [flown[0] is not None]
    else:
        ys0, ok0 = simulate_draws(model, names, theta0, run.time, us, x0, integ)
    measured = run_metrics(run, rt, length)
    if not ok0[0]:
        mc = tuple(MetricCheck(k, METRIC_UNITS.get(k, "deg/s"), v, math.nan, None, math.nan, math.nan,
                               math.isfinite(v)) for k, v in measured.items())
        return RunCheck(run.name, rt, mc, 0, 0, None, run, "the fitted model BLOWS UP on this run's inputs")
    pred = (_as_run(model, flown[0], np.stack([flown[0][c] for c in model.output_names], axis=1),
                    f"{run.name} (predicted)") if closed else _as_run(model, run, ys0[0], f"{run.name} (predicted)"))
    predicted = run_metrics(pred, rt, length)
    samp, failed = [], 0
    if len(draws):
        if closed:
            sims = _closed_loop(model, names, draws, integ, run, rt, x0)
        else:
            ys, ok = simulate_draws(model, names, draws, run.time, us, x0, integ)
            sims = [_as_run(model, run, ys[s], "draw") if ok[s] else None for s in range(len(draws))]
        for sim in sims:
            try:
                if sim is None:
                    raise ModelError("blew up")
                samp.append(run_metrics(sim, rt, length))
            except (ModelError, DataError):
                failed += 1
    out = []
    lacking = [k for k in measured if k not in predicted]  # e.g. a track from a heading-only model
    for k, mv in measured.items():
        if k in lacking:
            continue
        pv = predicted[k]
        v = np.asarray([s.get(k, math.nan) for s in samp], dtype=np.float64)
        v = v[np.isfinite(v)]
        iv = ((float(np.percentile(v, 2.5)), float(np.percentile(v, 97.5)))
              if v.size >= max(5, len(samp) // 2) and samp else None)
        unit = METRIC_UNITS.get(k, "deg/s")
        err = pv - mv
        rel = err / abs(mv) if math.isfinite(mv) and mv != 0 else math.nan
        out.append(MetricCheck(k, unit, float(mv), float(pv), iv, float(err), float(rel), _flag(unit, mv, pv, iv)))
    note = (f"model {model.name} does not predict {', '.join(lacking)} (outputs {', '.join(model.output_names)})"
            if lacking else "")
    return RunCheck(run.name, rt, tuple(out), len(samp), failed, pred, run, note)
