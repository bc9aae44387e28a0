r"""Damping effects: nonlinear damping terms and speed-dependent linear damping.

On 3-DOF models these are added forces (``force`` hook, turned into accelerations by the base
model's own mass matrix):

=================  =============================  ==========================================
name               parameters (null = 0)          added force
=================  =============================  ==========================================
damping_vv         Nvv                            :math:`N_{|v|v}|v|v` (Y_|v|v is in fossen3)
damping_rr         Yrr                            :math:`Y_{|r|r}|r|r` (N_|r|r is in fossen3)
damping_vr         Yvr, Nvr                       :math:`(Y, N)_{|v|r}\,|v|r`
damping_rv         Yrv, Nrv                       :math:`(Y, N)_{|r|v}\,|r|v`
speed_dependence   k_U                            :math:`s\,D_L\nu`, :math:`s = k_U (U - U_0)/U_0`
=================  =============================  ==========================================

On Nomoto models ``damping_rr`` is Norrbin's yaw damping term :math:`c_{rr}|r|r`, in rudder-angle
units (:class:`NorrbinRR`).
"""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp

from ._base import DataFacts, Effect, body_velocity, is_ship3, param, scalar

__all__ = ["DampingVV", "DampingRR", "DampingVR", "DampingRV", "SpeedDependence", "NorrbinRR"]


class _Damping(Effect):
    family: ClassVar[str] = "damping"
    confusable_with: ClassVar[tuple[str, ...]] = ("speed_dependence", "damping_vv", "damping_rr", "damping_vr", "damping_rv")
    separating: ClassVar[str] = "manoeuvres at the same speed with small and large rudder/nozzle angles"
    signature: ClassVar[str] = "amplitude-dependent error concentrated at large |v| or |r|"


class DampingVV(_Damping):
    r"""Yaw moment :math:`N_{|v|v}|v|v` (fossen3 already has :math:`Y_{|v|v}`)."""

    name: ClassVar[str] = "damping_vv"
    PROBE: ClassVar[dict[str, float]] = {"Nvv": 2000.0}
    MIN_RELEVANT: ClassVar[dict[str, float]] = {"Nvv": 100.0}
    Nvv: jnp.ndarray = param(0.0, scale=2000.0, unit="kg", description="N_|v|v")

    def force_parts(self, base, t, xb, ub, uext):
        u, v, r = body_velocity(base, xb)
        return jnp.zeros_like(v), jnp.zeros_like(v), self.Nvv * jnp.abs(v) * v


class DampingRR(_Damping):
    r"""Sway force :math:`Y_{|r|r}|r|r` (fossen3 already has :math:`N_{|r|r}`)."""

    name: ClassVar[str] = "damping_rr"
    PROBE: ClassVar[dict[str, float]] = {"Yrr": 2000.0}
    MIN_RELEVANT: ClassVar[dict[str, float]] = {"Yrr": 100.0}
    Yrr: jnp.ndarray = param(0.0, scale=2000.0, unit="kg m²", description="Y_|r|r")

    def force_parts(self, base, t, xb, ub, uext):
        u, v, r = body_velocity(base, xb)
        return jnp.zeros_like(r), self.Yrr * jnp.abs(r) * r, jnp.zeros_like(r)


class DampingVR(_Damping):
    r"""Cross terms :math:`Y_{|v|r}|v|r` and :math:`N_{|v|r}|v|r`."""

    name: ClassVar[str] = "damping_vr"
    PROBE: ClassVar[dict[str, float]] = {"Yvr": 2000.0, "Nvr": 5000.0}
    MIN_RELEVANT: ClassVar[dict[str, float]] = {"Yvr": 100.0, "Nvr": 300.0}
    Yvr: jnp.ndarray = param(0.0, scale=2000.0, unit="kg", description="Y_|v|r")
    Nvr: jnp.ndarray = param(0.0, scale=5000.0, unit="kg m", description="N_|v|r")

    def force_parts(self, base, t, xb, ub, uext):
        u, v, r = body_velocity(base, xb)
        q = jnp.abs(v) * r
        return jnp.zeros_like(q), self.Yvr * q, self.Nvr * q


