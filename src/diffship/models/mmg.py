r"""MMG 3-DOF manoeuvring model (hull, propeller and rudder submodels).

The "MMG standard method" of Yasukawa & Yoshimura (2015), written about the midship point
with body-fixed velocities :math:`(u, v_m, r)` (x forward, y starboard, r clockwise) and
earth-fixed pose :math:`(x_0, y_0, \psi)`:

.. math::
    (m + m_x)\dot u - (m + m_y) v_m r - x_G m r^2 &= X_H + X_R + X_P \\
    (m + m_y)\dot v_m + (m + m_x) u r + x_G m \dot r &= Y_H + Y_R \\
    (I_{zG} + x_G^2 m + J_z)\dot r + x_G m(\dot v_m + u r) &= N_H + N_R

solved in closed form (surge decoupled, 2×2 sway–yaw block), and
:math:`\dot x_0 = u\cos\psi - v_m\sin\psi,\ \dot y_0 = u\sin\psi + v_m\cos\psi,\ \dot\psi = r`.

**Non-dimensionalisation** (primes): :math:`U = \sqrt{u^2 + v_m^2}`, :math:`v' = v_m/U`,
:math:`r' = rL/U`; forces by :math:`\tfrac12\rho L d U^2`, yaw moment by
:math:`\tfrac12\rho L^2 d U^2`, added masses by :math:`\tfrac12\rho L^2 d` and :math:`J_z` by
:math:`\tfrac12\rho L^4 d`; lengths ``xH, xR, xP, lR`` by L.

**Hull** (cubic polynomials in v', r'):

.. math::
    X'_H &= -R'_0 + X'_{vv}v'^2 + X'_{vr}v'r' + X'_{rr}r'^2 + X'_{vvvv}v'^4 \\
    Y'_H &= Y'_v v' + Y'_r r' + Y'_{vvv}v'^3 + Y'_{vvr}v'^2r' + Y'_{vrr}v'r'^2 + Y'_{rrr}r'^3 \\
    N'_H &= N'_v v' + N'_r r' + N'_{vvv}v'^3 + N'_{vvr}v'^2r' + N'_{vrr}v'r'^2 + N'_{rrr}r'^3

**Propeller**: :math:`X_P = (1 - t_P)\rho n^2 D_P^4 K_T(J_P)`,
:math:`K_T = k_0 + k_1 J_P + k_2 J_P^2`, :math:`J_P = u(1 - w_P)/(n D_P)`, with the wake in
manoeuvring motion :math:`1 - w_P = (1 - w_{P0})[1 + (1 - e^{-C_1|\beta_P|})(C_2 - 1)]`,
:math:`\beta = \arctan(-v_m/u)`, :math:`\beta_P = \beta - x'_P r'`, and :math:`C_2` = ``C2_plus``
for :math:`\beta_P > 0`, ``C2_minus`` otherwise.

**Rudder**: normal force :math:`F_N = \tfrac12\rho A_R U_R^2 f_\alpha \sin\alpha_R`, with
:math:`\alpha_R = \delta - \arctan(v_R/u_R)`, :math:`v_R = U\gamma_R\beta_R`,
:math:`\beta_R = \beta - l'_R r'` (:math:`\gamma_R` = ``gammaR_minus`` for
:math:`\beta_R < 0`, ``gammaR_plus`` otherwise),

.. math::
    u_R = \varepsilon u (1 - w_P)\sqrt{\eta\{1 + \kappa(\sqrt{1 + 8K_T/(\pi J_P^2)} - 1)\}^2
          + (1 - \eta)},\qquad \eta = D_P/H_R

evaluated in the algebraically equal form
:math:`u_R = \varepsilon\sqrt{\eta[u_P + \kappa(\sqrt{u_P^2 + 8K_T(nD_P)^2/\pi} - u_P)]^2 + (1-\eta)u_P^2}`,
:math:`u_P = u(1-w_P)`, which has no :math:`1/J_P^2` singularity at zero speed; and

.. math::
    X_R = -(1 - t_R)F_N\sin\delta,\quad Y_R = -(1 + a_H)F_N\cos\delta,\quad
    N_R = -(x_R + a_H x_H)F_N\cos\delta .

**Sign convention of δ.** With the rudder force written as above and :math:`x_R < 0` (rudder
aft), a positive δ gives :math:`F_N > 0`, a rudder side force to port and a positive
(clockwise, starboard) yaw moment: positive δ turns the ship to starboard. That is diffship's
convention (starboard-positive rudder, positive δ → positive r), so the paper's equations
are used without a sign flip. Data recorded port-positive (e.g. the HSVA KVLCC2 files) are
flipped on loading (:func:`diffship.data.kvlcc2_runs`). The optional ``delta0`` (not in the
paper, default 0) is a rudder neutral-angle offset: the model sees :math:`\delta + \delta_0`.

**Water density.** The L = 7 m KVLCC2 model was tested in fresh water (HSVA; the tidy data's
``ship_data.yml`` gives ρ = 1000 kg/m³ and m = 3272 kg ≈ 1000·3.27 m³), so ρ = 1000 is the
default. Primed coefficients are independent of ρ; ρ only converts them to forces and
together with ``m`` sets the non-dimensional mass m/(½ρL²d).

Inputs: ``delta`` [rad] (starboard-positive) and ``n`` [rev/s] (propeller speed, > 0:
ahead; the open-water map is only valid for ahead operation). Parameters: every coefficient
above; the reference values (:func:`kvlcc2_mmg`) are the KVLCC2 L7 model of Yasukawa &
Yoshimura (2015, Tables 1–3), with x_G = 0.0348 L and k_zz = 0.2486 L from the HSVA model
(SIMMAN 2008). The damping derivatives Y'_v, Y'_vvv, N'_r and N'_rrr are bounded above by 0
(dissipative sway and yaw damping: a zigzag-only fit otherwise flips N'_rrr and the model blows up in
a hard turn). Free by default: ``Yv, Yr, Nv, Nr, Nvvr, Nrrr`` (hull), ``Jz``, ``f_alpha``,
``R0`` and ``delta0`` — what the real-data study (:mod:`diffship.studies.kvlcc2`) needs; every
other parameter is fixed at its reference value.

Each parameter is declared once, as a field made by ``_p(name, unit, description, ...)``:
value from :data:`KVLCC2_L7`, free when listed in ``_FREE``, scale ``max(|value|, 0.01)``.
The mass solve is the shared closed-form 3-DOF one (:mod:`diffship.models._rigid3`).

Reference: H. Yasukawa, Y. Yoshimura, "Introduction of MMG standard method for ship
maneuvering predictions", J. Mar. Sci. Technol. 20 (2015) 37–52,
doi:10.1007/s00773-014-0293-y.
"""

