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

__all__ = ["Current"]


class Current(Effect):
    r"""Constant ocean current :math:`v_c = (V_{cx}, V_{cy})` in NED [m/s] (null: no current)."""

    name: ClassVar[str] = "current"
    family: ClassVar[str] = "environment"
    hook: ClassVar[str] = "kinematics"
    PROBE: ClassVar[dict[str, float]] = {"Vcx": 0.2, "Vcy": 0.2}
    MIN_RELEVANT: ClassVar[dict[str, float]] = {"Vcx": 0.03, "Vcy": 0.03}
    signature: ClassVar[str] = "over-ground velocity residual sinusoidal in heading; position drift fixed in NED"
    confusable_with: ClassVar[tuple[str, ...]] = ("heading_bias", "rudder_offset", "wind")
    separating: ClassVar[str] = "a turning circle of 360° or more (current drift stays fixed in NED)"
    Vcx: jnp.ndarray = param(0.0, scale=0.2, unit="m/s", description="current towards north (x)")
    Vcy: jnp.ndarray = param(0.0, scale=0.2, unit="m/s", description="current towards east (y)")
