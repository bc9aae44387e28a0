r"""Simulated standard manoeuvres: zigzag, turning circle, pull-out, spiral (closed loop).

**Simulating a manoeuvre.** Any model whose inputs include ``delta`` can be driven; its other
inputs are held at given constants (e.g. ``{"n": 10.23}`` rev/s). The steering gear is part
of the closed loop: the rudder angle δ is an extra (discrete-time) state that moves towards
the commanded angle at most ``rudder_rate`` per second and never beyond ``max_rudder``,

.. math::
    \delta_{k+1} = \operatorname{clip}\big(\delta_k + \operatorname{clip}(\delta^c_k - \delta_k,
    -\dot\delta_{\max} h, \dot\delta_{\max} h), -\delta_{\max}, \delta_{\max}\big),

and the ship is integrated over each step (by default diffrax's RK4 tableau, two steps per
sample: :mod:`diffship.integrators`) with δ interpolated linearly from
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
"""


from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ..compiled import compiled
from ..data import Run
from ..errors import ModelError
from ..integrators import AbstractIntegrator, Diffrax
from ..models import AbstractModel
from ..scaling import helm_rate
from ..simulate import MAX_ABS
from .imo import side_name, side_sign

__all__ = ["ZigzagLaw", "ScheduleLaw", "closed_loop", "zigzag", "turning_circle", "pull_out", "spiral", "SpiralResult"]


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
                integrator: AbstractIntegrator = Diffrax(substeps=2)):
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
    if getattr(integrator, "hold", "linear") != "linear":
        # the simulated steering gear moves the rudder continuously (rate-limited): linear between samples,
        # whatever convention the fit read its logged inputs with
        integrator = dataclasses.replace(integrator, hold="linear")

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


class _Manoeuvre(eqx.Module):
    """Compile-cache owner of one closed-loop manoeuvre program (:func:`closed_loop` and the
    outputs): compiled once per structure and kept between processes (:mod:`diffship.compiled`)."""

    delta_index: int = eqx.field(static=True)
    integrator: AbstractIntegrator = eqx.field(static=True)

    def run(self, model, law, ts, x0, u_const, rudder_rate, max_rudder, delta_start):
        xs, ds, valid = closed_loop(model, law, ts, x0, u_const, self.delta_index, rudder_rate, max_rudder,
                                    delta_start, self.integrator)
        us = jnp.broadcast_to(u_const, (ts.shape[0], u_const.shape[0])).at[:, self.delta_index].set(ds)
        return xs, ds, valid, jax.vmap(model.observe)(xs, us)


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
                   integrator, name, metadata, scale=None) -> Run:
    d_idx, u_const = _input_slots(model, inputs)
    rudder_rate_deg_s, rate_source = helm_rate(model, rudder_rate_deg_s=rudder_rate_deg_s, scale=scale)
    x0 = _x0_vector(model, initial)
    ts = np.arange(0.0, duration + 0.5 * dt, dt)
    f = lambda a: jnp.asarray(a, dtype=jnp.float64)  # noqa: E731
    args = (model, law, f(ts), f(x0), f(u_const), f(math.radians(rudder_rate_deg_s)), f(math.radians(max_rudder_deg)),
            f(0.0))
    fn, _ = compiled(_Manoeuvre(d_idx, integrator), "run", args)
    xs, ds, valid, ys = (np.asarray(a) for a in fn(*args))
    us = np.repeat(u_const[None], len(ts), axis=0)
    us[:, d_idx] = ds
    channels = {c: ys[:, j] for j, c in enumerate(model.output_names)}
    for j, n in enumerate(model.input_names):
        channels[n] = us[:, j]
    meta = {"simulated": True, "model": model.name, "rudder_rate_deg_s": rudder_rate_deg_s,
            "rudder_rate_source": rate_source,
            "max_rudder_deg": max_rudder_deg, "valid": bool(valid.all()), **metadata}
    if not valid.all():
        t_bad = float(ts[int(np.argmin(valid))])
        raise ModelError(f"model {model.name}: the {metadata.get('manoeuvre', 'manoeuvre')} simulation blows up "
                         f"at t = {t_bad:.1f} s; check the parameters or shorten the manoeuvre")
    return Run(name, ts, channels, meta, check_units=False)


def _side(first: str | float) -> float:
    return side_sign(first)


