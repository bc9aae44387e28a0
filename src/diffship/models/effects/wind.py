r"""Wind: a force from the measured true wind (inputs ``wind_speed`` [m/s] and ``wind_dir`` [rad]).

``wind_dir`` is the direction the wind comes from (NED). Relative wind
:math:`u_{rw} = u + V_w\cos(\beta_w-\psi)`, :math:`v_{rw} = v + V_w\sin(\beta_w-\psi)`,
angle :math:`\gamma = \operatorname{atan2}(v_{rw}, u_{rw})`, :math:`q = u_{rw}^2 + v_{rw}^2`:

.. math::
    \Delta\tau = q\,(-C_{wx}\cos\gamma,\ -C_{wy}\sin\gamma,\ -C_{wn}\sin 2\gamma)

(the ½ρ_a A of the usual form is absorbed into the coefficients).
"""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp

from ._base import Effect, body_velocity, is_ship3, param

__all__ = ["Wind"]


class Wind(Effect):
    r"""Wind force :math:`q\,(-C_{wx}\cos\gamma, -C_{wy}\sin\gamma, -C_{wn}\sin 2\gamma)`
    from the measured wind (see the module docstring); null: no wind force."""

    name: ClassVar[str] = "wind"
    family: ClassVar[str] = "environment"
    PROBE: ClassVar[dict[str, float]] = {"Cwx": 3.0, "Cwy": 5.0, "Cwn": 10.0}
    MIN_RELEVANT: ClassVar[dict[str, float]] = {"Cwx": 0.2, "Cwy": 0.3, "Cwn": 0.5}
    extra_inputs: ClassVar[tuple[str, ...]] = ("wind_speed", "wind_dir")
    signature: ClassVar[str] = "sway/yaw residual periodic in the relative wind angle, ∝ wind speed²"
    confusable_with: ClassVar[tuple[str, ...]] = ("current", "constant_force")
    separating: ClassVar[str] = "runs on opposite headings or in different wind speeds"
    Cwx: jnp.ndarray = param(0.0, scale=3.0, unit="N s²/m²", description="longitudinal wind coefficient")
    Cwy: jnp.ndarray = param(0.0, scale=5.0, unit="N s²/m²", description="lateral wind coefficient")
    Cwn: jnp.ndarray = param(0.0, scale=10.0, unit="N s²/m", description="wind yaw moment coefficient")

    @classmethod
    def applicability(cls, base, runs=None) -> str:
        if not is_ship3(base):
            return f"{base.name} is not a 3-DOF ship model"
        if runs is not None and not all(r.has("wind_speed", "wind_dir") for r in runs):
            return "no measured wind (channels wind_speed and wind_dir) in every run"
        return ""

    def force(self, base, t, xb, ub, uext):
        u, v, r = body_velocity(base, xb)
        psi = xb[base.state_names.index("psi")]
        vw, bw = uext[0], uext[1]
        urw = u + vw * jnp.cos(bw - psi)
        vrw = v + vw * jnp.sin(bw - psi)
        q = urw * urw + vrw * vrw
        g = jnp.arctan2(vrw, urw)
        return -q * jnp.stack([self.Cwx * jnp.cos(g), self.Cwy * jnp.sin(g), self.Cwn * jnp.sin(2.0 * g)])
