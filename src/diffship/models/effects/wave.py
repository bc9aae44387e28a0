r"""A periodic (wave-like) disturbance at one encounter period, with the period as a parameter.

First-order wave loads on a ship oscillate at the wave **encounter** frequency
:math:`\omega_e = 2\pi/T_w` (Faltinsen 1990, *Sea Loads on Ships and Offshore Structures*,
ch. 3–5; Fossen 2011, *Handbook of Marine Craft Hydrodynamics and Motion Control*, ch. 10:
wave-frequency forces :math:`\tau_{wave1}`, usually added to the low-frequency manoeuvring model
as a separate disturbance). In a regular or narrow-band sea one line dominates, and a manoeuvring
model without it leaves a residual at that period (:mod:`diffship.diagnose.periodic` finds it
with Fisher's g). This family is that line:

* on a 3-DOF model (``force`` hook) a sway force and yaw moment

  .. math::
      \Delta\tau(t) = \big(0,\ A_{Yc}\cos\omega_e t + A_{Ys}\sin\omega_e t,\
                             A_{Nc}\cos\omega_e t + A_{Ns}\sin\omega_e t\big),
      \qquad \omega_e = 2\pi/T_w

  [N, N, N·m], turned into accelerations with the base model's own mass matrix
  (:class:`~.augmented.Augmented`). Cosine and sine amplitudes instead of amplitude and phase
  make the force linear in four of its five parameters and avoid the 2π wrap of a phase; the
  amplitude and phase are :math:`A = \sqrt{A_c^2 + A_s^2}`, :math:`\varphi = \operatorname{atan2}
  (-A_s, A_c)` in :math:`A\cos(\omega_e t + \varphi)`. Surge is left out: with the period the
  two DOF already fill the five effect parameters a refit may free at once
  (:data:`diffship.diagnose.screen.P_MAX`), and for manoeuvring in oblique seas sway and yaw carry
  the first-order load that the heading and track show;
* on a Nomoto model (``input`` hook, :class:`NomotoWave`) the same line as a rudder-equivalent
  disturbance, :math:`\delta \to \delta + a_c\cos\omega_e t + a_s\sin\omega_e t` [rad] (a yaw
  moment divided by the rudder's moment per radian: :math:`T\dot r + r = K(\delta + \delta_w)`).

**Null value**: zero amplitudes; the disturbance then vanishes exactly whatever :math:`T_w`, so
the augmented model equals the base model. The period's "null" is its start value: the
period the diagnosis found in the base fit's training residuals (:func:`~.registry.library`'s
``starts``, from :func:`diffship.diagnose.periodic.residual_period`); without one the effect is
not a candidate (a period cannot be found by a local fit from an arbitrary start: the cost is
multimodal in :math:`T_w` with minima a fraction :math:`T_w/t_{run}` of a period apart).

**Phase.** :math:`t` is each run's own clock, so the amplitudes describe one phase *relative to
the start of every run*: right for a disturbance locked to the run start (a towing-tank
wavemaker started with the carriage, the independent generator's ``wave`` scenario), wrong for
waves of random phase per run, where per-run amplitudes (two more unknowns per run, like the
per-run initial states) would be needed. That limitation is measured in
``benchmarks/results/wave_family.md``.
"""

from __future__ import annotations

import math
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from ._base import DataFacts, Effect, is_ship3, param, rudder_only_applicability

__all__ = ["Wave", "NomotoWave", "DEFAULT_PERIOD"]

#: The period a wave effect is built with when no start is given [s] (the diagnosis passes the
#: period of the periodic residual it found instead).
DEFAULT_PERIOD = 8.0

_SEPARATING = ("runs on several headings to the waves (the encounter period and the amplitudes change with the "
               "heading and speed; a periodic input or sensor artefact does not), with the wave elevation or a "
               "motion reference unit logged")


def _harmonic(T_w, t):
    """``(cos ω t, sin ω t)`` with ω = 2π/T_w (T_w kept ≥ its lower bound by the fit's clip)."""
    w = 2.0 * math.pi / T_w
    return jnp.cos(w * t), jnp.sin(w * t)