def zigzag(model: AbstractModel, initial, *, rudder_deg: float = 10.0, switch_deg: float | None = None,
           first: str | float = "starboard", inputs: Mapping[str, float] | None = None, duration: float = 100.0,
           dt: float = 0.1, t_execute: float = 0.0, rudder_rate_deg_s: float | None = None, max_rudder_deg: float = 35.0,
           switch_delay_s: float = 0.0, scale: float | None = None, integrator: AbstractIntegrator = Diffrax(substeps=2), name: str | None = None) -> Run:
    """Simulate a ``rudder_deg``/``switch_deg`` zigzag (switch defaults to the rudder angle).

    Args:
        model: any model with a ``delta`` input and a ``psi`` state.
        initial: initial state (mapping of state names, e.g. ``{"u": 1.179}``, or a vector).
        first: side of the first rudder order, ``"starboard"``/``+1`` or ``"port"``/``−1``.
        inputs: constant values of the model's other inputs (e.g. ``{"n": 10.23}``).
        duration, dt: simulated time and sample interval [s].
        t_execute: time of the first rudder order [s].
        rudder_rate_deg_s: steering-gear rate [°/s]; by default :func:`diffship.scaling.helm_rate`
            (IMO's 2.32°/s, Froude-scaled with ``scale``; a model-scale ship without either is an error).
        scale: length ratio λ = L_full / L_model for the default helm rate.
        max_rudder_deg: rudder saturation [°].
        switch_delay_s: autopilot delay between the heading reaching ±ψ_s and the rudder order [s].
    """
    switch_deg = rudder_deg if switch_deg is None else switch_deg
    psi0 = float(_x0_vector(model, initial)[model.state_names.index("psi")])
    law = ZigzagLaw(*(jnp.asarray(v, dtype=jnp.float64) for v in (
        math.radians(rudder_deg), math.radians(switch_deg), _side(first), t_execute, psi0, switch_delay_s)))
    first = side_name(first)
    tag = f"{rudder_deg:g}/{switch_deg:g} zigzag ({first} first)"
    return _run_manoeuvre(model, law, initial=initial, inputs=inputs or {}, duration=duration, dt=dt,
                          rudder_rate_deg_s=rudder_rate_deg_s, max_rudder_deg=max_rudder_deg, integrator=integrator, scale=scale,
                          name=name or f"{model.name} {tag}",
                          metadata={"manoeuvre": "zigzag", "rudder_angle_deg": float(rudder_deg),
                                    "switch_heading_deg": float(switch_deg), "first_rudder": first,
                                    "t_execute": float(t_execute), "switch_delay_s": float(switch_delay_s)})


def _schedule(times, levels_deg):
    return ScheduleLaw(jnp.asarray(times, dtype=jnp.float64), jnp.asarray(np.radians(levels_deg), dtype=jnp.float64))


def turning_circle(model: AbstractModel, initial, *, rudder_deg: float = 35.0, first: str | float = "starboard",
                   inputs: Mapping[str, float] | None = None, duration: float = 300.0, dt: float = 0.1,
                   t_execute: float = 0.0, rudder_rate_deg_s: float | None = None, max_rudder_deg: float = 35.0,
                   scale: float | None = None, integrator: AbstractIntegrator = Diffrax(substeps=2), name: str | None = None) -> Run:
    """Simulate a turning circle: straight until ``t_execute``, then ``rudder_deg`` to ``first``."""
    s, first = _side(first), side_name(first)
    law = _schedule([t_execute], [s * rudder_deg])
    return _run_manoeuvre(model, law, initial=initial, inputs=inputs or {}, duration=duration, dt=dt,
                          rudder_rate_deg_s=rudder_rate_deg_s, max_rudder_deg=max_rudder_deg, integrator=integrator, scale=scale,
                          name=name or f"{model.name} {rudder_deg:g} deg turning circle ({first})",
                          metadata={"manoeuvre": "turning_circle", "rudder_angle_deg": float(rudder_deg),
                                    "first_rudder": first, "t_execute": float(t_execute)})


def pull_out(model: AbstractModel, initial, *, rudder_deg: float = 20.0, first: str | float = "starboard",
             inputs: Mapping[str, float] | None = None, turn_s: float = 120.0, settle_s: float = 120.0,
             dt: float = 0.1, t_execute: float = 0.0, rudder_rate_deg_s: float | None = None,
             max_rudder_deg: float = 35.0, scale: float | None = None, integrator: AbstractIntegrator = Diffrax(substeps=2), name: str | None = None) -> Run:
    """Simulate a pull-out: ``rudder_deg`` for ``turn_s`` seconds (steady turn), then rudder to 0."""
    s, first = _side(first), side_name(first)
    t_release = t_execute + turn_s
    law = _schedule([t_execute, t_release], [s * rudder_deg, 0.0])
    return _run_manoeuvre(model, law, initial=initial, inputs=inputs or {}, duration=t_release + settle_s, dt=dt,
                          rudder_rate_deg_s=rudder_rate_deg_s, max_rudder_deg=max_rudder_deg, integrator=integrator, scale=scale,
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
           dt: float = 0.2, rudder_rate_deg_s: float | None = None, max_rudder_deg: float = 35.0, integrator: AbstractIntegrator = Diffrax(substeps=2),
           name: str | None = None, scale: float | None = None) -> SpiralResult:
    """Simulate a (direct) spiral: rudder steps held ``hold_s`` each; steady r per step.

    Run the sequence down and up again (e.g. ``(15, ..., -15, ..., 15)``) to see a hysteresis
    loop of a directionally unstable ship.
    """
    levels = np.asarray(rudder_deg, dtype=np.float64)
    times = np.arange(len(levels)) * hold_s
    law = _schedule(times, levels)
    run = _run_manoeuvre(model, law, initial=initial, inputs=inputs or {}, duration=len(levels) * hold_s, dt=dt,
                         rudder_rate_deg_s=rudder_rate_deg_s, max_rudder_deg=max_rudder_deg, integrator=integrator, scale=scale,
                         name=name or f"{model.name} spiral", metadata={"manoeuvre": "spiral", "hold_s": hold_s})
    run.require("r", "the spiral test's steady yaw rates")
    r = run["r"]
    out = []
    for t0 in times:
        sel = (run.time >= t0 + (1.0 - average_fraction) * hold_s) & (run.time <= t0 + hold_s)
        out.append(float(np.mean(r[sel])))
    return SpiralResult(levels, np.asarray(out), run)
