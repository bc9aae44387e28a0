r"""Actuator effects: input delay, actuator lag, rudder rate limit, rudder offset, constant force.

The first three act on the steering inputs (:func:`~._base.steering_inputs`) before the base
model sees them, in the order delay → rate limit → lag:

* **Input delay** is a Padé(2,2) approximant :math:`e^{-s\tau}\approx
  (1 - s\tau/2 + s^2\tau^2/12)/(1 + s\tau/2 + s^2\tau^2/12)`, exact in gain and accurate in
  phase up to :math:`\omega\tau\approx 3`. The alternative — interpolating the sampled input
  at ``t − τ`` — needs the input table inside the model, which breaks batching over runs of
  the unchanged fitter. Realisation (scaled so both states carry input units):
  :math:`\dot z_1 = z_2/\tau,\ \dot z_2 = (12/\tau)(u - z_1 - z_2/2),\ u_d = u - z_2`.
* **Actuator lag**: first order, :math:`T_a \dot u_a = u - u_a`.
* **Rate limit** is a fast tracking loop with clipped rate,
  :math:`\dot u_r = \mathrm{clip}((u - u_r)/\varepsilon, \pm A/T_{slew})`, ε = a fraction of
  a second (static), so the limited signal follows the command within ε when the limit is
  inactive; A is the largest |input| in the training data.

These switch to the raw input at the null (``jnp.where``), which makes them exact at the null
but not differentiable there: the screen uses probe secants for them (``smooth_null =
False``). Time constants are clamped below at a fraction of the sample interval so RK4 stays
stable during fits.

**Rudder offset** (``rudder_offset``) is the rudder angle offset :math:`\delta_{off}` added to the
rudder of a Nomoto model (:class:`NomotoRudderOffset`, :math:`\dot r = (K(\delta + \delta_{off}) - r)/T_1`
for the first-order model): the model's own ``delta0`` describes the same thing, so the diagnosis holds
``delta0`` at 0 in the base fit when ``rudder_offset`` is a candidate (:func:`~diffship.diagnose.diagnose`),
and the effect is not applicable where a given base fit already estimated ``delta0``.

**Constant force** (``constant_force``: propeller walk, a jet's or thruster's misalignment, thrust
asymmetry) is a constant sway force and yaw moment fixed to the hull on a 3-DOF model (``force`` hook,
:class:`ConstantForce`). It is named for what it is: on a model that carries a rudder offset of its own
(MMG's ``delta0``) a rudder offset is that coefficient, and a pair :math:`(Y_0, N_0)` is another effect — a
force at any lever arm, not only the rudder's. Because it turns with the ship, it is told apart from a
current (whose drift stays fixed in NED) by a turn through a large heading change, not by a zigzag about
one course.
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from ._base import DataFacts, Effect, is_ship3, param, rudder_only_applicability, scalar

__all__ = ["InputDelay", "ActuatorLag", "LagTrend", "RateLimit", "RudderOffset", "NomotoRudderOffset"]


class _InputEffect(Effect):
    """Shared by the effects on the steering inputs ``idx`` (applicable to every model)."""

    family: ClassVar[str] = "actuator"
    hook: ClassVar[str] = "input"
    smooth_null: ClassVar[bool] = False
    idx: tuple[int, ...] = eqx.field(static=True, default=(0,))
    dt: jnp.ndarray = scalar(0.1)  # data facts are array leaves (not static): no recompilation per data set

    @classmethod
    def applicability(cls, base, runs=None) -> str:
        return ""

    @classmethod
    def for_data(cls, base, facts: DataFacts) -> Effect:
        return cls(idx=facts.idx, dt=facts.dt)

    def _names(self, base, suffix=""):
        return tuple(base.input_names[i] + suffix for i in self.idx)

    def _put(self, ub: tuple, vals, on) -> tuple:
        """``ub`` with the steering components replaced by ``vals`` where the effect is on."""
        out = list(ub)
        for j, i in enumerate(self.idx):
            out[i] = jnp.where(on, vals[j], ub[i])
        return tuple(out)


class InputDelay(_InputEffect):
    r"""Steering inputs delayed by :math:`\tau_d` (Padé(2,2) realisation, see the module docstring)."""

    name: ClassVar[str] = "input_delay"
    input_order: ClassVar[int] = 0
    PROBE: ClassVar[dict[str, float]] = {"tau_d": 1.0}
    MIN_RELEVANT: ClassVar[dict[str, float]] = {"tau_d": 0.2}
    signature: ClassVar[str] = "residual/input-rate cross-correlation peaking at lag τ, same for all step sizes"
    confusable_with: ClassVar[tuple[str, ...]] = ("actuator_lag", "rate_limit")
    separating: ClassVar[str] = "steps or zigzags at two different amplitudes, and fast small PRBS steps"
    tau_d: jnp.ndarray = param(0.0, lower=0.0, scale=0.5, unit="s", description="input time delay")

    def extra_states(self, base):
        # the first state per input is named after the input, so it starts at the measured input
        return self._names(base) + self._names(base, "~pade2")

    def extra_init(self, base, y0):
        return [float(y0.get(n, 0.0)) for n in self._names(base)] + [0.0] * len(self.idx)

    def apply_input_parts(self, base, t, xb, xe, ub):
        k = len(self.idx)
        z1, z2 = xe[:k], xe[k:]
        on = self.tau_d > 0.0
        tau = jnp.maximum(jnp.where(on, self.tau_d, 1.0), 1.5 * self.dt)
        u = [ub[i] for i in self.idx]
        inv = 1.0 / tau  # a parameter's reciprocal, then products (no quotient in the time step)
        dz1 = tuple(z2[j] * inv for j in range(k))
        dz2 = tuple((12.0 * inv) * (u[j] - z1[j] - 0.5 * z2[j]) for j in range(k))
        return self._put(ub, [u[j] - z2[j] for j in range(k)], on), dz1 + dz2


class ActuatorLag(_InputEffect):
    r"""First-order actuator lag :math:`T_a \dot u_a = u - u_a` on the steering inputs."""

    name: ClassVar[str] = "actuator_lag"
    input_order: ClassVar[int] = 2
    PROBE: ClassVar[dict[str, float]] = {"T_act": 1.0}
    MIN_RELEVANT: ClassVar[dict[str, float]] = {"T_act": 0.2}
    signature: ClassVar[str] = "lagged response after steering steps; CCF with input rate at small positive lag"
    confusable_with: ClassVar[tuple[str, ...]] = ("input_delay", "rate_limit")
    separating: ClassVar[str] = "steps at two different amplitudes and fast small PRBS steps"
    T_act: jnp.ndarray = param(0.0, lower=0.0, scale=0.5, unit="s", description="actuator time constant")

    def extra_states(self, base):
        return self._names(base)

    def extra_init(self, base, y0):
        return [float(y0.get(n, 0.0)) for n in self._names(base)]

    def apply_input_parts(self, base, t, xb, xe, ub):
        on = self.T_act > 0.0
        inv = 1.0 / jnp.maximum(jnp.where(on, self.T_act, 1.0), 0.5 * self.dt)
        return self._put(ub, xe, on), tuple((ub[i] - xe[j]) * inv for j, i in enumerate(self.idx))


class LagTrend(_InputEffect):
    r"""An actuator lag that changes during a run, :math:`T_a(t) = T_{a,0} + \dot T_a\,t` (t: the
    run's clock; null: no lag) — a *possible* effect only (:mod:`diffship.diagnose`): a steering
    gear that slows as its oil warms, or a lag that depends on the load. Settled by the
    ``separating`` experiment, not by the fit."""

    name: ClassVar[str] = "lag_trend"
    input_order: ClassVar[int] = 2
    PROBE: ClassVar[dict[str, float]] = {"T_act0": 1.0, "dT_act": 0.01}
    MIN_RELEVANT: ClassVar[dict[str, float]] = {"T_act0": 0.2, "dT_act": 1e-3}
    signature: ClassVar[str] = "a lag residual after steering steps that grows (or shrinks) along the run"
    confusable_with: ClassVar[tuple[str, ...]] = ("actuator_lag",)
    separating: ClassVar[str] = ("rudder steps of one size at the start and at the end of a long run, with the rudder "
                                 "angle logged at the stock (the lag read off directly)")
    T_act0: jnp.ndarray = param(0.0, lower=0.0, scale=0.5, unit="s", description="actuator time constant at t = 0")
    dT_act: jnp.ndarray = param(0.0, scale=0.01, unit="s/s", description="rate of change of the time constant")

    def extra_states(self, base):
        return self._names(base)

    def extra_init(self, base, y0):
        return [float(y0.get(n, 0.0)) for n in self._names(base)]

    def apply_input_parts(self, base, t, xb, xe, ub):
        on = (self.T_act0 > 0.0) | (self.dT_act != 0.0)
        inv = 1.0 / jnp.maximum(jnp.where(on, self.T_act0 + self.dT_act * t, 1.0), 0.5 * self.dt)
        return self._put(ub, xe, on), tuple((ub[i] - xe[j]) * inv for j, i in enumerate(self.idx))


class RateLimit(_InputEffect):
    r"""Steering slew-rate limit: the input moves by at most ``A_i / T_slew`` per second."""

    name: ClassVar[str] = "rate_limit"
    input_order: ClassVar[int] = 1
    PROBE: ClassVar[dict[str, float]] = {"T_slew": 4.0}
    MIN_RELEVANT: ClassVar[dict[str, float]] = {"T_slew": 0.3}
    signature: ClassVar[str] = "residual spikes right after steering changes, lasting |Δu|/rate"
    confusable_with: ClassVar[tuple[str, ...]] = ("actuator_lag", "input_delay")
    separating: ClassVar[str] = "steering steps of two very different amplitudes (a rate limit's delay scales with the step)"
    T_slew: jnp.ndarray = param(0.0, lower=0.0, scale=2.0, unit="s", description="time to slew the largest input amplitude")
    amplitude: jnp.ndarray = eqx.field(converter=lambda a: jnp.asarray(a, dtype=jnp.float64), default=(1.0,))
    eps: jnp.ndarray = scalar(0.1)

    @classmethod
    def for_data(cls, base, facts: DataFacts) -> Effect:
        return cls(idx=facts.idx, dt=facts.dt, amplitude=facts.amplitude, eps=max(0.1, 0.6 * facts.dt))

    def extra_states(self, base):
        return self._names(base)

    def extra_init(self, base, y0):
        return [float(y0.get(n, 0.0)) for n in self._names(base)]

    def apply_input_parts(self, base, t, xb, xe, ub):
        on = self.T_slew > 0.0
        rate = self.amplitude * (1.0 / jnp.where(on, self.T_slew, 1.0))
        inv_eps = 1.0 / self.eps
        d = tuple(_clip((ub[i] - xe[j]) * inv_eps, rate[j]) for j, i in enumerate(self.idx))
        return self._put(ub, xe, on), d


def _clip(x, limit):
    """``clip(x, -limit, limit)`` by selection: the same values, a forward-mode derivative without the
    quotient of ``jnp.clip``'s (its min/max split the derivative at ties by dividing), which is a
    kernel of its own in every stage on a CPU."""
    return jnp.where(x > limit, limit, jnp.where(x < -limit, -limit, x))


class ConstantForce(Effect):
    r"""Constant sway force and yaw moment fixed to the hull, :math:`(Y_0, N_0)` (propeller walk, a jet's or
    thruster's misalignment, thrust asymmetry; null: 0)."""

    name: ClassVar[str] = "constant_force"
    family: ClassVar[str] = "bias"
    PROBE: ClassVar[dict[str, float]] = {"Y0": 50.0, "N0": 200.0}
    MIN_RELEVANT: ClassVar[dict[str, float]] = {"Y0": 5.0, "N0": 20.0}
    signature: ClassVar[str] = ("non-zero mean sway and yaw-rate residual on straight segments, fixed to the hull; "
                                "port/starboard asymmetry")
    confusable_with: ClassVar[tuple[str, ...]] = ("current", "wind")
    separating: ClassVar[str] = ("a turn through 180° or more (a force fixed to the hull turns with the ship, a "
                                 "current's drift stays fixed in NED) and symmetric port and starboard manoeuvres")
    Y0: jnp.ndarray = param(0.0, scale=50.0, unit="N", description="constant sway force")
    N0: jnp.ndarray = param(0.0, scale=200.0, unit="N m", description="constant yaw moment")

    @classmethod
    def applicability(cls, base, runs=None) -> str:
        if is_ship3(base):
            return ""
        return f"{base.name} is not a 3-DOF ship model (a rudder-steered model's offset is rudder_offset)"

    def force_parts(self, base, t, xb, ub, uext):
        return jnp.zeros_like(self.Y0), self.Y0, self.N0


class NomotoRudderOffset(Effect):
    r"""Rudder angle offset on a Nomoto model: the hull sees :math:`\delta + \delta_{off}`
    (null: 0). Smooth and linear in the offset, so the screen uses its forward-mode column."""

    name: ClassVar[str] = "rudder_offset"
    family: ClassVar[str] = "bias"
    hook: ClassVar[str] = "input"
    input_order: ClassVar[int] = 3  # after delay, rate limit and lag: an offset of the rudder as it acts
    PROBE: ClassVar[dict[str, float]] = {"delta_off": 0.01}
    MIN_RELEVANT: ClassVar[dict[str, float]] = {"delta_off": 0.1 * 3.141592653589793 / 180}
    signature: ClassVar[str] = "non-zero mean yaw-rate residual with the rudder amidships; port/starboard asymmetry"
    confusable_with: ClassVar[tuple[str, ...]] = ("current", "wind")
    separating: ClassVar[str] = "symmetric port and starboard zigzags at the same speed, and a straight run at 0° rudder"
    idx: tuple[int, ...] = eqx.field(static=True, default=(0,))
    delta_off: jnp.ndarray = param(0.0, scale=0.01, unit="rad", description="rudder angle offset")

    @classmethod
    def applicability(cls, base, runs=None) -> str:
        return rudder_only_applicability(base, "its rudder offset is its own delta0 where it has one; a constant "
                                                "sway force and yaw moment is constant_force")

    @classmethod
    def for_data(cls, base, facts: DataFacts) -> Effect:
        return cls(idx=(base.input_names.index("delta"),))

    def apply_input_parts(self, base, t, xb, xe, ub):
        out = list(ub)
        for i in self.idx:
            out[i] = out[i] + self.delta_off
        return tuple(out), ()