class _WaveBase(Effect):
    family: ClassVar[str] = "environment"
    signature: ClassVar[str] = "residual oscillating at one period not driven by the steering (a spectral line)"
    confusable_with: ClassVar[tuple[str, ...]] = ()
    separating: ClassVar[str] = _SEPARATING
    #: the parameter whose start value the data must give (:func:`~.registry.library` skips the effect without it)
    needs_start: ClassVar[str] = "T_w"

    def null(self) -> dict[str, float]:
        """Zero amplitudes, and the period at this instance's start value (not the class default)."""
        return {**super().null(), "T_w": float(self.T_w)}


class Wave(_WaveBase):
    r"""Sway force and yaw moment at encounter period :math:`T_w` (module docstring); null: zero
    amplitudes."""

    name: ClassVar[str] = "wave"
    PROBE: ClassVar[dict[str, float]] = {"A_Yc": 50.0, "A_Ys": 50.0, "A_Nc": 200.0, "A_Ns": 200.0,
                                         "T_w": DEFAULT_PERIOD}
    MIN_RELEVANT: ClassVar[dict[str, float]] = {"A_Yc": 5.0, "A_Ys": 5.0, "A_Nc": 20.0, "A_Ns": 20.0, "T_w": math.inf}
    A_Yc: jnp.ndarray = param(0.0, scale=50.0, unit="N", description="sway force, cosine amplitude")
    A_Ys: jnp.ndarray = param(0.0, scale=50.0, unit="N", description="sway force, sine amplitude")
    A_Nc: jnp.ndarray = param(0.0, scale=200.0, unit="N m", description="yaw moment, cosine amplitude")
    A_Ns: jnp.ndarray = param(0.0, scale=200.0, unit="N m", description="yaw moment, sine amplitude")
    T_w: jnp.ndarray = param(DEFAULT_PERIOD, lower=1.0, upper=3600.0, scale=0.5, unit="s",
                             description="encounter period")

    @classmethod
    def applicability(cls, base, runs=None) -> str:
        return "" if is_ship3(base) else f"{base.name} is not a 3-DOF ship model (a Nomoto model gets the rudder-equivalent form)"

    def force_parts(self, base, t, xb, ub, uext):
        c, s = _harmonic(self.T_w, t)
        return jnp.zeros_like(c), self.A_Yc * c + self.A_Ys * s, self.A_Nc * c + self.A_Ns * s


class NomotoWave(_WaveBase):
    r"""Rudder-equivalent periodic disturbance on a Nomoto model,
    :math:`\delta + a_c\cos(2\pi t/T_w) + a_s\sin(2\pi t/T_w)` (null: zero amplitudes)."""

    name: ClassVar[str] = "wave"
    hook: ClassVar[str] = "input"
    input_order: ClassVar[int] = 4  # after delay, rate limit, lag and the offset: a disturbance, not the rudder
    PROBE: ClassVar[dict[str, float]] = {"a_c": 0.01, "a_s": 0.01, "T_w": DEFAULT_PERIOD}
    MIN_RELEVANT: ClassVar[dict[str, float]] = {"a_c": 0.1 * math.pi / 180, "a_s": 0.1 * math.pi / 180, "T_w": math.inf}
    idx: tuple[int, ...] = eqx.field(static=True, default=(0,))
    a_c: jnp.ndarray = param(0.0, scale=0.01, unit="rad", description="rudder-equivalent disturbance, cosine amplitude")
    a_s: jnp.ndarray = param(0.0, scale=0.01, unit="rad", description="rudder-equivalent disturbance, sine amplitude")
    T_w: jnp.ndarray = param(DEFAULT_PERIOD, lower=1.0, upper=3600.0, scale=0.5, unit="s",
                             description="encounter period")

    @classmethod
    def applicability(cls, base, runs=None) -> str:
        return rudder_only_applicability(base, "the wave is a sway force and yaw moment there")

    @classmethod
    def for_data(cls, base, facts: DataFacts) -> Effect:
        return cls(idx=(base.input_names.index("delta"),))

    def apply_input_parts(self, base, t, xb, xe, ub):
        c, s = _harmonic(self.T_w, t)
        a = self.a_c * c + self.a_s * s
        out = list(ub)
        for i in self.idx:
            out[i] = out[i] + a
        return tuple(out), ()
