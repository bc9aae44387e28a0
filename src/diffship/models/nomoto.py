"""Nomoto steering models (first and second order).

Sign convention: starboard-positive rudder, ``K > 0`` means positive rudder gives positive
(starboard, clockwise) yaw rate. Angles in radians, time in seconds.

References:
    K. Nomoto et al., "On the steering qualities of ships", Int. Shipbuilding Progress 4 (1957).
    T. I. Fossen, *Handbook of Marine Craft Hydrodynamics and Motion Control*, 2nd ed.,
    Wiley 2021, §7.2.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import ClassVar

import jax.numpy as jnp
import numpy as np

from ..params import Param
from ._base import AbstractModel, scalar

__all__ = ["Nomoto1", "Nomoto2"]


class Nomoto1(AbstractModel):
    r"""First-order Nomoto model with a rudder offset.

    .. math::
        \dot\psi = r, \qquad T_1 \dot r + r = K(\delta + \delta_0)

    States ``(psi, r)``; input ``delta`` [rad]; parameters ``K`` [1/s], ``T1`` [s] > 0 and
    ``delta0`` [rad] (the rudder angle that holds a straight course is ``−delta0``).
    """

    name: ClassVar[str] = "nomoto1"
    state_names: ClassVar[tuple[str, ...]] = ("psi", "r")
    output_names: ClassVar[tuple[str, ...]] = ("psi", "r")
    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("K", 0.5, scale=0.5, unit="1/s", description="rudder gain"),
        Param("T1", 5.0, lower=0.0, scale=5.0, unit="s", description="yaw time constant"),
        Param("delta0", 0.0, scale=0.01, unit="rad", description="rudder offset"),
    )

    K: jnp.ndarray = scalar(0.5)
    T1: jnp.ndarray = scalar(5.0)
    delta0: jnp.ndarray = scalar(0.0)

    @property
    def input_names(self) -> tuple[str, ...]:
        return ("delta",)

    def vector_field(self, t, x, u):
        r = x[1]
        return jnp.stack([r, (self.K * (u[0] + self.delta0) - r) / self.T1])


class Nomoto2(AbstractModel):
    r"""Second-order Nomoto model (Nomoto 1957; Fossen 2021 eq. 7.11) with a rudder offset.

    .. math::
        T_1 T_2 \ddot r + (T_1 + T_2)\dot r + r = K(\delta + \delta_0 + T_3 \dot\delta)

    i.e. the transfer function :math:`r/\delta = K(1 + T_3 s)/((1 + T_1 s)(1 + T_2 s))`.
    It is realised without differentiating the rudder signal: with an internal state
    :math:`\xi` obeying :math:`T_1T_2\ddot\xi + (T_1+T_2)\dot\xi + \xi = K(\delta+\delta_0)`,
    the yaw rate is :math:`r = \xi + T_3\dot\xi`. States ``(psi, xi, xi_dot)``; outputs
    ``(psi, r)``. ``T3`` is free by default (the full second-order model); ``--fix T3=0`` gives
    the simpler form of seed 001 written in time constants (its ``K δ = r + T₁'ṙ + T₂'r̈`` has
    ``T₁' = T1 + T2`` and ``T₂' = T1·T2``). On the SSPA zigzag the T3 = 0 form collapses to first
    order (T2 → 0); the lead term is what the data support. The model is symmetric in ``T1``
    and ``T2``; fits report ``T1 ≥ T2``.
    """

    name: ClassVar[str] = "nomoto2"
    state_names: ClassVar[tuple[str, ...]] = ("psi", "xi", "xi_dot")
    output_names: ClassVar[tuple[str, ...]] = ("psi", "r")
    STATE_CHANNEL: ClassVar[dict[str, str]] = {"xi": "r", "xi_dot": "r"}
    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("K", 0.5, scale=0.5, unit="1/s", description="rudder gain"),
        Param("T1", 5.0, lower=0.0, scale=5.0, unit="s", description="first time constant"),
        Param("T2", 0.5, lower=0.0, scale=1.0, unit="s", description="second time constant"),
        Param("T3", 0.0, scale=1.0, unit="s", description="rudder lead time constant"),
        Param("delta0", 0.0, scale=0.01, unit="rad", description="rudder offset"),
    )

    K: jnp.ndarray = scalar(0.5)
    T1: jnp.ndarray = scalar(5.0)
    T2: jnp.ndarray = scalar(0.5)
    T3: jnp.ndarray = scalar(0.0)
    delta0: jnp.ndarray = scalar(0.0)

    @property
    def input_names(self) -> tuple[str, ...]:
        return ("delta",)

    def vector_field(self, t, x, u):
        xi, xid = x[1], x[2]
        r = xi + self.T3 * xid
        xidd = (self.K * (u[0] + self.delta0) - xi - (self.T1 + self.T2) * xid) / (self.T1 * self.T2)
        return jnp.stack([r, xid, xidd])

    def observe(self, x, u):
        return jnp.stack([x[0], x[1] + self.T3 * x[2]])

    def initial_state(self, y0: Mapping[str, float]) -> np.ndarray:
        xid = float(y0.get("r_dot", 0.0))
        return np.array([float(y0.get("psi", 0.0)), float(y0.get("r", 0.0)) - float(self.T3) * xid, xid])

    def states_for_channels(self, channels) -> tuple[str, ...]:
        out = ("psi",) if "psi" in channels else ()
        return out + (("xi", "xi_dot") if "r" in channels else ())

    @staticmethod
    def canonical(values: Mapping[str, float]) -> dict[str, float]:
        """Order the interchangeable time constants so that ``T1 ≥ T2``."""
        out = dict(values)
        if out["T2"] > out["T1"]:
            out["T1"], out["T2"] = out["T2"], out["T1"]
        return out


def nomoto2_from_polynomial(S: float, P: float) -> tuple[float, float] | None:
    """Time constants ``T1 ≥ T2`` from ``S = T1 + T2`` and ``P = T1·T2`` (None if not real/positive)."""
    disc = S * S - 4.0 * P
    if not (P > 0 and S > 0 and disc >= 0):
        return None
    root = math.sqrt(disc)
    return (S + root) / 2.0, (S - root) / 2.0
