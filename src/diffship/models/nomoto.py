r"""Nomoto steering models (first and second order).

Sign convention: starboard-positive rudder, ``K > 0`` means positive rudder gives positive
(starboard, clockwise) yaw rate. Angles in radians, time in seconds.

Equation-error form (seed 001), on the measured yaw rate ``r`` (or the derivative of the
heading when ``r`` is not measured) and its filtered derivatives:

* Nomoto 1: :math:`e = \dot r - (K(\delta+\delta_0) - r)/T_1`; linear regression
  :math:`\dot r = a r + b\delta + c` with :math:`T_1 = -1/a,\ K = bT_1,\ \delta_0 = c/b`;
* Nomoto 2: :math:`e = \ddot r - (K(\delta+\delta_0+T_3\dot\delta) - r - (T_1+T_2)\dot r)/(T_1T_2)`
  (``δ̇`` from the same filter); linear regression
  :math:`\ddot r = a r + b\dot r + c\delta + d + g\dot\delta` with :math:`T_1T_2 = -1/a`,
  :math:`T_1 + T_2 = -bT_1T_2`, :math:`K = cT_1T_2`, :math:`\delta_0 = d/c`, :math:`T_3 = g/c`
  (:func:`nomoto2_from_polynomial`); when those time constants are not real and positive,
  the first-order regression with :math:`T_2 = T_1/10`.

The maps back are bijections where defined, so the regression is the exact least-squares
solution of the equation error when every parameter is free, and a start otherwise.

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

from ._base import AbstractModel, LinearForm, param

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
    EQUATIONS: ClassVar[tuple[str, ...]] = ("r_dot",)
    EQUATION_CHANNELS: ClassVar[tuple[str, ...]] = ("r",)
    EQUATION_RATE_OF: ClassVar[dict[str, str]] = {"r": "psi"}

    K: jnp.ndarray = param(0.5, scale=0.5, unit="1/s", description="rudder gain")
    T1: jnp.ndarray = param(5.0, lower=0.0, scale=5.0, unit="s", description="yaw time constant")
    delta0: jnp.ndarray = param(0.0, scale=0.01, unit="rad", description="rudder offset")

    @property
    def input_names(self) -> tuple[str, ...]:
        return ("delta",)

    def effect_twins(self) -> dict[str, str]:
        """A rudder zero error is this model's own ``delta0`` (:meth:`AbstractModel.effect_twins`)."""
        return {"rudder_offset": "delta0"}

    def vector_field(self, t, x, u):
        r = x[1]
        return jnp.stack([r, (self.K * (u[0] + self.delta0) - r) / self.T1])

    def equation_residual(self, z, zd, zdd, u):
        """e = ṙ − (K(δ + δ0) − r)/T1 at one sample [rad/s²]."""
        return jnp.atleast_1d(zd[0] - (self.K * (u[0] + self.delta0) - z[0]) / self.T1)

    def regressors(self, z, zd, zdd, u):
        """ṙ = a r + b δ + c (module docstring)."""
        return {"first_order": _first_order_form(z, zd, u)}

    def from_regression(self, coefficients):
        """T1 = −1/a, K = b·T1, δ0 = c/b (None unless a < 0 and b ≠ 0)."""
        return _from_first_order(coefficients["first_order"])


