r"""Data consistency: measurement errors settled from the logs alone, before any hydrodynamic model.

Some effects are errors of the *measurement*, not of the model: a heading sensor misaligned
against the track, a logging clock offset between the rudder and the motion. A hydrodynamic
model fitted to such logs bends its coefficients to them (on the HSVA KVLCC2 zigzags a 1°
heading bias is absorbed by the base fit: the held-out error is *lower* with the bias than
without, ``benchmarks/results/withheld_real_mmg.md``), so the held-out test that judges model
effects cannot find them. Aircraft system identification settles them first, by *data
compatibility analysis* (Klein & Morelli 2006, *Aircraft System Identification*, ch. 10;
Mulder et al. 1999, flight-path reconstruction): relations that hold whatever the dynamics are.

**Heading against the track** (:func:`heading_consistency`). Over-ground body velocities
:math:`(u, v)` and the logged track obey :math:`\dot x = u\cos\psi - v\sin\psi`,
:math:`\dot y = u\sin\psi + v\cos\psi` exactly. With a heading that reads :math:`\psi + b`, the
track dead-reckoned from the logged :math:`(u, v, \psi)`, :math:`D(t) = \int R(\psi_{log})\,(u, v)\,dt`,
is the logged track turned by :math:`b`. Per run, the angle of the best rotation between the two
centred tracks (two-dimensional Procrustes, :math:`\theta = \operatorname{atan2}(\sum D\times P,
\sum D\cdot P)`) gives :math:`b = -\theta`, in closed form; the pooled estimate is the mean of the
training runs', its standard error their spread over :math:`\sqrt n` (all runs), and the held-out
runs judge it: their track misfit with :math:`b` against without. It needs :math:`u, v` measured
over ground apart from the heading (a tracker's velocities, GNSS velocity over ground); where
:math:`u, v` were computed from the track *with* the logged heading, the relation holds for any
:math:`b` and the check finds nothing — the line says what it used. A uniform current does not
enter (over-ground velocities are consistent with the track whatever the water does).

**Yaw rate against the heading** (:func:`rate_consistency`). A rate gyro that reads
:math:`r + b_r` integrates away from the logged heading at :math:`b_r`:
:math:`\psi(t) - \psi(t_0) - \int r_{log}\,dt = -b_r (t - t_0)`. Per run, the slope of that
difference (least squares with an offset) gives :math:`b_r`; pooled, judged and stated as the
heading bias is (held-out misfit: the RMS of the difference without and with it). No library
effect carries it (the models' yaw rate is a state): :func:`corrected` takes it out of ``r``.
Where ``r`` was derived from the heading the two agree by construction (the HSVA zigzags: under
0.0004°/s) and the check finds nothing.

**Rudder timing** (:func:`rudder_timing`). The yaw acceleration answers the rudder at once
(the rudder's lift acts on the hull without delay). Per shift :math:`\tau` on a grid of one sample
interval, the equation error of a polynomial yaw equation in the prime system's scaling
(:func:`_yaw_series`) with the rudder shifted, :math:`\delta_{log}(t-\tau)`, is fitted by least
squares on the training runs (at most 81 shifts, one sample interval apart or wider on fast logs);
the :math:`\tau` of its least residual (parabola through the three
grid points around it) is the time the motion follows the logged rudder. :math:`\dot r` comes from
a Savitzky–Golay cubic over about 1 s (zero phase: it shifts nothing). The standard error is the
spread of the runs' own shifts; the held-out runs judge it by their equation error with the
training coefficients at :math:`\tau` against at 0. The equation error holds no hull coefficient
of the model under diagnosis, so a structural gap of that model does not bend it (on the HSVA
zigzags with a 0.5-s clock offset: 0.41 s here, 0.50 s above the unshifted logs' −0.09 s, where
the output-error refit of the delay beside the missing damping terms gave 0.31 s). What it
cannot do on zigzags is tell a pure shift from a steering-gear lag or delay (measured: on
independent synthetic ships a first-order lag fits as well as a shift, training residuals equal
to 0.3 %): the line says "a logging-clock offset or a steering lag", and the model search
(:mod:`.which`) tells the actuator effects apart. Either sign is a finding (a rudder logged late
makes the motion lead it) when the held-out equation error falls enough (below).

A check *finds* an error when its estimate is at least the effect's smallest relevant size
(:attr:`~diffship.models.effects.Effect.MIN_RELEVANT`), its 95 % interval (Student t over the
runs) excludes 0, and the held-out misfit falls by at least the 5 % the model search asks of an
effect (``DiagnoseOptions.min_gain``). Measured: on the HSVA zigzags rudder shifts of ±0.3 to
±1 s lower the held-out yaw equation error by 9–51 % (the logs as they are: −0.09 s, 3 %); on the
independent synthetic ships (their yaw rate logged with 0.1°/s noise, so the equation error is
mostly noise) by at most 1.2 % for any effect — there the timing, with its sign, is reported and
left to the model search, whose shifts of −0.5 s where a nonlinear damping term is missing would
otherwise be claimed. Findings are reported — the
verdict's "In the data" line, :attr:`~.diagnosis.Diagnosis.in_data`, the JSON's ``in_data`` —
beside the model search, which runs on the logs as given.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np
from scipy.special import stdtrit  # Student t quantiles; scipy.stats/signal cost 0.3–0.6 s of every process's start

from ..data import Run
from ..preprocess import Filter, derivative

__all__ = ["DataFinding", "heading_consistency", "rate_consistency", "rudder_timing", "data_checks", "in_data_line",
           "corrected", "correction_note"]

DEG = math.pi / 180
#: smallest sizes worth reporting: the library effects' own (``HeadingBias``, ``InputDelay``)
MIN_HEADING = 0.2 * DEG
MIN_TIMING = 0.2  # s
#: a rate-gyro zero error worth reporting: it turns the integrated heading 1° in 100 s
MIN_RATE = 0.01 * DEG
#: the least match (cosine of the turned tracks) of a run the heading check uses
MIN_MATCH = 0.9
#: display factor and unit of the checks' SI units
_SHOWN = {"rad": (1 / DEG, "°"), "rad/s": (1 / DEG, "°/s")}


def shown_unit(unit: str) -> tuple[float, str]:
    """``(factor, label)`` to show a value in ``unit`` (SI) as a user reads it: degrees for angles."""
    return _SHOWN.get(unit, (1.0, unit))


def _t95(n: int) -> float:
    """The 97.5 % Student t quantile for ``n`` runs (n − 1 degrees of freedom)."""
    return float(stdtrit(n - 1, 0.975))


#: the rudder-timing grid's shifts at most (one sample interval apart, or wider on fast logs)
MAX_SHIFTS = 80


@dataclasses.dataclass(frozen=True)
class DataFinding:
    """One consistency check's result.

    ``effect``/``parameter``: what it measures (``heading_bias`` ``b_psi`` [rad], the library
    effect of that name; ``rudder_timing`` ``tau_d`` [s], the time the motion follows the logged
    rudder, the library's ``input_delay`` when it is a clock offset; negative when the logged
    rudder lags the motion; ``rate_bias`` ``b_r`` [rad/s], a rate-gyro zero error, no library
    effect); ``value`` the pooled estimate over the training runs, ``stderr`` its standard
    error over all runs (``per_run``); ``heldout`` the held-out runs' misfit without and with it
    (``misfit_unit``); ``found`` whether it is an error of the logs (module docstring) and
    ``reason`` why or why not; ``curve`` what the figure draws (the rudder timing: the shifts and
    the training runs' RMS equation error at each).
    """

    effect: str
    parameter: str
    value: float
    stderr: float
    unit: str
    per_run: dict[str, float]
    heldout: tuple[float, float]
    misfit_unit: str
    method: str
    found: bool
    reason: str
    curve: tuple[tuple[float, ...], tuple[float, ...]] = ((), ())

    def half95(self) -> float:
        n = len(self.per_run)
        return _t95(n) * self.stderr if n > 1 and math.isfinite(self.stderr) else math.inf

    def shown(self) -> str:
        k, unit = shown_unit(self.unit)
        return f"{k * self.value:.3g} ± {k * self.half95():.2g}{unit if unit.startswith('°') else ' ' + unit}"

    @property
    def library_effect(self) -> str | None:
        """The library effect whose parameter this measures (``input_delay`` for the rudder timing;
        ``None`` for the rate bias, which no effect carries)."""
        return {"rudder_timing": "input_delay", "rate_bias": None}.get(self.effect, self.effect)

    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["half95"] = self.half95()
        d["library_effect"] = self.library_effect
        return d


def _verdict(value: float, stderr: float, n: int, minimum: float, before: float, after: float,
             what: str, unit: str, min_fall: float) -> tuple[bool, str]:
    if n < 2 or not math.isfinite(stderr):
        return False, f"too few runs to give {what} an interval ({n})"
    half = _t95(n) * stderr
    if abs(value) < minimum:
        k, u = shown_unit(unit)
        return False, f"smaller than the smallest relevant size ({k * minimum:.3g}{u if u.startswith('°') else ' ' + u})"
    if abs(value) <= half:
        return False, "its 95 % interval includes 0"
    if not (math.isfinite(before) and math.isfinite(after)):
        return False, "no held-out run to judge it"
    if not after < before:
        return False, "the held-out runs do not agree (their misfit does not fall)"
    fall = 1 - after / before
    if fall < min_fall:
        return False, (f"the held-out misfit falls by {100 * fall:.2g} % only, under the {100 * min_fall:.3g} % the "
                       "model search asks of an effect")
    return True, (f"interval excludes 0, above the smallest relevant size, the held-out misfit falls by "
                  f"{100 * fall:.3g} %")


# -- heading against the track -------------------------------------------------------------------

def _rotation(run: Run) -> tuple[float, np.ndarray, np.ndarray, float]:
    """``(b, D, P, match)``: the heading bias of one run, its centred dead-reckoned and logged
    tracks, and how well they match once turned (1: exactly; the cosine of the Procrustes fit)."""
    t = np.asarray(run.time, dtype=float)
    psi, u, v = (np.asarray(run[c], dtype=float) for c in ("psi", "u", "v"))
    xd, yd = u * np.cos(psi) - v * np.sin(psi), u * np.sin(psi) + v * np.cos(psi)
    dt = np.diff(t)
    D = np.stack([np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * dt)]) for w in (xd, yd)])
    P = np.stack([np.asarray(run[c], dtype=float) for c in ("x0", "y0")])
    D, P = D - D.mean(1, keepdims=True), P - P.mean(1, keepdims=True)
    cross, dot = float(np.sum(D[0] * P[1] - D[1] * P[0])), float(np.sum(D[0] * P[0] + D[1] * P[1]))
    norm = math.sqrt(float(np.sum(D * D)) * float(np.sum(P * P)))
    return -math.atan2(cross, dot), D, P, (math.hypot(cross, dot) / norm if norm > 0 else 0.0)


def _track_misfit(tracks: Sequence[tuple], b: float) -> float:
    """RMS [m] of the logged tracks against the dead-reckoned ones (:func:`_rotation`'s) with the
    heading ψ − b (centred)."""
    sq, n = 0.0, 0
    c, s = math.cos(-b), math.sin(-b)
    for _, D, P, _ in tracks:
        Dr = np.stack([c * D[0] - s * D[1], s * D[0] + c * D[1]])
        Dr = Dr - Dr.mean(1, keepdims=True)
        sq += float(np.sum((Dr - P) ** 2))
        n += P.shape[1]
    return math.sqrt(sq / max(n, 1))


def heading_consistency(train: Sequence[Run], val: Sequence[Run], min_fall: float = 0.05) -> DataFinding | None:
    """The heading bias the track and the over-ground velocities imply (module docstring), or
    ``None`` where a run lacks ``x0, y0, psi, u, v``, is too short (under 10 samples), or no
    training run's dead-reckoned track matches its logged one however turned (:data:`MIN_MATCH`)."""
    runs = list(train) + list(val)
    if not runs or not all(r.has("x0", "y0", "psi", "u", "v") and r.n >= 10 for r in runs):
        return None
    # a run whose dead-reckoned track does not match the logged one however turned (a craft holding
    # station, u, v in other units or through the water in a current) says nothing about the heading
    rot = {r.name: _rotation(r) for r in runs}
    ok = {k for k, v in rot.items() if v[3] >= MIN_MATCH}
    train, val = [r for r in train if r.name in ok], [r for r in val if r.name in ok]
    if not train:
        return None
    per = {r.name: rot[r.name][0] for r in train + val}
    b = float(np.mean([per[r.name] for r in train]))
    vals = np.array(list(per.values()))
    se = float(np.std(vals, ddof=1) / math.sqrt(len(vals))) if len(vals) > 1 else math.nan
    held = tuple(_track_misfit([rot[r.name] for r in val], x) for x in (0.0, b))
    found, reason = _verdict(b, se, len(vals), MIN_HEADING, *held, "the heading bias", "rad", min_fall)
    return DataFinding("heading_bias", "b_psi", b, se, "rad", per, held, "m",
                       "track dead-reckoned from the logged u, v and heading against the logged track "
                       "(over-ground u, v assumed)" + (f"; {len(runs) - len(ok)} run(s) left out, their tracks do "
                                                       f"not match (under {MIN_MATCH})" if len(ok) < len(runs) else ""),
                       found, reason)


# -- yaw rate against the heading ---------------------------------------------------------------

def _rate_drift(run: Run) -> tuple[float, np.ndarray, np.ndarray]:
    """``(b_r, t − t0, d)``: the rate bias of one run and the heading minus the integrated rate."""
    t = np.asarray(run.time, dtype=float)
    psi, r = np.unwrap(np.asarray(run["psi"], dtype=float)), np.asarray(run["r"], dtype=float)
    d = psi - psi[0] - np.concatenate([[0.0], np.cumsum(0.5 * (r[1:] + r[:-1]) * np.diff(t))])
    tt = t - t[0]
    slope = np.polyfit(tt, d, 1)[0]
    return -float(slope), tt, d


def _rate_misfit(drifts: Sequence[tuple], b: float) -> float:
    """RMS [rad] of the heading minus the integrated rate (:func:`_rate_drift`'s) corrected by ``b``
    (each run's offset removed)."""
    sq, n = 0.0, 0
    for _, tt, d in drifts:
        e = d + b * tt
        sq += float(np.sum((e - e.mean()) ** 2))
        n += len(e)
    return math.sqrt(sq / max(n, 1)) if n else math.nan


def rate_consistency(train: Sequence[Run], val: Sequence[Run], min_fall: float = 0.05) -> DataFinding | None:
    """The rate-gyro zero error the heading implies (module docstring), or ``None`` where a run
    lacks ``psi`` or ``r`` or is too short (under 10 samples)."""
    runs = list(train) + list(val)
    if not train or not all(r.has("psi", "r") and r.n >= 10 for r in runs):
        return None
    drift = {r.name: _rate_drift(r) for r in runs}
    per = {k: v[0] for k, v in drift.items()}
    b = float(np.mean([per[r.name] for r in train]))
    vals = np.array(list(per.values()))
    se = float(np.std(vals, ddof=1) / math.sqrt(len(vals))) if len(vals) > 1 else math.nan
    held = tuple(_rate_misfit([drift[r.name] for r in val], x) for x in (0.0, b)) if val else (math.nan, math.nan)
    found, reason = _verdict(b, se, len(vals), MIN_RATE, *held, "the rate bias", "rad/s", min_fall)
    return DataFinding("rate_bias", "b_r", b, se, "rad/s", per, held, "rad (heading minus integrated rate)",
                       "the logged heading against the integrated logged yaw rate", found, reason)


# -- rudder timing ------------------------------------------------------------------------------

def _yaw_series(run: Run, window_s: float = 1.0):
    r"""``(t, hull features, rudder, U, ṙ)`` of one run on a uniform grid, or ``None``.

    The hull terms scale as the forces of a manoeuvring model in the prime system do
    (:math:`U r, U v, r^3/U, v^3/U, v^2 r/U, v r^2/U, r|r|, v|v|` and a constant; :math:`U r, r|r|,
    r^3/U` and a constant without sway; U = 1 without surge), the rudder's as its lift in a propeller slipstream, :math:`\sin\delta` and
    :math:`U^2\sin\delta` (:func:`_rudder_cols`). On the HSVA KVLCC2 zigzags these terms brought the
    runs' own shifts together (their spread ±0.12 s → ±0.04 s) and the held-out equation error
    down by a third against unscaled odd polynomials."""
    if not run.has("delta") or not (run.has("r") or run.has("psi")):
        return None
    dt = run.dt
    uni = run.resample(dt)  # ψ unwrapped
    g = {c: np.asarray(uni[c], dtype=float) for c in ("u", "v", "r", "psi", "delta") if uni.has(c)}
    t = np.asarray(uni.time, dtype=float)
    flt = Filter("savgol", window=max(window_s, 7 * dt))  # a cubic over 1 s, 7 samples at least
    if len(t) < 3 * (int(round(flt.window / dt)) | 1):
        return None
    r = g["r"] if "r" in g else derivative(t, g["psi"], flt, run.name)
    rdot = derivative(t, r, flt, run.name)
    one = np.ones_like(r)
    if "u" in g:
        U = np.hypot(g["u"], g.get("v", 0.0 * one))
        U = np.maximum(U, 0.1 * max(float(U.max()), 1e-9))
    else:
        U = one
    if "v" in g and "u" in g:
        v = g["v"]
        cols = [U * r, U * v, r ** 3 / U, v ** 3 / U, v ** 2 * r / U, v * r ** 2 / U,
                r * np.abs(r), v * np.abs(v), one]
    else:
        cols = [U * r, r * np.abs(r), r ** 3 / U, one]
    return t, np.stack(cols, 1), g["delta"], U, rdot


def _rudder_cols(d: np.ndarray, U: np.ndarray) -> np.ndarray:
    s = np.sin(d)
    return np.stack([s, s * U ** 2], 1)


def _shifted(t, d, tau):
    return np.interp(t - tau, t, d)


def _design(series, edge: float, transform):
    """Stacked regression rows (interior samples: ``edge`` s in from each end) of the runs' yaw
    equations with the rudder transformed by ``transform(t, delta)``."""
    F, y = [], []
    for t, X, d, u2, rdot in series:
        keep = (t >= t[0] + edge) & (t <= t[-1] - edge)
        F.append(np.concatenate([X, _rudder_cols(transform(t, d), u2)], 1)[keep])
        y.append(rdot[keep])
    return np.concatenate(F), np.concatenate(y)


def _fit(series, edge, transform):
    F, y = _design(series, edge, transform)
    c = np.linalg.lstsq(F, y, rcond=None)[0]
    return c, float(np.mean((y - F @ c) ** 2))


def _heldout(series, edge, transform, c) -> float:
    if not series:
        return math.nan
    F, y = _design(series, edge, transform)
    return float(np.sqrt(np.mean((y - F @ c) ** 2)))


def _best_shift(series, edge, taus) -> tuple[float, np.ndarray]:
    """The shift of least equation error (parabola through its grid neighbours) and the mean square
    error at every shift of ``taus``."""
    ssr = np.array([_fit(series, edge, lambda t, d, a=a: _shifted(t, d, a))[1] for a in taus])
    i = int(np.argmin(ssr))
    if 0 < i < len(taus) - 1:
        a, b, c = ssr[i - 1], ssr[i], ssr[i + 1]
        den = a - 2 * b + c
        if den > 0:
            return float(taus[i] + 0.5 * (a - c) / den * (taus[1] - taus[0])), ssr
    return float(taus[i]), ssr


def rudder_timing(train: Sequence[Run], val: Sequence[Run], max_shift: float = 4.0,
                  min_fall: float = 0.05) -> DataFinding | None:
    """The time the yaw acceleration follows the logged rudder (module docstring), or ``None``
    where a run lacks ``delta`` and a yaw rate (``r`` or ``psi``), is too short, or the rudder
    hardly moves in any training run (its spread under 0.5°; such runs are left out)."""
    series = {r.name: _yaw_series(r) for r in list(train) + list(val)}
    # runs whose rudder moves (a straight run or a free decay says nothing about timing)
    series = {k: v for k, v in series.items() if v is not None and np.std(v[2]) >= 0.5 * DEG}
    train = [r for r in train if r.name in series]
    val = [r for r in val if r.name in series]
    runs = train + val
    if not train:
        return None
    dt = min(s[0][1] - s[0][0] for s in series.values())
    span = min(s[0][-1] - s[0][0] for s in series.values())
    m = min(max_shift, span / 10)
    step = max(dt, 2 * m / MAX_SHIFTS)  # fast logs: at most MAX_SHIFTS + 1 shifts, the parabola refines
    edge = m + step
    taus = np.arange(-m, m + 0.5 * step, step)
    tr = [series[r.name] for r in train]
    vl = [series[r.name] for r in val]
    tau, ssr = _best_shift(tr, edge, taus)
    per = {r.name: _best_shift([series[r.name]], edge, taus)[0] for r in runs}
    vals = np.array(list(per.values()))
    se = float(np.std(vals, ddof=1) / math.sqrt(len(vals))) if len(vals) > 1 else math.nan

    def shift(a):
        return lambda t, d: _shifted(t, d, a)
    c0 = _fit(tr, edge, shift(0.0))[0]
    c1 = _fit(tr, edge, shift(tau))[0]
    held = (_heldout(vl, edge, shift(0.0), c0), _heldout(vl, edge, shift(tau), c1))
    found, reason = _verdict(tau, se, len(vals), MIN_TIMING, *held, "the rudder timing", "s", min_fall)
    return DataFinding("rudder_timing", "tau_d", tau, se, "s", per, held, "rad/s² (yaw-acceleration equation error)",
                       f"equation error of a polynomial yaw equation with the rudder shifted, {len(taus)} shifts in "
                       f"±{m:.3g} s", found, reason,
                       (tuple(float(x) for x in taus), tuple(float(x) for x in np.sqrt(ssr))))


def data_checks(train: Sequence[Run], val: Sequence[Run], min_fall: float = 0.05) -> dict[str, DataFinding]:
    """Every check that applies to these runs, by name; ``min_fall``: the smallest relative fall of
    the held-out misfit a finding needs (the model search's ``DiagnoseOptions.min_gain``)."""
    out = {}
    for check in (heading_consistency, rate_consistency, rudder_timing):
        f = check(train, val, min_fall=min_fall)
        if f is not None:
            out[f.effect] = f
    return out


def in_data_line(findings: dict[str, DataFinding]) -> str | None:
    """The verdict's line for the findings (``found`` only), or ``None``."""
    parts = []
    for f in findings.values():
        if not f.found:
            continue
        if f.effect == "rate_bias":
            parts.append(f"rate_bias b_r = {f.shown()} (a yaw-rate zero error: the logged heading against the "
                         f"integrated logged rate; held-out misfit {f.heldout[0] / DEG:.3g} → "
                         f"{f.heldout[1] / DEG:.3g}°; "
                         "no library effect carries it)")
        elif f.effect == "heading_bias":
            parts.append(f"heading_bias b_psi = {f.shown()} (the logged heading against the track and u, v; "
                         f"held-out track misfit {f.heldout[0]:.3g} → {f.heldout[1]:.3g} m)")
        else:
            side = ("the motion follows the logged rudder by that time" if f.value > 0 else
                    f"the logged rudder follows the motion by {-f.value:.3g} s: logged late")
            parts.append(f"rudder timing (input_delay) tau_d = {f.shown()} ({side}: a logging-clock offset"
                         + (", or a steering lag or delay — the model search tells them apart" if f.value > 0 else "")
                         + f"; held-out yaw equation error {f.heldout[0]:.3g} → {f.heldout[1]:.3g} rad/s²)")
    if not parts:
        return None
    return ("In the data: " + "; ".join(parts) + ". Settled from the logs alone, with no hull coefficient: "
            "correct the logs for a measurement error, then refit (the base coefficients absorb it otherwise).")


def corrected(runs: Sequence[Run], findings: dict[str, DataFinding]) -> list[Run]:
    r"""The runs with the *found* measurement errors taken out (new runs; the given ones are not
    changed): the heading :math:`\psi_{log} - b`; the yaw rate :math:`r_{log} - b_r`; the rudder
    re-timed to when the hull answers it,
    :math:`\delta(t) = \delta_{log}(t - \tau)` (held at the first or last logged value past the ends)."""
    hb = findings.get("heading_bias")
    rt = findings.get("rudder_timing")
    rb = findings.get("rate_bias")
    out = []
    for r in runs:
        new = {}
        if hb is not None and hb.found and r.has("psi"):
            new["psi"] = np.asarray(r["psi"], dtype=float) - hb.value
        if rb is not None and rb.found and r.has("r"):
            new["r"] = np.asarray(r["r"], dtype=float) - rb.value
        if rt is not None and rt.found and r.has("delta"):
            t = np.asarray(r.time, dtype=float)
            new["delta"] = np.interp(t - rt.value, t, np.asarray(r["delta"], dtype=float))
        out.append(r.with_channels(**new) if new else r)
    return out


def correction_note(findings: dict[str, DataFinding]) -> str | None:
    """What :func:`corrected` takes out, in words (``None``: nothing found)."""
    parts = [f"{f.effect} {f.parameter} = {f.shown()}" for f in findings.values() if f.found]
    if not parts:
        return None
    return ("the logs were corrected for the data findings before the base fit (--correct-data): "
            + "; ".join(parts) + " taken out")
