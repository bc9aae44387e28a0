r"""Predict standard manoeuvres from a fit: the approach condition, the simulations, IMO metrics.

:func:`predict` takes a fit (a :class:`~diffship.fitfile.LoadedFit` or a fit-file path) and a
list of manoeuvres (:func:`parse_manoeuvre`: ``turning:35``, ``zigzag:10/10``, ``zigzag:20/20``,
``pullout``, ...) and

1. sets the **approach**: speed and propulsion input from ``speed`` / ``inputs`` where given,
   the other one from :func:`diffship.trim.trim` (straight-course equilibrium at zero rudder);
   neither given: the training runs' speed (the fit file's ``operating_point``) and trim;
2. sets the **helm rate**: given; else the rate the training runs' rudder moved at (the fit file's
   ``helm_rate``, :func:`diffship.steering.measured_helm_rate`), so a prediction of the trained
   manoeuvre reproduces it; else :func:`diffship.scaling.helm_rate` (IMO's 2.32°/s × √λ)
   and the autopilot delay, and flies each manoeuvre closed loop
   (:mod:`diffship.manoeuvres.drive`) with the fit's integrator;
3. computes the IMO metrics (:mod:`diffship.manoeuvres.imo`) at model scale and, with a scale
   λ, at full scale by Froude scaling (lengths × λ, times × √λ, angles unchanged), and checks
   the IMO 2002 criteria (:mod:`diffship.predict.criteria`) at full scale;
4. **intervals**: where the fit has a finite covariance Σ of its free parameters, ``samples``
   parameter vectors are drawn from N(θ̂, Σ) (draws outside a parameter's bounds are redrawn
   out; draws whose manoeuvre blows up are counted), all are flown together (vmapped in one
   compiled closed-loop simulation, :mod:`diffship.predict.sampling`) through the same
   manoeuvres, and the 2.5 and 97.5 percentiles of each metric are reported — Monte-Carlo
   propagation of the Gaussian (linearised) parameter uncertainty through the nonlinear
   simulation; model-structure error is not in it.

Models without a track (Nomoto: heading only) get a kinematic track at the constant approach
speed, :math:`\dot x_0 = U\cos\psi,\ \dot y_0 = U\sin\psi` (no speed loss in the turn), and the
report says so.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ..data import Run
from ..errors import DataError, ModelError
from ..fitfile import LoadedFit, fit_warnings, load_fit
from ..manoeuvres import (
    pull_out,
    pullout_metrics,
    side_name,
    side_sign,
    turning_circle,
    turning_metrics,
    zigzag,
    zigzag_metrics,
)
from ..scaling import FroudeScale, helm_rate, model_length
from ..trim import trim
from .criteria import Criterion, check_criteria
from .sampling import draw_parameters, fly_draws, manoeuvre_law

__all__ = [
    "METRIC_KINDS",
    "Condition",
    "ManoeuvrePrediction",
    "ManoeuvreSpec",
    "Prediction",
    "approach",
    "check_inputs",
    "parse_manoeuvre",
    "predict",
]

#: How each metric scales to full scale (``length``: × λ, ``time``: × √λ, ``rate``: ÷ √λ, else unchanged) and its unit.
METRIC_KINDS = {
    "advance": ("length", "m"), "transfer": ("length", "m"), "tactical_diameter": ("length", "m"),
    "steady_diameter": ("length", "m"), "advance_L": ("ratio", "L"), "tactical_diameter_L": ("ratio", "L"),
    "steady_diameter_L": ("ratio", "L"), "time_to_90": ("time", "s"), "time_to_180": ("time", "s"),
    "speed_ratio": ("ratio", "-"),
    "first_overshoot": ("angle", "deg"), "second_overshoot": ("angle", "deg"), "initial_turning_time": ("time", "s"),
    "time_to_check": ("time", "s"), "distance_at_10deg_L": ("ratio", "L"),
    "r_turn": ("rate", "deg/s"), "r_residual": ("rate", "deg/s"),
}


@dataclasses.dataclass(frozen=True)
class ManoeuvreSpec:
    """One standard manoeuvre: ``kind`` (``turning_circle``, ``zigzag``, ``pull_out``), rudder angle
    and switch heading [°], and the side of the first rudder order (+1 starboard, −1 port)."""

    kind: str
    rudder_deg: float
    switch_deg: float | None = None
    side: float = 1.0

    @property
    def key(self) -> str:
        if self.kind == "zigzag":
            return f"zigzag_{self.rudder_deg:g}_{self.switch_deg:g}"
        return f"{'turning' if self.kind == 'turning_circle' else 'pullout'}_{self.rudder_deg:g}"

    @property
    def label(self) -> str:
        side = side_name(self.side)
        if self.kind == "zigzag":
            return f"zigzag {self.rudder_deg:g}/{self.switch_deg:g} ({side} first)"
        what = "turning circle" if self.kind == "turning_circle" else "pull-out"
        return f"{what} {self.rudder_deg:g}° {side}"


_KINDS = {"turning": "turning_circle", "turn": "turning_circle", "turning_circle": "turning_circle",
          "zigzag": "zigzag", "zz": "zigzag", "pullout": "pull_out", "pull_out": "pull_out", "pull-out": "pull_out"}


def parse_manoeuvre(text: str) -> ManoeuvreSpec:
    """``turning:35``, ``turning:35:port``, ``zigzag:10/10``, ``zigzag:20`` (= 20/20),
    ``zigzag:10/10:-1``, ``pullout`` (20°), ``pullout:15:port``; side ``starboard``/``port``/``+1``/``-1``."""
    parts = [p.strip() for p in str(text).split(":")]
    kind = _KINDS.get(parts[0].lower())
    usage = ("expected turning:ANGLE[:SIDE], zigzag:RUDDER/SWITCH[:SIDE] or pullout[:ANGLE][:SIDE], e.g. "
             "turning:35 zigzag:10/10 zigzag:20/20:port pullout")
    if kind is None or len(parts) > 3:
        raise DataError(f"--manoeuvre {text!r}: {usage}")
    try:
        side = side_sign(parts[2]) if len(parts) == 3 else 1.0
    except DataError:
        raise DataError(f"--manoeuvre {text!r}: side {parts[2]!r} is not starboard, port, +1 or -1; {usage}") from None
    default = {"turning_circle": "35", "zigzag": "10/10", "pull_out": "20"}[kind]
    arg = parts[1] if len(parts) > 1 and parts[1] else default
    num = r"(\d+(?:\.\d*)?|\.\d+)"
    m = re.fullmatch(rf"{num}(?:/{num})?", arg)
    if not m and re.fullmatch(rf"-?{num}(?:/-?{num})?", arg):
        raise DataError(f"--manoeuvre {text!r}: a negative angle is not allowed: angles are sizes, and the side of "
                        f"the first rudder order is given after them, e.g. {parts[0]}:{arg.replace('-', '')}:port")
    if not m:
        raise DataError(f"--manoeuvre {text!r}: angle {arg!r} is not a number; {usage}")
    rudder = float(m.group(1))
    if not 0 < rudder <= 45:
        raise DataError(f"--manoeuvre {text!r}: rudder angle {rudder:g}° outside (0, 45]")
    switch = float(m.group(2)) if m.group(2) else (rudder if kind == "zigzag" else None)
    if kind != "zigzag" and m.group(2):
        raise DataError(f"--manoeuvre {text!r}: only a zigzag has a switch heading; {usage}")
    if switch is not None and not 0 < switch <= 90:
        raise DataError(f"--manoeuvre {text!r}: switch heading {switch:g}° outside (0, 90]")
    return ManoeuvreSpec(kind, rudder, switch, side)


@dataclasses.dataclass(frozen=True)
class Condition:
    """Approach condition and simulation settings (model scale, SI; helm rate and delay as used)."""

    speed: float | None
    inputs: dict[str, float]
    approach: str
    helm_rate_deg_s: float
    helm_rate_source: str
    delay_s: float
    scale: float | None
    length: float | None
    dt: float
    duration: dict[str, float]
    notes: tuple[str, ...] = ()

    @property
    def l_over_v(self) -> float | None:
        """L/V [s] at model scale."""
        return self.length / self.speed if self.length and self.speed else None

    @property
    def l_over_v_full(self) -> float | None:
        """L/V [s] at full scale (√λ times the model's; the model's where no scale is given)."""
        lv = self.l_over_v
        return None if lv is None else lv * (math.sqrt(self.scale) if self.scale else 1.0)


@dataclasses.dataclass(frozen=True)
class ManoeuvrePrediction:
    """One manoeuvre: the simulated run, its metrics at model and full scale, and intervals."""

    spec: ManoeuvreSpec
    run: Run
    metrics: dict[str, float]
    full_scale: dict[str, float]
    intervals: dict[str, tuple[float, float]]
    samples_used: int
    samples_failed: int


@dataclasses.dataclass(frozen=True)
class Prediction:
    """What :func:`predict` returns; ``fit``: the fit file's own word on the fit (``usable``, ``converged``, the
    verdict's ``label``: ``None`` where the file has none), which a program reads beside the ``notes``' warnings."""

    model_name: str
    fit_path: str
    condition: Condition
    manoeuvres: tuple[ManoeuvrePrediction, ...]
    criteria: tuple[Criterion, ...]
    criteria_scale: str
    interval_method: str
    notes: tuple[str, ...]
    fit: dict | None = None


def _full(name: str, value: float, scale: FroudeScale | None) -> float:
    kind = METRIC_KINDS.get(name, ("ratio", ""))[0]
    if scale is None or not math.isfinite(value):
        return value
    return {"length": scale.length, "time": scale.time, "rate": scale.rate}.get(kind, lambda x: x)(value)


def _with_track(run: Run, speed: float | None) -> Run:
    """Kinematic track at constant speed for heading-only models (Nomoto)."""
    if run.has("x0", "y0") or speed is None:
        return run
    psi = np.asarray(run["psi"])
    t = run.time
    dx, dy = speed * np.cos(psi), speed * np.sin(psi)
    x0 = np.concatenate([[0.0], np.cumsum(0.5 * (dx[1:] + dx[:-1]) * np.diff(t))])
    y0 = np.concatenate([[0.0], np.cumsum(0.5 * (dy[1:] + dy[:-1]) * np.diff(t))])
    return Run(run.name, run.time, {**run.channels, "x0": x0, "y0": y0, "u": np.full(run.n, speed)},
               {**run.metadata, "kinematic_track": f"constant speed {speed:g} m/s"}, check_units=False)


def _distance_to_second_execute(run: Run, t_second: float, t_first: float) -> float:
    """Distance sailed [m] between the first execute and the second (heading change = switch angle)."""
    sel = (run.time >= t_first) & (run.time <= t_second)
    if not run.has("x0", "y0") or sel.sum() < 2:
        return math.nan
    x, y = np.asarray(run["x0"])[sel], np.asarray(run["y0"])[sel]
    return float(np.sum(np.hypot(np.diff(x), np.diff(y))))


def manoeuvre_metrics(spec: ManoeuvreSpec, run: Run, length: float | None) -> dict[str, float]:
    """The metrics of one simulated manoeuvre (SI; angles and rates in degrees)."""
    nan = math.nan
    if spec.kind == "turning_circle":
        tm = turning_metrics(run, length=length)
        out = {"advance": tm.advance, "transfer": tm.transfer, "tactical_diameter": tm.tactical_diameter,
               "steady_diameter": tm.steady_diameter, "time_to_90": tm.time_to_90, "time_to_180": tm.time_to_180}
        if length:
            out.update(advance_L=tm.advance / length, tactical_diameter_L=tm.tactical_diameter / length,
                       steady_diameter_L=tm.steady_diameter / length)
        if run.has("u") and "kinematic_track" not in run.metadata:
            u = np.asarray(run["u"])
            out["speed_ratio"] = float(np.mean(u[-max(2, run.n // 20):]) / u[0]) if u[0] else nan
        return out
    if spec.kind == "zigzag":
        zm = zigzag_metrics(run, switch_deg=spec.switch_deg, rudder_deg=spec.rudder_deg)
        out = {"first_overshoot": zm.first_overshoot, "second_overshoot": zm.second_overshoot,
               "initial_turning_time": zm.initial_turning_time, "time_to_check": zm.time_to_check}
        if length and spec.switch_deg == 10:
            out["distance_at_10deg_L"] = (_distance_to_second_execute(run, zm.execute_times[0], zm.t_execute) / length
                                          if zm.execute_times else nan)
        return out
    pm = pullout_metrics(run)
    return {"r_turn": math.degrees(pm["r_turn"]), "r_residual": math.degrees(pm["r_residual"])}


def check_inputs(model, inputs: Mapping[str, float], option: str = "--input") -> None:
    """Constant inputs must be the model's, other than the rudder (each manoeuvre sets it): a :class:`DataError`
    naming the first that is not."""
    others = [n for n in model.input_names if n != "delta"]
    have = f"its constant inputs: {', '.join(others)}" if others else f"model {model.name} has no constant input"
    for k in inputs:
        if k == "delta":
            raise DataError(f"{option} delta: the rudder angle is set by each manoeuvre (--manoeuvre), not held "
                            f"constant; {option} is for the model's other inputs ({have})")
        if k not in model.input_names:
            raise DataError(f"{option} {k}: model {model.name} has no input {k!r} ({have})")


def approach(fit: LoadedFit, *, speed: float | None = None, inputs: Mapping[str, float] | None = None
             ) -> tuple[float | None, dict[str, float], str]:
    """Approach speed and constant inputs (model scale) and a sentence saying where they come from."""
    model = fit.model
    inputs = {k: float(v) for k, v in (inputs or {}).items()}
    check_inputs(model, inputs)
    others = [n for n in model.input_names if n != "delta"]
    op = fit.operating_point
    if "u" not in model.state_names:
        missing = [n for n in others if n not in inputs]
        if missing:
            raise ModelError(f"model {model.name}: give its input(s) {', '.join(missing)}")
        if speed is None and "u" in op:
            speed = float(op["u"])
            return speed, inputs, f"speed {speed:.4g} m/s from the training runs (for the track only)"
        how = f"speed {speed:.4g} m/s given (for the track only)" if speed else "no speed: no track"
        return speed, inputs, how
    if speed is not None and all(n in inputs for n in others):
        tr = trim(model, inputs=inputs)
        return speed, inputs, (f"speed {speed:.4g} m/s and {', '.join(f'{k} = {v:.4g}' for k, v in inputs.items())} "
                               f"given (the model's equilibrium at these inputs is {tr.speed:.4g} m/s)")
    if speed is not None:
        tr = trim(model, speed=speed)
        return speed, tr.inputs, f"speed {speed:.4g} m/s given; {tr.status} (trim)"
    if inputs and all(n in inputs for n in others):
        tr = trim(model, inputs=inputs)
        return tr.speed, tr.inputs, f"{tr.status} (trim at the given inputs)"
    if "u" in op:
        tr = trim(model, speed=float(op["u"]))
        return tr.speed, tr.inputs, (f"speed {tr.speed:.4g} m/s: the training runs' approach speed; {tr.status} "
                                     "(trim)")
    raise ModelError(f"model {model.name}: give the approach speed (--speed) or its input(s) {', '.join(others)} "
                     "(--rps); the fit file has no training speed")


def _fly(model, spec: ManoeuvreSpec, cond: Condition, integrator, fixed_duration: float | None = None) -> Run:
    initial = {"u": cond.speed} if "u" in model.state_names else {}
    inputs = {k: v for k, v in cond.inputs.items() if k != "delta"}
    kw = {"rudder_deg": spec.rudder_deg, "first": spec.side, "inputs": inputs, "dt": cond.dt, "t_execute": cond.dt,
          "rudder_rate_deg_s": cond.helm_rate_deg_s, "integrator": integrator}
    dur = fixed_duration or cond.duration[spec.kind]
    if spec.kind == "turning_circle":
        for _ in range(4):  # long enough for 450° of heading change (steady diameter over ≥ 180° of arc)
            run = turning_circle(model, initial, duration=dur, **kw)
            turned = abs(float(np.unwrap(np.asarray(run["psi"]))[-1] - float(run["psi"][0])))
            if turned >= math.radians(460.0) or fixed_duration is not None:
                break
            dur *= 2.0
    elif spec.kind == "zigzag":
        run = zigzag(model, initial, switch_deg=spec.switch_deg, duration=dur, switch_delay_s=cond.delay_s, **kw)
    else:
        run = pull_out(model, initial, turn_s=dur / 2, settle_s=dur / 2, **kw)
    return _with_track(run, cond.speed)


def _durations(length, speed, duration) -> tuple[dict[str, float], float, str | None]:
    if duration:
        d = float(duration)
        return {"turning_circle": d, "zigzag": d, "pull_out": d}, d / 1000.0, None
    if length and speed:
        lv = length / speed
        # step L/V/200: the zigzag autopilot looks at the heading once per step, so a coarser step
        # reverses the rudder late (L/V/50 added +0.18° to a 20/20 and +0.22° to a 10/10 first
        # overshoot, more than their 95 % intervals' half-width; benchmarks/results/coverage_metrics*.md)
        return ({"turning_circle": 45 * lv, "zigzag": 40 * lv, "pull_out": 50 * lv}, lv / 200.0, None)
    return ({"turning_circle": 300.0, "zigzag": 200.0, "pull_out": 300.0}, 0.1,
            ("no ship length or speed: durations 300 s (turning, pull-out) and 200 s (zigzag), dt 0.1 s; "
             "set --duration"))


_EXTRAPOLATION = {"r": ("yaw rate", "deg/s", 180.0 / math.pi), "v": ("sway speed", "m/s", 1.0),
                  "delta": ("rudder angle", "deg", 180.0 / math.pi)}


def extrapolation(fit: LoadedFit, spec: ManoeuvreSpec, run: Run, margin: float = 1.1) -> str | None:
    """A sentence when the manoeuvre leaves the range of the training runs (|r|, |v|, |δ| beyond
    ``margin`` times the largest measured), else ``None``."""
    over = []
    for c, (what, unit, k) in _EXTRAPOLATION.items():
        rng = fit.data_ranges.get(c)
        if rng is None or not run.has(c):
            continue
        seen = max(abs(rng[0]), abs(rng[1]))
        top = float(np.max(np.abs(np.asarray(run[c]))))
        if top > margin * seen:
            over.append(f"|{c}| up to {top * k:.3g} {unit} (training runs: ≤ {seen * k:.3g})")
    if not over:
        return None
    return (f"{spec.label} is an EXTRAPOLATION: {', '.join(over)}; its metrics rest on the model outside the "
            "data it was fitted to, which the intervals do not cover")


def _draw(fit: LoadedFit, n: int, seed: int) -> tuple[np.ndarray, str]:
    names = fit.covariance_names
    mean = np.asarray([fit.params[k] for k in names])
    draws = draw_parameters(fit.model, names, mean, fit.covariance, n, seed)
    return draws, (f"{n} parameter sets drawn from N(θ̂, Σ) of the {len(names)} free parameters "
                   "(Monte Carlo through the nonlinear manoeuvre simulation, all draws in one vmapped compiled "
                   "simulation; draws outside bounds "
                   "redrawn); intervals: 2.5–97.5 percentiles; parameter uncertainty only (not "
                   "model-structure error)")


def _fly_draws(fit: LoadedFit, spec: ManoeuvreSpec, cond: Condition, draws: np.ndarray, duration: float
               ) -> list[Run | None]:
    """The draws flown through ``spec`` as :func:`_fly` flies one model with ``fixed_duration``, vmapped."""
    model = fit.model
    initial = {"u": cond.speed} if "u" in model.state_names else {}
    inputs = {k: v for k, v in cond.inputs.items() if k != "delta"}
    turn_s = duration / 2 if spec.kind == "pull_out" else None
    total = cond.dt + duration if spec.kind == "pull_out" else duration
    law = manoeuvre_law(model, spec.kind, rudder_deg=spec.rudder_deg, side=spec.side, t_execute=cond.dt,
                        initial=initial, switch_deg=spec.switch_deg, delay_s=cond.delay_s, turn_s=turn_s)
    meta = {"manoeuvre": spec.kind, "t_release": cond.dt + turn_s} if turn_s else {"manoeuvre": spec.kind}
    runs = fly_draws(model, fit.covariance_names, draws, law, initial=initial, inputs=inputs, duration=total,
                     dt=cond.dt, rudder_rate_deg_s=cond.helm_rate_deg_s, integrator=fit.integrator, metadata=meta)
    return [None if r is None else _with_track(r, cond.speed) for r in runs]


def predict(fit: LoadedFit | str | Path, manoeuvres: Sequence[str | ManoeuvreSpec], *, speed: float | None = None,
            inputs: Mapping[str, float] | None = None, scale: float | None = None, length: float | None = None,
            helm_rate_deg_s: float | None = None, delay_s: float | None = None, duration: float | None = None,
            samples: int = 40, seed: int = 0) -> Prediction:
    """Fly standard manoeuvres with a fitted model (see the module docstring).

    Args:
        fit: a :class:`~diffship.fitfile.LoadedFit` or the path of a fit file.
        manoeuvres: specs or strings for :func:`parse_manoeuvre`.
        speed: approach speed [m/s] at the fit's scale; inputs: constant inputs (e.g. ``{"n": 10.23}``).
        scale: λ = L_full / L_model; default the fit file's ``ship.model_scale`` (``None``: no full scale).
        length: ship length [m] at the fit's scale (default the model's ``L``).
        helm_rate_deg_s: steering-gear rate [°/s] at the fit's scale (default
            :func:`diffship.scaling.helm_rate`); delay_s: autopilot delay [s] of the zigzag (default:
            the median delay measured in the training zigzags, ``training_manoeuvres[].switch_delay_s``,
            else 0).
        duration: simulated time per manoeuvre [s] (default 40–50 L/V).
        samples: parameter draws for the intervals (0: none).
    """
    fit = fit if isinstance(fit, LoadedFit) else load_fit(fit)
    model = fit.model
    specs = [m if isinstance(m, ManoeuvreSpec) else parse_manoeuvre(m) for m in manoeuvres]
    if not specs:
        raise DataError("no manoeuvre given: e.g. --manoeuvre turning:35 zigzag:10/10 zigzag:20/20")
    notes = list(fit_warnings(fit))
    vessel = fit.document.get("vessel") or {}
    if scale is None and fit.ship.get("model_scale"):
        scale = float(fit.ship["model_scale"])
        notes.append(f"scale λ = {scale:g} from the fit file's training data (ship.model_scale)")
    elif scale is None and vessel.get("scale") and float(vessel["scale"]) != 1.0:
        scale = float(vessel["scale"])
        notes.append(f"scale λ = {scale:g} from the vessel file of the fit ({vessel.get('name')})")
    length = length or model_length(model)
    sp, inp, how = approach(fit, speed=speed, inputs=inputs)
    measured_rate = fit.document.get("helm_rate") or {}
    if helm_rate_deg_s is None and measured_rate.get("deg_s"):
        rate, rate_src = float(measured_rate["deg_s"]), (
            f"measured in the training runs ({measured_rate.get('source', 'fit file')}; --helm-rate to change)")
    else:
        rate, rate_src = helm_rate(model, rudder_rate_deg_s=helm_rate_deg_s, scale=scale, length=length)
    if delay_s is None:
        measured = [float(m["switch_delay_s"]) for m in fit.document.get("training_manoeuvres") or ()
                    if m.get("switch_delay_s") is not None]
        delay_s = float(np.median(measured)) if measured else 0.0
        if measured:
            notes.append(f"zigzag switch delay {delay_s:.3g} s: measured in the training zigzags (--delay to change)")
    durs, dt, dnote = _durations(length, sp, duration)
    if dnote:
        notes.append(dnote)
    if "u" not in model.state_names:
        notes.append(f"model {model.name} has no surge speed: the track is kinematic at the constant speed "
                     f"{sp:.4g} m/s (no speed loss in the turn)" if sp else f"model {model.name}: no speed, no track")
    cond = Condition(sp, inp, how, rate, rate_src, float(delay_s), scale, length, dt, durs)
    fscale = FroudeScale(scale) if scale else None
    has_cov = fit.has_covariance and samples > 0
    draws, method = _draw(fit, samples, seed) if has_cov else (np.zeros((0, 0)), "")
    if not has_cov:
        method = ("no intervals: the fit file has no finite covariance" if samples > 0 else "no intervals (samples=0)")
    out, by_key = [], {}
    for spec in specs:
        if spec.kind == "turning_circle" and not (model_length(model) or sp):
            raise ModelError(f"{spec.label}: model {model.name} has no track; give --speed for a kinematic track")
        run = _fly(model, spec, cond, fit.integrator)
        met = manoeuvre_metrics(spec, run, length)
        extra = extrapolation(fit, spec, run)
        if extra:
            notes.append(extra)
        samp, failed = [], 0
        for r in _fly_draws(fit, spec, cond, draws, run.duration) if len(draws) else []:
            try:
                if r is None:
                    raise ModelError("blew up")
                samp.append(manoeuvre_metrics(spec, r, length))
            except (ModelError, DataError):
                failed += 1
        intervals = {}
        for k in met:
            v = np.asarray([s.get(k, math.nan) for s in samp], dtype=np.float64)
            v = v[np.isfinite(v)]
            if v.size >= max(5, len(samp) // 2):
                intervals[k] = (float(np.percentile(v, 2.5)), float(np.percentile(v, 97.5)))
        full = {k: _full(k, v, fscale) for k, v in met.items()}
        mp = ManoeuvrePrediction(spec, run, met, full, intervals, len(samp), failed)
        out.append(mp)
        if (spec.kind == "turning_circle" and spec.rudder_deg == 35) or spec.kind == "zigzag":
            key = "turning_35" if spec.kind == "turning_circle" else spec.key
            worst = by_key.setdefault(key, {})
            for k, v in met.items():  # several sides: the worst counts
                if math.isfinite(v):
                    worst[k] = max(worst.get(k, -math.inf), v)
    crit = check_criteria(by_key, cond.l_over_v_full)
    where = (f"full scale (λ = {scale:g}: L/V = {cond.l_over_v_full:.3g} s)" if scale and cond.l_over_v_full
             else "the fit's scale (no --scale given: L/V is the model's, the criteria are for the full-scale ship)")
    said = {"usable": fit.document.get("usable"), "converged": fit.converged,
            "verdict": (fit.document.get("verdict") or {}).get("label")}
    return Prediction(model.name, str(fit.path), cond, tuple(out), tuple(crit), where, method,
                      tuple(notes + [f"helm rate {rate:.3g}°/s at the fit's scale: {rate_src}"]), said)