class Nomoto2(AbstractModel):
    r"""Second-order Nomoto model (Nomoto 1957; Fossen 2021 eq. 7.11) with a rudder offset.

    .. math::
        T_1 T_2 \ddot r + (T_1 + T_2)\dot r + r = K(\delta + \delta_0 + T_3 \dot\delta)

    i.e. the transfer function :math:`r/\delta = K(1 + T_3 s)/((1 + T_1 s)(1 + T_2 s))`.
    It is realised without differentiating the rudder signal: with an internal state
    :math:`\xi` obeying :math:`T_1T_2\ddot\xi + (T_1+T_2)\dot\xi + \xi = K(\delta+\delta_0)`,
    the yaw rate is :math:`r = \xi + T_3\dot\xi`. States ``(psi, r, xi_dot)`` — the yaw rate itself
    is a state (:math:`\xi = r - T_3\dot\xi`, :math:`\dot r = \dot\xi + T_3\ddot\xi`), so the
    measured initial heading and yaw rate are the initial state whatever the parameters (an initial
    state in :math:`\xi` would change with ``T3`` and a fit would be judged from another start than it
    was fitted from); outputs ``(psi, r)``. ``T3`` is free by default (the full second-order model); ``--fix T3=0`` gives
    the simpler form of seed 001 written in time constants (its ``K δ = r + T₁'ṙ + T₂'r̈`` has
    ``T₁' = T1 + T2`` and ``T₂' = T1·T2``). On the SSPA zigzag the T3 = 0 form collapses to first
    order (T2 → 0); the lead term is what the data support. The model is symmetric in ``T1``
    and ``T2``; fits report ``T1 ≥ T2``.
    """

    name: ClassVar[str] = "nomoto2"
    state_names: ClassVar[tuple[str, ...]] = ("psi", "r", "xi_dot")
    output_names: ClassVar[tuple[str, ...]] = ("psi", "r")
    STATE_CHANNEL: ClassVar[dict[str, str]] = {"r": "r", "xi_dot": "r"}
    #: ξ̇(0) is the yaw acceleration ṙ(0) where T3 = 0 or the rudder is still: an estimated ξ̇(0) moves from
    #: the measured ṙ(0) only within the noise of a numerical derivative of r (``OutputError.x0_prior``)
    STATE_RATE_OF: ClassVar[dict[str, str]] = {"xi_dot": "r"}
    EQUATIONS: ClassVar[tuple[str, ...]] = ("r_ddot",)
    EQUATION_CHANNELS: ClassVar[tuple[str, ...]] = ("r",)
    EQUATION_ORDER: ClassVar[int] = 2
    EQUATION_RATE_OF: ClassVar[dict[str, str]] = {"r": "psi"}
    EQUATION_INPUT_RATES: ClassVar[tuple[str, ...]] = ("delta",)

    K: jnp.ndarray = param(0.5, scale=0.5, unit="1/s", description="rudder gain")
    T1: jnp.ndarray = param(5.0, lower=0.0, scale=5.0, unit="s", description="first time constant")
    T2: jnp.ndarray = param(0.5, lower=0.0, scale=1.0, unit="s", description="second time constant")
    T3: jnp.ndarray = param(0.0, scale=1.0, unit="s", description="rudder lead time constant")
    delta0: jnp.ndarray = param(0.0, scale=0.01, unit="rad", description="rudder offset")

    @property
    def input_names(self) -> tuple[str, ...]:
        return ("delta",)

    def effect_twins(self) -> dict[str, str]:
        """A rudder zero error is this model's own ``delta0`` (:meth:`AbstractModel.effect_twins`)."""
        return {"rudder_offset": "delta0"}

    def vector_field(self, t, x, u):
        r, xid = x[1], x[2]
        xi = r - self.T3 * xid
        xidd = (self.K * (u[0] + self.delta0) - xi - (self.T1 + self.T2) * xid) / (self.T1 * self.T2)
        return jnp.stack([r, xid + self.T3 * xidd, xidd])

    def initial_state(self, y0: Mapping[str, float]) -> np.ndarray:
        r"""Measured ψ and r; :math:`\dot\xi_0` = the measured ṙ (exact where T3 = 0 or δ̇ = 0), the same
        values at any parameters."""
        return np.array([float(y0.get("psi", 0.0)), float(y0.get("r", 0.0)), float(y0.get("r_dot", 0.0))])

    def states_for_channels(self, channels) -> tuple[str, ...]:
        """ψ, r and ξ̇ wherever ψ or r is fitted: the yaw rate's initial value shapes the heading whether
        or not r is measured (unmeasured states are estimated free, :mod:`diffship.initial`)."""
        return (("psi",) if "psi" in channels else ()) + (("r", "xi_dot") if {"psi", "r"} & set(channels) else ())

    def canonical(self, values: Mapping[str, float]) -> dict[str, float]:
        """Order the interchangeable time constants so that ``T1 ≥ T2``."""
        out = dict(values)
        if out["T2"] > out["T1"]:
            out["T1"], out["T2"] = out["T2"], out["T1"]
        return out

    def equation_residual(self, z, zd, zdd, u):
        """e = r̈ − (K(δ + δ0 + T3 δ̇) − r − (T1 + T2)ṙ)/(T1 T2) at one sample; ``u = (δ, δ̇)``."""
        forcing = self.K * (u[0] + self.delta0 + self.T3 * u[1])
        return jnp.atleast_1d(zdd[0] - (forcing - z[0] - (self.T1 + self.T2) * zd[0]) / (self.T1 * self.T2))

    def regressors(self, z, zd, zdd, u):
        """r̈ = a r + b ṙ + c δ + d + g δ̇, and the first-order form as a fallback (module docstring)."""
        r, rd, d = z[..., 0], zd[..., 0], u[..., 0]
        A = jnp.stack([r, rd, d, jnp.ones_like(r), u[..., 1]], -1)
        return {"second_order": LinearForm(A, zdd[..., 0], ("a", "b", "c", "d", "g")),
                "first_order": _first_order_form(z, zd, u)}

    def from_regression(self, coefficients):
        """K, T1 ≥ T2, T3, δ0 from the second-order coefficients, else the first-order ones with T2 = T1/10."""
        c2 = coefficients["second_order"]
        a, b, c = c2["a"], c2["b"], c2["c"]
        if not (a >= 0 or c == 0):
            P = -1.0 / a
            T = nomoto2_from_polynomial(-b * P, P) if P > 0 else None
            if T is not None and T[1] > 0:
                return {"K": c * P, "T1": T[0], "T2": T[1], "delta0": c2["d"] / c, "T3": c2["g"] / c}
        first = _from_first_order(coefficients["first_order"])  # r̈ too noisy: 1st order, T2 = T1/10
        return None if first is None else {**first, "T2": 0.1 * first["T1"]}


def _first_order_form(z, zd, u) -> LinearForm:
    r, d = z[..., 0], u[..., 0]
    return LinearForm(jnp.stack([r, d, jnp.ones_like(r)], -1), zd[..., 0], ("a", "b", "c"))


def _from_first_order(coef: Mapping[str, float]) -> dict[str, float] | None:
    """K, T1, δ0 from ṙ = a r + b δ + c (None unless a < 0 and b ≠ 0)."""
    a, b, c = coef["a"], coef["b"], coef["c"]
    if a >= 0 or b == 0:
        return None
    T1 = -1.0 / a
    return {"K": b * T1, "T1": T1, "delta0": c / b}


def nomoto2_from_polynomial(S: float, P: float) -> tuple[float, float] | None:
    """Time constants ``T1 ≥ T2`` from ``S = T1 + T2`` and ``P = T1·T2`` (None if not real/positive)."""
    disc = S * S - 4.0 * P
    if not (P > 0 and S > 0 and disc >= 0):
        return None
    root = math.sqrt(disc)
    return (S + root) / 2.0, (S - root) / 2.0