class DampingRV(_Damping):
    r"""Cross terms :math:`Y_{|r|v}|r|v` and :math:`N_{|r|v}|r|v`."""

    name: ClassVar[str] = "damping_rv"
    PROBE: ClassVar[dict[str, float]] = {"Yrv": 2000.0, "Nrv": 5000.0}
    MIN_RELEVANT: ClassVar[dict[str, float]] = {"Yrv": 100.0, "Nrv": 300.0}
    Yrv: jnp.ndarray = param(0.0, scale=2000.0, unit="kg m", description="Y_|r|v")
    Nrv: jnp.ndarray = param(0.0, scale=5000.0, unit="kg m²", description="N_|r|v")

    def force_parts(self, base, t, xb, ub, uext):
        u, v, r = body_velocity(base, xb)
        q = jnp.abs(r) * v
        return jnp.zeros_like(q), self.Yrv * q, self.Nrv * q


class SpeedDependence(_Damping):
    r"""Speed-dependent linear damping: :math:`D_L \to D_L\,(1 + k_U (U - U_0)/U_0)`, with
    :math:`U = \sqrt{u^2+v^2}` and :math:`U_0` the mean training speed."""

    name: ClassVar[str] = "speed_dependence"
    PROBE: ClassVar[dict[str, float]] = {"k_U": 0.3}
    MIN_RELEVANT: ClassVar[dict[str, float]] = {"k_U": 0.05}
    signature: ClassVar[str] = "error growing with |U − U0|; per-speed fits drift"
    separating: ClassVar[str] = "the same manoeuvre at two or more speeds"
    k_U: jnp.ndarray = param(0.0, scale=0.3, unit="-", description="relative change of linear damping per relative speed change")
    U0: jnp.ndarray = scalar(1.0)

    @classmethod
    def applicability(cls, base, runs=None) -> str:
        if is_ship3(base) and all(hasattr(base, a) for a in ("Xu", "Yv", "Yr", "Nv", "Nr")):
            return ""
        return f"{base.name} has no linear damping derivatives to make speed-dependent"

    @classmethod
    def for_data(cls, base, facts: DataFacts) -> Effect:
        return cls(U0=facts.U0)

    def force_parts(self, base, t, xb, ub, uext):
        u, v, r = body_velocity(base, xb)
        s = (self.k_U * (1.0 / self.U0)) * (jnp.sqrt(u * u + v * v + 1e-12) - self.U0)
        return s * (base.Xu * u), s * (base.Yv * v + base.Yr * r), s * (base.Nv * v + base.Nr * r)


class NorrbinRR(Effect):
    r"""Nomoto with a Norrbin-type yaw damping term: :math:`\delta_{eff} = \delta - c_{rr}|r|r`,
    i.e. :math:`T\dot r + r + K c_{rr}|r|r = K(\delta + \delta_0)` (``damping_rr`` on models
    with a rudder input and a yaw-rate output that are not 3-DOF)."""

    name: ClassVar[str] = "damping_rr"
    family: ClassVar[str] = "damping"
    hook: ClassVar[str] = "input"
    PROBE: ClassVar[dict[str, float]] = {"c_rr": 20.0}
    MIN_RELEVANT: ClassVar[dict[str, float]] = {"c_rr": 0.5}
    signature: ClassVar[str] = "amplitude-dependent error: large rudder angles over-predict the turn rate"
    confusable_with: ClassVar[tuple[str, ...]] = ("rate_limit",)
    separating: ClassVar[str] = "zigzags at small and large rudder angles"
    c_rr: jnp.ndarray = param(0.0, scale=10.0, unit="rad s²", description="Norrbin |r|r coefficient (rudder-angle units)")

    @classmethod
    def applicability(cls, base, runs=None) -> str:
        if "delta" in base.input_names and "r" in base.output_names:
            return ""
        return f"{base.name} has no rudder input and yaw-rate output"

    def apply_input(self, base, t, xb, xe, ub):
        r = base.observe(xb, ub)[base.output_names.index("r")]
        i = base.input_names.index("delta")
        return ub.at[i].add(-self.c_rr * jnp.abs(r) * r), jnp.zeros((0,), dtype=xb.dtype)
