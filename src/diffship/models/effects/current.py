r"""Ocean current: a constant current :math:`v_c = (V_{cx}, V_{cy})` in NED [m/s].

The kinematics live in :meth:`~.augmented.Augmented.vector_field`: the velocity states stay
**over ground** (what GNSS measures, so the initial states do not depend on the current), the
hydrodynamics see the velocity through the water :math:`\nu_r = \nu_g - R^\top(\psi)\,v_c`,
and for a constant current :math:`\dot\nu_g = \dot\nu_r + r\,(v^b_{c,y}, -v^b_{c,x}, 0)`.
"""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp

from ._base import Effect, param

__all__ = ["Current", "CurrentTrend"]


class Current(Effect):
    r"""Constant ocean current :math:`v_c = (V_{cx}, V_{cy})` in NED [m/s] (null: no current)."""

    name: ClassVar[str] = "current"
    family: ClassVar[str] = "environment"
    hook: ClassVar[str] = "kinematics"
    PROBE: ClassVar[dict[str, float]] = {"Vcx": 0.2, "Vcy": 0.2}
    MIN_RELEVANT: ClassVar[dict[str, float]] = {"Vcx": 0.03, "Vcy": 0.03}
    signature: ClassVar[str] = "over-ground velocity residual sinusoidal in heading; position drift fixed in NED"
    confusable_with: ClassVar[tuple[str, ...]] = ("heading_bias", "constant_force", "wind")
    separating: ClassVar[str] = "a turning circle of 360° or more (current drift stays fixed in NED)"
    Vcx: jnp.ndarray = param(0.0, scale=0.2, unit="m/s", description="current towards north (x)")
    Vcy: jnp.ndarray = param(0.0, scale=0.2, unit="m/s", description="current towards east (y)")

    def velocity(self, t):
        r"""The current :math:`v_c(t)` in NED [m/s] and its rate :math:`\dot v_c(t)` [m/s²]."""
        z = jnp.zeros_like(self.Vcx)
        return (self.Vcx, self.Vcy), (z, z)


class CurrentTrend(Effect):
    r"""A current that changes during a run, :math:`v_c(t) = v_{c,0} + \dot v_c\,t` in NED (t: the
    run's clock) — a *possible* effect only (:mod:`diffship.diagnose`): a linear trend stands for
    any slow change (a tidal current turning, a basin's water settling), and whether the change is
    real is settled by repeating the run, not by the fit (``separating``)."""

    name: ClassVar[str] = "current_trend"
    family: ClassVar[str] = "environment"
    hook: ClassVar[str] = "kinematics"
    PROBE: ClassVar[dict[str, float]] = {"Vcx_0": 0.2, "Vcy_0": 0.2, "dVcx": 1e-3, "dVcy": 1e-3}
    MIN_RELEVANT: ClassVar[dict[str, float]] = {"Vcx_0": 0.03, "Vcy_0": 0.03, "dVcx": 1e-4, "dVcy": 1e-4}
    signature: ClassVar[str] = "current drift whose speed or direction changes along the run"
    confusable_with: ClassVar[tuple[str, ...]] = ("current",)
    separating: ClassVar[str] = ("the same manoeuvre repeated at the start and at the end of the session (or on "
                                 "reciprocal headings), with the current measured by a drifting buoy or ADCP")
    Vcx_0: jnp.ndarray = param(0.0, scale=0.2, unit="m/s", description="current towards north at t = 0")
    Vcy_0: jnp.ndarray = param(0.0, scale=0.2, unit="m/s", description="current towards east at t = 0")
    dVcx: jnp.ndarray = param(0.0, scale=1e-3, unit="m/s^2", description="rate of change of the north current")
    dVcy: jnp.ndarray = param(0.0, scale=1e-3, unit="m/s^2", description="rate of change of the east current")

    def velocity(self, t):
        return (self.Vcx_0 + self.dVcx * t, self.Vcy_0 + self.dVcy * t), (self.dVcx, self.dVcy)