from __future__ import annotations

import math
from typing import ClassVar

import jax.numpy as jnp

from ._base import param, parts
from ..particulars import MMG
from ._rigid3 import AbstractShip3, Mass3

__all__ = ["MMG", "KVLCC2_L7", "kvlcc2_mmg"]

#: KVLCC2 L = 7 m model (Yasukawa & Yoshimura 2015, Tables 1–3; x_G, k_zz, m from the HSVA
#: SIMMAN 2008 model, which is the same hull at the same scale).
KVLCC2_L7: dict[str, float] = dict(
    # hull resistance and manoeuvring derivatives (non-dimensional)
    R0=0.022, Xvv=-0.040, Xvr=0.002, Xrr=0.011, Xvvvv=0.771,
    Yv=-0.315, Yr=0.083, Yvvv=-1.607, Yvvr=0.379, Yvrr=-0.391, Yrrr=0.008,
    Nv=-0.137, Nr=-0.049, Nvvv=-0.030, Nvvr=-0.294, Nvrr=0.055, Nrrr=-0.013,
    # added masses (non-dimensional)
    mx=0.022, my=0.223, Jz=0.011,
    # propeller
    tP=0.220, wP0=0.40, xP=-0.48, C1=2.0, C2_plus=1.6, C2_minus=1.1,
    k0=0.2931, k1=-0.2753, k2=-0.1385,
    # rudder and hull–rudder interaction
    tR=0.387, aH=0.312, xH=-0.464, xR=-0.5, eps=1.09, kappa=0.50, lR=-0.710,
    gammaR_minus=0.395, gammaR_plus=0.640, f_alpha=2.747, delta0=0.0,
    # geometry and mass (SI)
    L=7.0, B=1.27, d=0.46, DP=0.216, HR=0.345, AR=0.0539,
    m=3272.0, xG=0.0348 * 7.0, kzz=0.2486, rho=1000.0,
)  # fmt: skip

#: Free by default: linear sway/yaw derivatives, two nonlinear yaw derivatives, yaw added inertia,
#: rudder lift slope, resistance and rudder offset — the set that predicts the HSVA KVLCC2
#: zigzags of other runs within about 1° of first overshoot (:mod:`diffship.studies.kvlcc2`).
_FREE = ("Yv", "Yr", "Nv", "Nr", "Nvvr", "Nrrr", "Jz", "f_alpha", "R0", "delta0")


