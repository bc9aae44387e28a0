r"""Standard manoeuvres (zigzag, turning circle, pull-out, spiral) and the IMO metrics.

**Simulating a manoeuvre.** Any model whose inputs include ``delta`` can be driven; its other
inputs are held at given constants (e.g. ``{"n": 10.23}`` rev/s). The steering gear is part
of the closed loop: the rudder angle δ is an extra (discrete-time) state that moves towards
the commanded angle at most ``rudder_rate`` per second and never beyond ``max_rudder``,

.. math::
    \delta_{k+1} = \operatorname{clip}\big(\delta_k + \operatorname{clip}(\delta^c_k - \delta_k,
    -\dot\delta_{\max} h, \dot\delta_{\max} h), -\delta_{\max}, \delta_{\max}\big),

and the ship is integrated over each step with RK4 and δ interpolated linearly from
:math:`\delta_k` to :math:`\delta_{k+1}` (the same first-order hold as measured inputs get in
:func:`diffship.simulate.simulate`). The command :math:`\delta^c` comes from a *steering law*:

* zigzag (:class:`ZigzagLaw`): the target rudder angle is latched in the state; it is
  ``side·δ_z`` from the execute time on and flips to ``−δ_z`` when the heading change
  :math:`\psi - \psi_0` reaches ``+ψ_s`` and to ``+δ_z`` when it reaches ``−ψ_s``, optionally
  after an autopilot delay (the time of the pending switch is latched too; ``jnp.where`` only,
  no Python control flow on traced values);
* schedules (:class:`ScheduleLaw`): a piecewise-constant rudder order in time — the turning
  circle (0 then δ), the pull-out (0, δ, 0) and the spiral (a staircase of δ).

Everything is one :func:`jax.lax.scan`, works under ``jax.jit`` and is differentiable with
respect to the model parameters (:func:`closed_loop`). The user-facing builders return a
:class:`~diffship.data.Run` with the same channels as measured data (the model outputs,
``delta`` and the constant inputs) and the metadata of :func:`diffship.data.kvlcc2_runs`
(``manoeuvre``, ``rudder_angle_deg``, ``switch_heading_deg``, ``first_rudder``), so metrics
are computed identically on simulated and measured runs.

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
from collections.abc import Mapping, Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .data import Run
from .errors import DataError, ModelError
from .integrators import RK4, AbstractIntegrator
from .models._base import AbstractModel
from .simulate import MAX_ABS

__all__ = [
    "ZigzagLaw", "ScheduleLaw", "closed_loop", "zigzag", "turning_circle", "pull_out", "spiral",
    "ZigzagMetrics", "TurningMetrics", "SpiralResult", "zigzag_metrics", "turning_metrics",
    "pullout_metrics", "imo_metrics", "first_execute",
]


# ----------------------------------------------------------------------------------------
# steering laws
# ----------------------------------------------------------------------------------------
class ZigzagLaw(eqx.Module):
    """Zigzag autopilot: rudder ``side·rudder`` from ``t_execute``, reversed at ``±switch``.

    All angles in radians; ``side`` is +1 (first rudder to starboard) or −1 (port); ``delay``
    [s] is the time between the heading reaching the switch angle and the rudder order (0 for
    the ideal IMO manoeuvre; about 0.3 s for the HSVA autopilot). The latch holds the current
    target rudder angle (0 before the execute) and the time the pending switch was detected
    (``NEVER`` when none is pending).
    """

    rudder: Float[Array, ""]
    switch: Float[Array, ""]
    side: Float[Array, ""]
    t_execute: Float[Array, ""]
    psi0: Float[Array, ""]
    delay: Float[Array, ""] = eqx.field(default_factory=lambda: jnp.zeros(()))

    NEVER = 1e30

    def init_latch(self):
        return jnp.array([0.0, self.NEVER])

    def __call__(self, t, psi, latch):
        target, t_hit = latch[0], latch[1]
        target = jnp.where((t >= self.t_execute) & (target == 0.0), self.side * self.rudder, target)
        h = psi - self.psi0
        crossed = ((target > 0.0) & (h >= self.switch)) | ((target < 0.0) & (h <= -self.switch))
        t_hit = jnp.where(crossed & (t_hit >= self.NEVER), t, t_hit)
        flip = t >= t_hit + self.delay
        target = jnp.where(flip, -target, target)
        t_hit = jnp.where(flip, self.NEVER, t_hit)
        return target, jnp.stack([target, t_hit])


class ScheduleLaw(eqx.Module):
    """Piecewise-constant rudder order: ``levels[i]`` from ``times[i]`` on, 0 before ``times[0]``."""

    times: Float[Array, " k"]
    levels: Float[Array, " k"]

    def __call__(self, t, psi, latch):
        i = jnp.clip(jnp.sum(t >= self.times) - 1, 0, self.levels.shape[0] - 1)
        target = jnp.where(t >= self.times[0], self.levels[i], 0.0)
        return target, latch

    def init_latch(self):
        return jnp.zeros(())


# ----------------------------------------------------------------------------------------
# closed-loop simulation
# ----------------------------------------------------------------------------------------
def _input_slots(model: AbstractModel, inputs: Mapping[str, float]) -> tuple[int, np.ndarray]:
    names = tuple(model.input_names)
    if "delta" not in names:
        raise ModelError(f"model {model.name} has inputs {names}: a manoeuvre needs a rudder input 'delta'")
    missing = [n for n in names if n != "delta" and n not in inputs]
    if missing:
        raise ModelError(f"model {model.name}: give constant values for its input(s) {', '.join(missing)} "
                         f"(e.g. inputs={{'{missing[0]}': ...}})")
    unknown = set(inputs) - set(names)
    if unknown:
        raise ModelError(f"model {model.name} has no input(s) {', '.join(sorted(unknown))}; its inputs are {names}")
    return names.index("delta"), np.array([float(inputs.get(n, 0.0)) for n in names], dtype=np.float64)


@eqx.filter_jit
def closed_loop(model: AbstractModel, law, ts: Float[Array, " N"], x0: Float[Array, " n_x"],
                u_const: Float[Array, " n_u"], delta_index: int, rudder_rate: Float[Array, ""],
                max_rudder: Float[Array, ""], delta_start: Float[Array, ""],
                integrator: AbstractIntegrator = RK4(substeps=2)):
    """Simulate ``model`` under a steering law with a rate-limited, saturated rudder.

    Pure JAX (jit-compiled, differentiable in the model parameters). Returns
    ``(xs, deltas, valid)``: states ``(N, n_x)``, actual rudder angles ``(N,)`` and the
    blow-up flag of :func:`diffship.simulate.simulate` (state frozen after a blow-up).
    ``delta_index`` is the position of ``delta`` in ``model.input_names`` (static). Between
    samples the rudder moves linearly from its value to the rate-limited target, and the state
    is advanced by ``integrator`` (the same :meth:`~diffship.integrators.AbstractIntegrator.interval`
    as every other simulation).
    """
    psi_i = model.state_names.index("psi")
    ts = jnp.asarray(ts, dtype=jnp.float64)

    def inp(delta):
        return u_const.at[delta_index].set(delta)

    def step(carry, tt):
        x, delta, latch, good = carry
        t0, t1 = tt
        h = t1 - t0
        target, latch = law(t0, x[psi_i], latch)
        target = jnp.clip(target, -max_rudder, max_rudder)
        d1 = delta + jnp.clip(target - delta, -rudder_rate * h, rudder_rate * h)
        d1 = jnp.clip(d1, -max_rudder, max_rudder)
        y = integrator.interval(model.vector_field, t0, t1, x, inp(delta), inp(d1))
        good = good & jnp.all(jnp.isfinite(y)) & jnp.all(jnp.abs(y) < MAX_ABS)
        y = jnp.where(good, y, x)
        return (y, d1, latch, good), (y, d1, good)

    carry0 = (x0, delta_start, law.init_latch(), jnp.array(True))
    _, (xs, ds, valid) = jax.lax.scan(step, carry0, (ts[:-1], ts[1:]))
    xs = jnp.concatenate([x0[None], xs])
    ds = jnp.concatenate([delta_start[None], ds])
    valid = jnp.concatenate([jnp.array([True]), valid])
    return xs, ds, valid


def _x0_vector(model: AbstractModel, initial) -> np.ndarray:
    if isinstance(initial, Mapping):
        unknown = set(initial) - set(model.state_names)
        if unknown:
            raise ModelError(f"model {model.name}: initial values for unknown state(s) {', '.join(sorted(unknown))}; "
                             f"its states are {model.state_names}")
        return np.asarray(model.initial_state(initial), dtype=np.float64)
    x0 = np.asarray(initial, dtype=np.float64)
    if x0.shape != (len(model.state_names),):
        raise ModelError(f"model {model.name}: initial state must have {len(model.state_names)} entries "
                         f"{model.state_names}, got shape {x0.shape}")
    return x0


def _run_manoeuvre(model, law, *, initial, inputs, duration, dt, rudder_rate_deg_s, max_rudder_deg,
                   integrator, name, metadata) -> Run:
    d_idx, u_const = _input_slots(model, inputs)
    x0 = _x0_vector(model, initial)
    ts = np.arange(0.0, duration + 0.5 * dt, dt)
    xs, ds, valid = closed_loop(model, law, jnp.asarray(ts), jnp.asarray(x0), jnp.asarray(u_const), d_idx,
                                jnp.asarray(math.radians(rudder_rate_deg_s)), jnp.asarray(math.radians(max_rudder_deg)),
                                jnp.asarray(0.0), integrator)
    xs, ds, valid = np.asarray(xs), np.asarray(ds), np.asarray(valid)
    us = np.repeat(u_const[None], len(ts), axis=0)
    us[:, d_idx] = ds
    ys = np.asarray(jax.vmap(model.observe)(jnp.asarray(xs), jnp.asarray(us)))
    channels = {c: ys[:, j] for j, c in enumerate(model.output_names)}
    for j, n in enumerate(model.input_names):
        channels[n] = us[:, j]
    meta = {"simulated": True, "model": model.name, "rudder_rate_deg_s": rudder_rate_deg_s,
            "max_rudder_deg": max_rudder_deg, "valid": bool(valid.all()), **metadata}
    if not valid.all():
        t_bad = float(ts[int(np.argmin(valid))])
        raise ModelError(f"model {model.name}: the {metadata.get('manoeuvre', 'manoeuvre')} simulation blows up "
                         f"at t = {t_bad:.1f} s; check the parameters or shorten the manoeuvre")
    return Run(name, ts, channels, meta, check_units=False)


def _side(first: str) -> float:
    if first not in ("starboard", "port"):
        raise ModelError(f"first rudder side must be 'starboard' or 'port', got {first!r}")
    return 1.0 if first == "starboard" else -1.0


def zigzag(model: AbstractModel, initial, *, rudder_deg: float = 10.0, switch_deg: float | None = None,
           first: str = "starboard", inputs: Mapping[str, float] | None = None, duration: float = 100.0,
           dt: float = 0.1, t_execute: float = 0.0, rudder_rate_deg_s: float = 2.32, max_rudder_deg: float = 35.0,
           switch_delay_s: float = 0.0, integrator: AbstractIntegrator = RK4(substeps=2), name: str | None = None) -> Run:
    """Simulate a ``rudder_deg``/``switch_deg`` zigzag (switch defaults to the rudder angle).

    Args:
        model: any model with a ``delta`` input and a ``psi`` state.
        initial: initial state (mapping of state names, e.g. ``{"u": 1.179}``, or a vector).
        first: side of the first rudder order, ``"starboard"`` or ``"port"``.
        inputs: constant values of the model's other inputs (e.g. ``{"n": 10.23}``).
        duration, dt: simulated time and sample interval [s].
        t_execute: time of the first rudder order [s].
        rudder_rate_deg_s: steering-gear rate [°/s] (IMO: ≥ 2.32 °/s at full scale).
        max_rudder_deg: rudder saturation [°].
        switch_delay_s: autopilot delay between the heading reaching ±ψ_s and the rudder order [s].
    """
    switch_deg = rudder_deg if switch_deg is None else switch_deg
    psi0 = float(_x0_vector(model, initial)[model.state_names.index("psi")])
    law = ZigzagLaw(*(jnp.asarray(v, dtype=jnp.float64) for v in (
        math.radians(rudder_deg), math.radians(switch_deg), _side(first), t_execute, psi0, switch_delay_s)))
    tag = f"{rudder_deg:g}/{switch_deg:g} zigzag ({first} first)"
    return _run_manoeuvre(model, law, initial=initial, inputs=inputs or {}, duration=duration, dt=dt,
                          rudder_rate_deg_s=rudder_rate_deg_s, max_rudder_deg=max_rudder_deg, integrator=integrator,
                          name=name or f"{model.name} {tag}",
                          metadata={"manoeuvre": "zigzag", "rudder_angle_deg": float(rudder_deg),
                                    "switch_heading_deg": float(switch_deg), "first_rudder": first,
                                    "t_execute": float(t_execute), "switch_delay_s": float(switch_delay_s)})


def _schedule(times, levels_deg):
    return ScheduleLaw(jnp.asarray(times, dtype=jnp.float64), jnp.asarray(np.radians(levels_deg), dtype=jnp.float64))


def turning_circle(model: AbstractModel, initial, *, rudder_deg: float = 35.0, first: str = "starboard",
                   inputs: Mapping[str, float] | None = None, duration: float = 300.0, dt: float = 0.1,
                   t_execute: float = 0.0, rudder_rate_deg_s: float = 2.32, max_rudder_deg: float = 35.0,
                   integrator: AbstractIntegrator = RK4(substeps=2), name: str | None = None) -> Run:
    """Simulate a turning circle: straight until ``t_execute``, then ``rudder_deg`` to ``first``."""
    s = _side(first)
    law = _schedule([t_execute], [s * rudder_deg])
    return _run_manoeuvre(model, law, initial=initial, inputs=inputs or {}, duration=duration, dt=dt,
                          rudder_rate_deg_s=rudder_rate_deg_s, max_rudder_deg=max_rudder_deg, integrator=integrator,
                          name=name or f"{model.name} {rudder_deg:g} deg turning circle ({first})",
                          metadata={"manoeuvre": "turning_circle", "rudder_angle_deg": float(rudder_deg),
                                    "first_rudder": first, "t_execute": float(t_execute)})


def pull_out(model: AbstractModel, initial, *, rudder_deg: float = 20.0, first: str = "starboard",
             inputs: Mapping[str, float] | None = None, turn_s: float = 120.0, settle_s: float = 120.0,
             dt: float = 0.1, t_execute: float = 0.0, rudder_rate_deg_s: float = 2.32,
             max_rudder_deg: float = 35.0, integrator: AbstractIntegrator = RK4(substeps=2), name: str | None = None) -> Run:
    """Simulate a pull-out: ``rudder_deg`` for ``turn_s`` seconds (steady turn), then rudder to 0."""
    s = _side(first)
    t_release = t_execute + turn_s
    law = _schedule([t_execute, t_release], [s * rudder_deg, 0.0])
    return _run_manoeuvre(model, law, initial=initial, inputs=inputs or {}, duration=t_release + settle_s, dt=dt,
                          rudder_rate_deg_s=rudder_rate_deg_s, max_rudder_deg=max_rudder_deg, integrator=integrator,
                          name=name or f"{model.name} {rudder_deg:g} deg pull-out ({first})",
                          metadata={"manoeuvre": "pull_out", "rudder_angle_deg": float(rudder_deg),
                                    "first_rudder": first, "t_execute": float(t_execute),
                                    "t_release": float(t_release)})


@dataclasses.dataclass(frozen=True)
class SpiralResult:
    """Steady yaw rate per rudder step of a spiral test (Dieudonné)."""

    delta_deg: np.ndarray  #: rudder angle of each step [°]
    r_steady: np.ndarray  #: mean yaw rate over the last ``average_fraction`` of each step [rad/s]
    run: Run  #: the whole simulated record


def spiral(model: AbstractModel, initial, *, rudder_deg: Sequence[float] = (15, 10, 5, 2, 0, -2, -5, -10, -15),
           hold_s: float = 120.0, average_fraction: float = 0.25, inputs: Mapping[str, float] | None = None,
           dt: float = 0.2, rudder_rate_deg_s: float = 2.32, max_rudder_deg: float = 35.0, integrator: AbstractIntegrator = RK4(substeps=2),
           name: str | None = None) -> SpiralResult:
    """Simulate a (direct) spiral: rudder steps held ``hold_s`` each; steady r per step.

    Run the sequence down and up again (e.g. ``(15, ..., -15, ..., 15)``) to see a hysteresis
    loop of a directionally unstable ship.
    """
    levels = np.asarray(rudder_deg, dtype=np.float64)
    times = np.arange(len(levels)) * hold_s
    law = _schedule(times, levels)
    run = _run_manoeuvre(model, law, initial=initial, inputs=inputs or {}, duration=len(levels) * hold_s, dt=dt,
                         rudder_rate_deg_s=rudder_rate_deg_s, max_rudder_deg=max_rudder_deg, integrator=integrator,
                         name=name or f"{model.name} spiral", metadata={"manoeuvre": "spiral", "hold_s": hold_s})
    run.require("r", "the spiral test's steady yaw rates")
    r = run["r"]
    out = []
    for t0 in times:
        sel = (run.time >= t0 + (1.0 - average_fraction) * hold_s) & (run.time <= t0 + hold_s)
        out.append(float(np.mean(r[sel])))
    return SpiralResult(levels, np.asarray(out), run)


# ----------------------------------------------------------------------------------------
# metrics
# ----------------------------------------------------------------------------------------
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
    """Index of the first rudder execute and the side (+1 starboard, −1 port)."""
    run.require(("delta",), "finding the first rudder execute")
    d = np.asarray(run["delta"], dtype=np.float64)
    d = d - d[0]
    amp = float(np.max(np.abs(d)))
    if amp < math.radians(0.5):
        raise DataError(f"run '{run.name}': the rudder never moves by more than 0.5 deg; no manoeuvre to measure")
    half = int(np.argmax(np.abs(d) >= 0.5 * amp))
    side = float(np.sign(d[half]))
    small = np.nonzero(np.abs(d[: half + 1]) <= 0.1 * amp)[0]
    return (int(small[-1]) if small.size else 0), side


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
    rudder angle in the record.
    """
    run.require(("psi", "delta"), "zigzag metrics")
    switch_deg = switch_deg if switch_deg is not None else run.metadata.get("switch_heading_deg")
    if switch_deg is None:
        raise DataError(f"run '{run.name}': give switch_deg (the heading change at which the rudder is reversed); "
                        "it is not in the run's metadata")
    if rudder_deg is None:
        rudder_deg = run.metadata.get("rudder_angle_deg", float(np.degrees(np.max(np.abs(run["delta"])))))
    t = np.asarray(run.time, dtype=np.float64)
    i0, side = first_execute(run)
    psi = _smooth(np.unwrap(np.asarray(run["psi"], dtype=np.float64)), run.dt, smooth_s)
    psi0 = float(psi[i0])
    h = np.degrees(side * (psi - psi0))
    s = float(switch_deg)
    executes, crossing_idx = [], []
    sign, i = 1.0, i0
    while True:  # hysteresis: look for +s, then −s, then +s, ...
        hit = np.nonzero(sign * h[i:] >= s)[0]
        if not hit.size:
            break
        i = i + int(hit[0])
        executes.append(_crossing_time(t, sign * h, i, s))
        crossing_idx.append(i)
        sign = -sign
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


def turning_metrics(run: Run, *, length: float | None = None, smooth_s: float = 0.0) -> TurningMetrics:
    """IMO turning-circle metrics of a Run with ``time, x0, y0, psi, delta`` (see module docstring)."""
    run.require(("x0", "y0", "psi", "delta"), "turning-circle metrics")
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