def _p(name: str, unit: str, description: str, **kw):
    """A parameter field at its KVLCC2 L7 value, free if in ``_FREE``, scale max(|value|, 0.01)."""
    v = KVLCC2_L7[name]
    scale = kw.pop("scale", max(abs(v), 0.01))
    return param(v, free=name in _FREE, scale=scale, unit=unit, description=description, **kw)


_ND = "-"


class MMG(AbstractShip3):
    """MMG 3-DOF model (see module docstring); defaults: KVLCC2 L7 model, fresh water.

    Parameters are declared once each below (:func:`_p`: the KVLCC2 L7 value, free when in
    ``_FREE``). No equation-error form (the rudder and propeller submodels are not linear in
    the free parameters): fit by output error.
    """

    name: ClassVar[str] = "mmg"
    #: The published/standard parameter set the defaults are (priors: :mod:`diffship.fit.priors`).
    REFERENCE: ClassVar[str] = "KVLCC2 L7 model, Yasukawa & Yoshimura 2015"
    PARTICULARS: ClassVar[dict[str, str]] = MMG
    REFERENCE_VESSEL: ClassVar[str | None] = "kvlcc2_model"
    R0: jnp.ndarray = _p("R0", _ND, "straight-ahead resistance coefficient R'_0", lower=0.0)
    Xvv: jnp.ndarray = _p("Xvv", _ND, "surge force derivative X'_vv")
    Xvr: jnp.ndarray = _p("Xvr", _ND, "surge force derivative X'_vr")
    Xrr: jnp.ndarray = _p("Xrr", _ND, "surge force derivative X'_rr")
    Xvvvv: jnp.ndarray = _p("Xvvvv", _ND, "surge force derivative X'_vvvv")
    Yv: jnp.ndarray = _p("Yv", _ND, "sway force derivative Y'_v (damping: ≤ 0)", upper=0.0)
    Yr: jnp.ndarray = _p("Yr", _ND, "sway force derivative Y'_r")
    Yvvv: jnp.ndarray = _p("Yvvv", _ND, "sway force derivative Y'_vvv (damping: ≤ 0)", upper=0.0)
    Yvvr: jnp.ndarray = _p("Yvvr", _ND, "sway force derivative Y'_vvr")
    Yvrr: jnp.ndarray = _p("Yvrr", _ND, "sway force derivative Y'_vrr")
    Yrrr: jnp.ndarray = _p("Yrrr", _ND, "sway force derivative Y'_rrr")
    Nv: jnp.ndarray = _p("Nv", _ND, "yaw moment derivative N'_v")
    Nr: jnp.ndarray = _p("Nr", _ND, "yaw moment derivative N'_r (damping: ≤ 0)", upper=0.0)
    Nvvv: jnp.ndarray = _p("Nvvv", _ND, "yaw moment derivative N'_vvv")
    Nvvr: jnp.ndarray = _p("Nvvr", _ND, "yaw moment derivative N'_vvr")
    Nvrr: jnp.ndarray = _p("Nvrr", _ND, "yaw moment derivative N'_vrr")
    Nrrr: jnp.ndarray = _p("Nrrr", _ND, "yaw moment derivative N'_rrr (damping: ≤ 0)", upper=0.0)
    mx: jnp.ndarray = _p("mx", _ND, "surge added mass m'_x", lower=0.0)
    my: jnp.ndarray = _p("my", _ND, "sway added mass m'_y", lower=0.0)
    Jz: jnp.ndarray = _p("Jz", _ND, "yaw added moment of inertia J'_z", lower=0.0)
    tP: jnp.ndarray = _p("tP", _ND, "thrust deduction factor t_P", lower=-0.5, upper=1.0)
    wP0: jnp.ndarray = _p("wP0", _ND, "propeller wake fraction in straight motion w_P0", lower=-0.5, upper=1.0)
    xP: jnp.ndarray = _p("xP", _ND, "propeller position x'_P (from midship, / L)")
    C1: jnp.ndarray = _p("C1", _ND, "wake correction coefficient C_1")
    C2_plus: jnp.ndarray = _p("C2_plus", _ND, "wake correction coefficient C_2 for beta_P > 0")
    C2_minus: jnp.ndarray = _p("C2_minus", _ND, "wake correction coefficient C_2 for beta_P <= 0")
    k0: jnp.ndarray = _p("k0", _ND, "open-water thrust coefficient K_T(J=0)")
    k1: jnp.ndarray = _p("k1", _ND, "open-water K_T slope k_1")
    k2: jnp.ndarray = _p("k2", _ND, "open-water K_T curvature k_2")
    tR: jnp.ndarray = _p("tR", _ND, "steering resistance deduction factor t_R")
    aH: jnp.ndarray = _p("aH", _ND, "rudder force increase factor a_H")
    xH: jnp.ndarray = _p("xH", _ND, "position of the hull force increase by steering x'_H")
    xR: jnp.ndarray = _p("xR", _ND, "rudder position x'_R (from midship, / L)")
    eps: jnp.ndarray = _p("eps", _ND, "ratio of wake fractions at rudder and propeller epsilon", lower=0.0)
    kappa: jnp.ndarray = _p("kappa", _ND, "propeller slipstream correction kappa", lower=0.0)
    lR: jnp.ndarray = _p("lR", _ND, "effective longitudinal rudder position l'_R")
    gammaR_minus: jnp.ndarray = _p("gammaR_minus", _ND, "flow straightening coefficient for beta_R < 0", lower=0.0)
    gammaR_plus: jnp.ndarray = _p("gammaR_plus", _ND, "flow straightening coefficient for beta_R >= 0", lower=0.0)
    f_alpha: jnp.ndarray = _p("f_alpha", _ND, "rudder lift gradient coefficient f_alpha", lower=0.0)
    delta0: jnp.ndarray = _p("delta0", "rad", "rudder neutral-angle offset (not in the MMG paper)", scale=0.01)
    L: jnp.ndarray = _p("L", "m", "length between perpendiculars", lower=0.0)
    B: jnp.ndarray = _p("B", "m", "breadth (not used by the equations; for reference)", lower=0.0)
    d: jnp.ndarray = _p("d", "m", "draught", lower=0.0)
    DP: jnp.ndarray = _p("DP", "m", "propeller diameter", lower=0.0)
    HR: jnp.ndarray = _p("HR", "m", "rudder span", lower=0.0)
    AR: jnp.ndarray = _p("AR", "m2", "rudder area", lower=0.0)
    m: jnp.ndarray = _p("m", "kg", "mass", lower=0.0)
    xG: jnp.ndarray = _p("xG", "m", "longitudinal centre of gravity from midship (forward positive)")
    kzz: jnp.ndarray = _p("kzz", _ND, "yaw radius of gyration about G divided by L", lower=0.0)
    rho: jnp.ndarray = _p("rho", "kg/m3", "water density", lower=0.0)

    @property
    def input_names(self) -> tuple[str, ...]:
        return ("delta", "n")

    # -- submodels (all in SI units; each returns forces [N] and moments [N m]) -------------
    def hull_forces(self, u, v, r):
        """Hull forces (X_H, Y_H, N_H) at midship."""
        U2 = u * u + v * v + 1e-12
        U = jnp.sqrt(U2)
        vp, rp = v / U, r * self.L / U
        vp2, rp2 = vp * vp, rp * rp
        q = 0.5 * self.rho * self.L * self.d * U2
        X = -self.R0 + self.Xvv * vp2 + self.Xvr * vp * rp + self.Xrr * rp2 + self.Xvvvv * vp2 * vp2
        Y = (self.Yv * vp + self.Yr * rp + self.Yvvv * vp2 * vp + self.Yvvr * vp2 * rp
             + self.Yvrr * vp * rp2 + self.Yrrr * rp2 * rp)
        N = (self.Nv * vp + self.Nr * rp + self.Nvvv * vp2 * vp + self.Nvvr * vp2 * rp
             + self.Nvrr * vp * rp2 + self.Nrrr * rp2 * rp)
        return q * X, q * Y, q * self.L * N

    def _propeller(self, u, v, r, n):
        U = jnp.sqrt(u * u + v * v + 1e-12)
        beta = jnp.arctan2(-v, u)
        rp = r * self.L / U
        beta_p = beta - self.xP * rp
        c2 = jnp.where(beta_p > 0.0, self.C2_plus, self.C2_minus)
        one_minus_w = (1.0 - self.wP0) * (1.0 + (1.0 - jnp.exp(-self.C1 * jnp.abs(beta_p))) * (c2 - 1.0))
        u_p = u * one_minus_w
        nd = n * self.DP
        J = u_p / jnp.where(jnp.abs(nd) > 1e-9, nd, 1e-9)
        kt = self.k0 + self.k1 * J + self.k2 * J * J
        return U, beta, rp, u_p, kt, nd

    @staticmethod
    def _slipstream(u_p, kt, nd):
        r"""Far-slipstream axial speed :math:`\sqrt{u_P^2 + 8K_T(nD_P)^2/\pi}` (momentum theory)."""
        return jnp.sqrt(jnp.maximum(u_p * u_p + 8.0 * kt * nd * nd / math.pi, 1e-12))

    def propeller_loading(self, u, v, r, n):
        r"""Propeller loading :math:`\sqrt{1 + 8K_T/(\pi J_P^2)} - 1` [-], the slipstream's speed-up of the
        propeller inflow (the factor κ scales in the rudder inflow :math:`u_R`)."""
        _, _, _, u_p, kt, nd = self._propeller(u, v, r, n)
        return self._slipstream(u_p, kt, nd) / u_p - 1.0

    def propeller_thrust(self, u, v, r, n):
        """Surge force of the propeller X_P [N]."""
        _, _, _, _, kt, nd = self._propeller(u, v, r, n)
        return (1.0 - self.tP) * self.rho * nd * nd * self.DP * self.DP * kt

    def rudder_forces(self, u, v, r, delta, n):
        """Rudder forces (X_R, Y_R, N_R) including the hull interaction (t_R, a_H, x_H)."""
        U, beta, rp, u_p, kt, nd = self._propeller(u, v, r, n)
        eta = self.DP / self.HR
        slip = self._slipstream(u_p, kt, nd)
        ur = self.eps * jnp.sqrt(eta * (u_p + self.kappa * (slip - u_p)) ** 2 + (1.0 - eta) * u_p * u_p + 1e-12)
        beta_r = beta - self.lR * rp
        gamma = jnp.where(beta_r < 0.0, self.gammaR_minus, self.gammaR_plus)
        vr = U * gamma * beta_r
        d = delta + self.delta0
        alpha = d - jnp.arctan2(vr, ur)
        fn = 0.5 * self.rho * self.AR * (ur * ur + vr * vr) * self.f_alpha * jnp.sin(alpha)
        cd, sd = jnp.cos(d), jnp.sin(d)
        X = -(1.0 - self.tR) * fn * sd
        Y = -(1.0 + self.aH) * fn * cd
        N = -(self.xR + self.aH * self.xH) * self.L * fn * cd
        return X, Y, N

    def forces(self, x, inp):
        """Total external forces (X, Y, N_m) [N, N, N m] at midship."""
        u, v, r = x[3], x[4], x[5]
        delta, n = inp[0], inp[1]
        xh, yh, nh = self.hull_forces(u, v, r)
        xr, yr, nr = self.rudder_forces(u, v, r, delta, n)
        return xh + xr + self.propeller_thrust(u, v, r, n), yh + yr, nh + nr

    def masses(self):
        """(m + m_x, m + m_y, x_G m, I_zG + x_G² m + J_z) in SI units."""
        half = 0.5 * self.rho * self.L * self.L * self.d
        izg = self.m * (self.kzz * self.L) ** 2
        return (self.m + half * self.mx, self.m + half * self.my, self.xG * self.m,
                izg + self.xG * self.xG * self.m + half * self.L * self.L * self.Jz)

    def mass_entries(self) -> Mass3:
        """M = [[m + m_x, 0, 0], [0, m + m_y, x_G m], [0, x_G m, I_zG + x_G² m + J_z]] (midship)."""
        a, b, c, e = self.masses()
        return Mass3(a, b, c, c, e)

    def effect_twins(self) -> dict[str, str]:
        """A rudder zero error is this model's own ``delta0`` (:meth:`AbstractModel.effect_twins`)."""
        return {"rudder_offset": "delta0"}

    def vector_field(self, t, x, u):
        return jnp.stack(self.vector_field_parts(t, parts(x), parts(u)))

    def vector_field_parts(self, t, xs, us):
        """The vector field on scalar components (:meth:`AbstractModel.vector_field_parts`)."""
        psi, uu, v, r = xs[2], xs[3], xs[4], xs[5]
        X, Y, N = self.forces(xs, us)
        a, b, c, _ = self.masses()
        # M ν̇ = (X + b v r + c r², Y − a u r, N − c u r)
        acc = self.solve_mass_parts(X + b * v * r + c * r * r, Y - a * uu * r, N - c * uu * r)
        xd, yd = self.position_rates(psi, uu, v)
        return (xd, yd, r, *acc)


def kvlcc2_mmg(**overrides: float) -> MMG:
    """The KVLCC2 L7 model-scale MMG model (Yasukawa & Yoshimura 2015), fresh water."""
    return MMG(**{**KVLCC2_L7, **overrides})
