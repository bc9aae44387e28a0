r"""Polynomial manoeuvring models (VMM: "vessel manoeuvring models") in the prime system.

Three members of one family, 3 DOF (surge, sway, yaw), states ``(x0, y0, psi, u, v, r)``
(earth-fixed position [m], heading [rad], body-fixed velocities at the origin CO [m/s, rad/s]),
inputs ``delta`` (rudder angle [rad], starboard-positive: positive δ gives positive r) and
``thrust`` (propeller thrust [N]):

* ``vmm_linear`` (:class:`VMMLinear`): forces linear in the prime velocities and rudder angle;
* ``vmm_simple`` (:class:`VMMSimple`): the linear model plus the dominant second/third-order
  hull terms (a reduced nonlinear model in the spirit of the "simple" models used with
  inverse-dynamics motion regression);
* ``vmm_abkowitz`` (:class:`VMMAbkowitz`): an Abkowitz-type third-order Taylor expansion in
  surge perturbation, sway, yaw rate and rudder angle, with speed–rudder cross terms.

Rigid-body equations (origin CO on the centre line, CG at :math:`(x_G, 0)`, :math:`I_z` about
CO, added masses diagonal except the sway–yaw pair; the rigid-body Coriolis terms are written
explicitly, so the hydrodynamic derivatives below contain no rigid-body parts):

.. math::
    (m - X_{\dot u})\dot u &= X_H + m(vr + x_G r^2) \\
    (m - Y_{\dot v})\dot v + (m x_G - Y_{\dot r})\dot r &= Y_H - m u r \\
    (m x_G - N_{\dot v})\dot v + (I_z - N_{\dot r})\dot r &= N_H - m x_G u r

with :math:`\dot x_0 = u\cos\psi - v\sin\psi`, :math:`\dot y_0 = u\sin\psi + v\cos\psi`,
:math:`\dot\psi = r` (x north/forward, y east/starboard, ψ clockwise).

**Prime system** (Norrbin/SNAME "prime I"): the reference length is the ship length ``L``, the
reference speed the *instantaneous* speed :math:`U = \sqrt{u^2 + v^2}` and the density ρ.
Dimensionless quantities (primes):

===========================  ===========================================
quantity                     prime
===========================  ===========================================
surge speed perturbation     :math:`\Delta u' = (u - U_0)/U` (``U0`` = approach speed, fixed)
sway velocity                :math:`v' = v/U`
yaw rate                     :math:`r' = rL/U`
thrust                       :math:`T' = T/(\tfrac12\rho L^2U^2)`
forces X, Y                  :math:`X' = X/(\tfrac12\rho L^2U^2)`
yaw moment N                 :math:`N' = N/(\tfrac12\rho L^3U^2)`
mass, surge/sway added mass  :math:`m' = m/(\tfrac12\rho L^3)`
sway–yaw added mass          :math:`Y'_{\dot r} = Y_{\dot r}/(\tfrac12\rho L^4)` (same for :math:`N_{\dot v}`)
yaw inertia, added inertia   :math:`I'_z = I_z/(\tfrac12\rho L^5)`
===========================  ===========================================

The parameters are the prime hydrodynamic derivatives (a polynomial coefficient named after
its monomial: ``Yvvr`` multiplies :math:`v'^2r'`, ``Yud`` multiplies :math:`\Delta u'\delta`),
so that :math:`X_H = \tfrac12\rho L^2U^2\,X'(\Delta u', v', r', \delta, T')` etc., with the
thrust entering surge as :math:`X'_T T'` (:math:`X'_T = 1 - t`, thrust deduction; fixed by
default) and a constant resistance coefficient ``X0`` (< 0). The instantaneous U makes the
linear model's forces scale with speed (:math:`Y = \tfrac12\rho L^2 U Y'_v v`), as in
Abkowitz's expansion; ``U0`` only defines the surge perturbation. m, I_z, x_G (dimensional),
L, ρ, U0 and :math:`X'_T` are fixed parameters; the added masses (prime) are fixed by default
("given", e.g. from strip theory) and can be freed.

**Equation error** (inverse dynamics and motion regression): from measured u, v, r and
their filtered derivatives, the hydrodynamic forces follow from the rigid-body equations
above (inverse dynamics); made prime, they are linear in the derivatives, one regression per
DOF with a feature matrix built from the model's own monomials:

.. math::
    e_X = \frac{(m - X_{\dot u})\dot u - m(vr + x_G r^2)}{\tfrac12\rho L^2U^2} - X'(\cdot),\quad
    e_Y = \frac{(m - Y_{\dot v})\dot v + (m x_G - Y_{\dot r})\dot r + m u r}{\tfrac12\rho L^2U^2} - Y'(\cdot),

and :math:`e_N` likewise over :math:`\tfrac12\rho L^3U^2`. With the added masses fixed the
three regressions are independent ordinary least squares (what
:func:`diffship.fit.fit_equation_error` solves, in one Gauss–Newton step); output error then
refines from there.

**Parameters** are declared once, as fields of the common base :class:`VMM` (every
derivative of the monomial table, the added masses and the fixed rigid-body and reference
quantities); a member's ``PARAMS`` are the fixed quantities, the added masses and the
derivatives of its own polynomial (``X_TERMS + Y_TERMS + N_TERMS``), in declaration order. The
mass matrix is the shared 3-DOF one (:mod:`diffship.models._rigid3`), with the prime added
masses made dimensional.

**Speed conventions** (``prime_speed``). With primes on the instantaneous speed (``"instantaneous"``,
the default of ``vmm_linear`` and ``vmm_simple``) every force scales with U² by construction, and a
speed–rudder term :math:`Y'_{u\delta}\Delta u'\delta` changes that scaling: Abkowitz's relations
:math:`Y'_{u\delta} = 2Y'_\delta,\ Y'_{uu\delta} = Y'_\delta` would make the rudder force
:math:`\propto U^2(1 + \Delta u')^2`, zero at u = U0/2. Those relations belong to Abkowitz's expansion
about the approach speed (``"approach"``, the default of ``vmm_abkowitz``): primes on U0,
:math:`\Delta u' = (u - U_0)/U_0`, forces :math:`\tfrac12\rho L^2U_0^2X'`, so that
:math:`\tfrac12\rho L^2U_0^2 Y'_\delta(1 + \Delta u')^2\delta = \tfrac12\rho L^2u^2Y'_\delta\delta` and
:math:`Y'_{vu} = Y'_v` gives :math:`\tfrac12\rho L^2 u Y'_v v` at every speed. :meth:`VMM.convention_warnings`
says when the data's speeds leave the range a coefficient set is valid in.

**Propulsion** (``propulsion``): the thrust T is the measured input ``thrust`` [N]
(:class:`~diffship.models.actuators.ThrustInput`, default), the propeller speed ``n`` [1/s] through an
open-water curve (:class:`~diffship.models.actuators.OpenWaterPropeller`, wake fraction w; the thrust
deduction is :math:`X'_T = 1 - t`), or a constant (:class:`~diffship.models.actuators.ConstantThrust`).

Reference values: an illustrative single-screw cargo ship, derivative magnitudes after the
Mariner-class derivatives of Chislett & Strøm-Tejsen (1965) as tabulated in Fossen's MSS
toolbox (``mariner.m``), with the rudder sign flipped to starboard-positive, the rigid-body
terms taken out of :math:`Y'_r, N'_r, X'_{vr}, X'_{rr}` (they are explicit here), the
propeller-asymmetry terms dropped, and a resistance/thrust balance added (``X0``, ``XT``).
It is a plausible, stable test ship — not a validated replica of the Mariner.

References:
    M. A. Abkowitz, *Lectures on ship hydrodynamics — steering and manoeuvrability*, Hy-5,
    Hydro- og Aerodynamisk Laboratorium, Lyngby 1964.
    N. H. Norrbin, "Theory and observations on the use of a mathematical model for ship
    manoeuvring in deep and confined waters", SSPA Publ. 68, 1971.
    M. S. Chislett, J. Strøm-Tejsen, "Planar motion mechanism tests and full-scale steering
    and manoeuvring predictions for a Mariner class vessel", Int. Shipbuilding Progress 12, 1965.
    T. I. Fossen, *Handbook of Marine Craft Hydrodynamics and Motion Control*, 2nd ed., Wiley 2021, §6–7.
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from ._base import LinearForm, param
from ..particulars import VMM
from ._rigid3 import AbstractShip3, Mass3
from .actuators import ConstantThrust, OpenWaterPropeller, ThrustInput

__all__ = ["VMM", "VMMLinear", "VMMSimple", "VMMAbkowitz", "VMM_REFERENCE", "approach_thrust"]

_E5 = 1e-5

# -- reference ship (see module docstring) ------------------------------------------------
L_REF, RHO_REF, U0_REF = 160.93, 1025.0, 7.7175
_HALF_RHO_L3 = 0.5 * RHO_REF * L_REF**3
_XG_PRIME = -0.023
_M_PRIME, _IZG_PRIME = 798 * _E5, 39.2 * _E5
M_REF = _M_PRIME * _HALF_RHO_L3
XG_REF = _XG_PRIME * L_REF
IZ_REF = (_IZG_PRIME + _M_PRIME * _XG_PRIME**2) * 0.5 * RHO_REF * L_REF**5  # about CO

#: Reference prime derivatives (×1 — already multiplied by 1e-5 where listed so).
VMM_REFERENCE: dict[str, float] = {k: v * _E5 for k, v in dict(
    Xudot=-42.0, Yvdot=-748.0, Yrdot=-9.354, Nvdot=4.646, Nrdot=-43.8,
    X0=-100.0, Xu=-184.0, Xuu=-110.0, Xuuu=-215.0, Xvv=-899.0, Xrr=36.4, Xvr=0.0, Xdd=-95.0,
    Xudd=-190.0, Xrd=-93.0, Xvd=-93.0, Xuvd=-93.0,
    Yv=-1160.0, Yr=299.0, Yd=-278.0, Yvvv=-8078.0, Yvvr=15356.0, Yvu=-1160.0, Yru=299.0,
    Yddd=90.0, Yud=-556.0, Yuud=-278.0, Yvdd=-4.0, Yvvd=-1190.0, Y0=0.0,
    Nv=-264.0, Nr=-184.4, Nd=139.0, Nvvv=1636.0, Nvvr=-5483.0, Nvu=-264.0, Nru=-184.4,
    Nddd=-45.0, Nud=278.0, Nuud=139.0, Nvdd=13.0, Nvvd=489.0, N0=0.0,
).items()}  # fmt: skip
VMM_REFERENCE["XT"] = 0.8


def approach_thrust(X0: float = VMM_REFERENCE["X0"], XT: float = 0.8, U0: float = U0_REF,
                    L: float = L_REF, rho: float = RHO_REF) -> float:
    """Thrust [N] that holds the approach speed U0 on a straight course: X'_0 + X'_T T' = 0."""
    return -X0 * 0.5 * rho * L**2 * U0**2 / XT


# Monomials: name -> powers of (Δu', v', r', δ). The parameter name is the coefficient.
_POWERS: dict[str, tuple[int, int, int, int]] = {
    "X0": (0, 0, 0, 0), "Xu": (1, 0, 0, 0), "Xuu": (2, 0, 0, 0), "Xuuu": (3, 0, 0, 0),
    "Xvv": (0, 2, 0, 0), "Xrr": (0, 0, 2, 0), "Xvr": (0, 1, 1, 0), "Xdd": (0, 0, 0, 2),
    "Xudd": (1, 0, 0, 2), "Xrd": (0, 0, 1, 1), "Xvd": (0, 1, 0, 1), "Xuvd": (1, 1, 0, 1),
    "Yv": (0, 1, 0, 0), "Yr": (0, 0, 1, 0), "Yd": (0, 0, 0, 1), "Yvvv": (0, 3, 0, 0),
    "Yvvr": (0, 2, 1, 0), "Yvu": (1, 1, 0, 0), "Yru": (1, 0, 1, 0), "Yddd": (0, 0, 0, 3),
    "Yud": (1, 0, 0, 1), "Yuud": (2, 0, 0, 1), "Yvdd": (0, 1, 0, 2), "Yvvd": (0, 2, 0, 1), "Y0": (0, 0, 0, 0),
    "Nv": (0, 1, 0, 0), "Nr": (0, 0, 1, 0), "Nd": (0, 0, 0, 1), "Nvvv": (0, 3, 0, 0),
    "Nvvr": (0, 2, 1, 0), "Nvu": (1, 1, 0, 0), "Nru": (1, 0, 1, 0), "Nddd": (0, 0, 0, 3),
    "Nud": (1, 0, 0, 1), "Nuud": (2, 0, 0, 1), "Nvdd": (0, 1, 0, 2), "Nvvd": (0, 2, 0, 1), "N0": (0, 0, 0, 0),
}  # fmt: skip

_ADDED = {"Xudot": "surge added mass", "Yvdot": "sway added mass", "Yrdot": "sway–yaw added mass",
          "Nvdot": "yaw–sway added mass", "Nrdot": "yaw added inertia"}


def _added(name: str):
    """A prime added mass: fixed ("given") by default."""
    v = VMM_REFERENCE[name]
    return param(v, free=False, scale=max(abs(v), 1e-4), unit="-", description=f"{_ADDED[name]} (prime)")


def _ref(name: str):
    """A prime hydrodynamic derivative (free); used by a member only if in its polynomial."""
    v = VMM_REFERENCE[name]
    return param(v, scale=max(abs(v), 1e-3), unit="-",
                 description=f"prime derivative of {name[0]} w.r.t. {name[1:] or 'const'}")


class VMM(AbstractShip3):
    """Base of the polynomial manoeuvring models (see the module docstring).

    Subclasses choose the polynomial by the class variables ``X_TERMS``, ``Y_TERMS``,
    ``N_TERMS`` (names from the monomial table). Every derivative is declared once here as a
    parameter field; a member's ``PARAMS`` are the fixed rigid-body and reference quantities,
    the added masses and the derivatives of its own polynomial (:meth:`_select_params`); the
    other fields are ignored.
    """

    name: ClassVar[str] = "vmm"
    EQUATIONS: ClassVar[tuple[str, ...]] = ("X'", "Y'", "N'")
    EQUATION_CHANNELS: ClassVar[tuple[str, ...]] = ("u", "v", "r")
    X_TERMS: ClassVar[tuple[str, ...]] = ()
    Y_TERMS: ClassVar[tuple[str, ...]] = ()
    N_TERMS: ClassVar[tuple[str, ...]] = ()
    PARTICULARS: ClassVar[dict[str, str]] = VMM
    REFERENCE_VESSEL: ClassVar[str | None] = "mariner"

    m: jnp.ndarray = param(M_REF, free=False, lower=0.0, scale=M_REF, unit="kg", description="mass")
    Iz: jnp.ndarray = param(IZ_REF, free=False, lower=0.0, scale=IZ_REF, unit="kg m2", description="yaw inertia about CO")
    xG: jnp.ndarray = param(XG_REF, free=False, scale=L_REF / 50, unit="m",
                            description="longitudinal CG (from CO, + forward)")
    L: jnp.ndarray = param(L_REF, free=False, lower=0.0, scale=L_REF, unit="m", description="reference length (Lpp)")
    rho: jnp.ndarray = param(RHO_REF, free=False, lower=0.0, scale=1000.0, unit="kg/m3", description="water density")
    U0: jnp.ndarray = param(U0_REF, free=False, lower=0.0, scale=U0_REF, unit="m/s",
                            description="approach speed (Δu' = (u−U0)/U)")
    XT: jnp.ndarray = param(VMM_REFERENCE["XT"], free=False, scale=1.0, unit="-", description="thrust factor 1 − t (X'_T)")
    Xudot: jnp.ndarray = _added("Xudot")
    Yvdot: jnp.ndarray = _added("Yvdot")
    Yrdot: jnp.ndarray = _added("Yrdot")
    Nvdot: jnp.ndarray = _added("Nvdot")
    Nrdot: jnp.ndarray = _added("Nrdot")
    dwP: jnp.ndarray = param(0.0, free=False, scale=0.1, unit="-",
                             description="wake-fraction correction Δw of the open-water propeller map (w = w_vessel + Δw; "
                                         "--propulsion propeller only)")
    X0: jnp.ndarray = _ref("X0")
    Xu: jnp.ndarray = _ref("Xu")
    Xuu: jnp.ndarray = _ref("Xuu")
    Xuuu: jnp.ndarray = _ref("Xuuu")
    Xvv: jnp.ndarray = _ref("Xvv")
    Xrr: jnp.ndarray = _ref("Xrr")
    Xvr: jnp.ndarray = _ref("Xvr")
    Xdd: jnp.ndarray = _ref("Xdd")
    Xudd: jnp.ndarray = _ref("Xudd")
    Xrd: jnp.ndarray = _ref("Xrd")
    Xvd: jnp.ndarray = _ref("Xvd")
    Xuvd: jnp.ndarray = _ref("Xuvd")
    Yv: jnp.ndarray = _ref("Yv")
    Yr: jnp.ndarray = _ref("Yr")
    Yd: jnp.ndarray = _ref("Yd")
    Yvvv: jnp.ndarray = _ref("Yvvv")
    Yvvr: jnp.ndarray = _ref("Yvvr")
    Yvu: jnp.ndarray = _ref("Yvu")
    Yru: jnp.ndarray = _ref("Yru")
    Yddd: jnp.ndarray = _ref("Yddd")
    Yud: jnp.ndarray = _ref("Yud")
    Yuud: jnp.ndarray = _ref("Yuud")
    Yvdd: jnp.ndarray = _ref("Yvdd")
    Yvvd: jnp.ndarray = _ref("Yvvd")
    Y0: jnp.ndarray = _ref("Y0")
    Nv: jnp.ndarray = _ref("Nv")
    Nr: jnp.ndarray = _ref("Nr")
    Nd: jnp.ndarray = _ref("Nd")
    Nvvv: jnp.ndarray = _ref("Nvvv")
    Nvvr: jnp.ndarray = _ref("Nvvr")
    Nvu: jnp.ndarray = _ref("Nvu")
    Nru: jnp.ndarray = _ref("Nru")
    Nddd: jnp.ndarray = _ref("Nddd")
    Nud: jnp.ndarray = _ref("Nud")
    Nuud: jnp.ndarray = _ref("Nuud")
    Nvdd: jnp.ndarray = _ref("Nvdd")
    Nvvd: jnp.ndarray = _ref("Nvvd")
    N0: jnp.ndarray = _ref("N0")
    #: Reference speed of the prime system: ``"instantaneous"`` (U = √(u² + v²); forces scale with U², the
    #: right system for coefficient sets without speed cross terms) or ``"approach"`` (U0: Abkowitz's
    #: expansion about the approach speed, where Y'_uδ = 2Y'_δ, Y'_uuδ = Y'_δ make the rudder force scale with
    #: u² at every speed; ``vmm_abkowitz``'s default). See "Speed conventions" in the module docstring.
    prime_speed: str = eqx.field(static=True, default="instantaneous")
    #: Where the thrust comes from: the measured ``thrust`` input [N] (default), propeller speed ``n`` through
    #: an open-water curve (:class:`~diffship.models.actuators.OpenWaterPropeller`), or a constant.
    propulsion: ThrustInput | OpenWaterPropeller | ConstantThrust = eqx.field(default_factory=ThrustInput)

    @classmethod
    def _select_params(cls, declared):
        used = set(cls.X_TERMS + cls.Y_TERMS + cls.N_TERMS)
        return tuple(n for n in declared if n not in _POWERS or n in used)

    @property
    def input_names(self) -> tuple[str, ...]:
        return ("delta",) + self.propulsion.input_names

    # -- prime system ---------------------------------------------------------------------
    def speed(self, u, v):
        """Reference speed of the prime system [m/s]: the instantaneous U = sqrt(u² + v²) (floored at
        1 mm/s), or U0 when ``prime_speed == "approach"``."""
        if self.prime_speed == "approach":
            return self.U0 + 0.0 * u
        return jnp.sqrt(u * u + v * v + 1e-6)

    def primes(self, nu, inp):
        """(Δu', v', r', δ, T') and U from body velocities and inputs."""
        u, v, r = nu[0], nu[1], nu[2]
        U = self.speed(u, v)
        q = 0.5 * self.rho * self.L**2 * U * U
        return (u - self.U0) / U, v / U, r * self.L / U, inp[0], self.propulsion.thrust(inp[1:], u, self.dwP) / q, U

    @staticmethod
    def _poly(model, terms, du, v, r, d):
        """Σ coefficient·monomial, evaluated term by term (scalars only)."""
        pw = {"u": [1.0, du, du * du, du * du * du], "v": [1.0, v, v * v, v * v * v],
              "r": [1.0, r, r * r, r * r * r], "d": [1.0, d, d * d, d * d * d]}
        total = 0.0
        for name in terms:
            a, b, c, e = _POWERS[name]
            mono = pw["u"][a] * pw["v"][b] * pw["r"][c] * pw["d"][e]
            total = total + getattr(model, name) * mono
        return total

    def hydro_prime(self, nu, inp):
        """Prime hydrodynamic force and moment (X', Y', N') including the thrust term."""
        du, v, r, d, T, _ = self.primes(nu, inp)
        X = self._poly(self, self.X_TERMS, du, v, r, d) + self.XT * T
        Y = self._poly(self, self.Y_TERMS, du, v, r, d)
        N = self._poly(self, self.N_TERMS, du, v, r, d)
        return X, Y, N

    def added_masses(self):
        """Dimensional added masses (X_u̇, Y_v̇, Y_ṙ, N_v̇, N_ṙ) [kg, kg, kg m, kg m, kg m²]."""
        h = 0.5 * self.rho
        L = self.L
        return (self.Xudot * h * L**3, self.Yvdot * h * L**3, self.Yrdot * h * L**4,
                self.Nvdot * h * L**4, self.Nrdot * h * L**5)

    def mass_entries(self) -> Mass3:
        """M = M_RB + M_A (dimensional): surge decoupled, sway–yaw block."""
        Xud, Yvd, Yrd, Nvd, Nrd = self.added_masses()
        mx = self.m * self.xG
        return Mass3(self.m - Xud, self.m - Yvd, mx - Yrd, mx - Nvd, self.Iz - Nrd)

    def vector_field(self, t, x, inp):
        psi, u, v, r = x[2], x[3], x[4], x[5]
        nu = x[3:]
        Xp, Yp, Np = self.hydro_prime(nu, inp)
        U = self.speed(u, v)
        q = 0.5 * self.rho * self.L**2 * U * U
        X = q * Xp + self.m * (v * r + self.xG * r * r)
        Y = q * Yp - self.m * u * r
        N = q * self.L * Np - self.m * self.xG * u * r
        xd, yd = self.position_rates(psi, u, v)
        return jnp.concatenate([jnp.stack([xd, yd, r]), self.solve_mass(jnp.stack([X, Y, N]))])

    def convention_warnings(self, u_low: float, u_high: float) -> list[str]:
        r"""Where the data's speeds ``u_low..u_high`` [m/s] leave the range the coefficients are valid in.

        Instantaneous primes: the rudder force per δ relative to its U²-scaled value is
        :math:`f = 1 + (Y'_{u\delta}/Y'_\delta)\Delta u' + (Y'_{uu\delta}/Y'_\delta)\Delta u'^2`; with
        Abkowitz's Y'_uδ = 2Y'_δ it is (1 + Δu')², zero at u = U0/2. Approach-speed primes: a Taylor
        expansion about U0, trusted for |u − U0| ≤ U0/2.
        """
        U0, out = float(self.U0), []
        if self.prime_speed == "approach":
            if u_low < 0.5 * U0 or u_high > 1.5 * U0:
                out.append(f"model {self.name}: data speeds {u_low:.3g}–{u_high:.3g} m/s leave 0.5–1.5 × U0 = "
                           f"{U0:.3g} m/s, the range of its expansion about the approach speed")
            return out
        for dof in ("Y", "N"):
            d, ud, uud = (f"{dof}d", f"{dof}ud", f"{dof}uud")
            terms = self.Y_TERMS + self.N_TERMS
            if d not in terms or (ud not in terms and uud not in terms) or float(getattr(self, d)) == 0.0:
                continue
            a = float(getattr(self, ud)) / float(getattr(self, d)) if ud in terms else 0.0
            b = float(getattr(self, uud)) / float(getattr(self, d)) if uud in terms else 0.0
            for u in (u_low, u_high):
                du = (u - U0) / max(u, 1e-3)
                f = 1.0 + a * du + b * du * du
                if not 0.5 <= f <= 2.0:
                    out.append(f"model {self.name}: at u = {u:.3g} m/s the rudder {dof} force is {f:.2g} × its "
                               f"U²-scaled value ({dof}'_uδ/{dof}'_δ = {a:.3g} on primes of the instantaneous speed; "
                               f"Abkowitz's {dof}'_uδ = 2{dof}'_δ holds for primes on U0: prime_speed='approach')")
                    break
        return out

    # -- equation error (inverse dynamics + motion regression) ----------------------------
    def inverse_dynamics_prime(self, nu, nu_dot):
        """Prime hydrodynamic forces that the measured motion requires (the regression labels)."""
        u, v, r = nu[0], nu[1], nu[2]
        ud, vd, rd = nu_dot[0], nu_dot[1], nu_dot[2]
        Xud, Yvd, Yrd, Nvd, Nrd = self.added_masses()
        U = self.speed(u, v)
        q = 0.5 * self.rho * self.L**2 * U * U
        fX = (self.m - Xud) * ud - self.m * (v * r + self.xG * r * r)
        fY = (self.m - Yvd) * vd + (self.m * self.xG - Yrd) * rd + self.m * u * r
        fN = (self.m * self.xG - Nvd) * vd + (self.Iz - Nrd) * rd + self.m * self.xG * u * r
        return fX / q, fY / q, fN / (q * self.L)

    def equation_residual(self, z, zd, zdd, inp):
        """(e_X, e_Y, e_N) at one sample: inverse-dynamics prime forces minus the polynomial."""
        fX, fY, fN = self.inverse_dynamics_prime(z, zd)
        Xp, Yp, Np = self.hydro_prime(z, inp)
        return jnp.stack([fX - Xp, fY - Yp, fN - Np])

    def regressors(self, z, zd, zdd, inp):
        """Seed 000's motion regression, one linear form per DOF (broadcast over samples).

        Labels: the inverse-dynamics prime forces (the known thrust term taken out of X');
        regressors: the model's own monomials of (Δu', v', r', δ); coefficients: its
        derivatives. Exact least squares of the equation error when the added masses are fixed.
        """
        nu, nud, u = (jnp.moveaxis(a, -1, 0) for a in (z, zd, inp))
        fX, fY, fN = self.inverse_dynamics_prime(nu, nud)
        du, v, r, d, T, _ = self.primes(nu, u)
        pw = {"u": du, "v": v, "r": r, "d": d}
        labels = {"X": fX - self.XT * T, "Y": fY, "N": fN}
        out = {}
        for dof, terms in (("X", self.X_TERMS), ("Y", self.Y_TERMS), ("N", self.N_TERMS)):
            cols = [_monomial(pw, _POWERS[n]) for n in terms]
            out[dof] = LinearForm(jnp.stack(cols, -1), labels[dof], terms)
        return out


def _monomial(pw, powers):
    out = jnp.ones_like(pw["u"])
    for k, e in zip("uvrd", powers):
        for _ in range(e):
            out = out * pw[k]
    return out


class VMMLinear(VMM):
    r"""Linear VMM: :math:`X' = X'_0 + X'_u\Delta u' + X'_T T'`,
    :math:`Y' = Y'_v v' + Y'_r r' + Y'_\delta\delta`, :math:`N' = N'_v v' + N'_r r' + N'_\delta\delta`."""

    name: ClassVar[str] = "vmm_linear"
    X_TERMS: ClassVar[tuple[str, ...]] = ("X0", "Xu")
    Y_TERMS: ClassVar[tuple[str, ...]] = ("Yv", "Yr", "Yd")
    N_TERMS: ClassVar[tuple[str, ...]] = ("Nv", "Nr", "Nd")


class VMMSimple(VMM):
    r"""Reduced nonlinear VMM: the linear model plus
    :math:`X'_{vv}v'^2 + X'_{rr}r'^2 + X'_{vr}v'r' + X'_{\delta\delta}\delta^2` in surge and
    :math:`(\cdot)_{vvv}v'^3 + (\cdot)_{vvr}v'^2r'` in sway and yaw."""

    name: ClassVar[str] = "vmm_simple"
    X_TERMS: ClassVar[tuple[str, ...]] = ("X0", "Xu", "Xvv", "Xrr", "Xvr", "Xdd")
    Y_TERMS: ClassVar[tuple[str, ...]] = ("Yv", "Yr", "Yd", "Yvvv", "Yvvr")
    N_TERMS: ClassVar[tuple[str, ...]] = ("Nv", "Nr", "Nd", "Nvvv", "Nvvr")


class VMMAbkowitz(VMM):
    r"""Abkowitz-type cubic VMM (third-order Taylor expansion; odd in v', r', δ for Y and N,
    even for X, plus constant terms ``Y0``, ``N0`` for asymmetry)."""

    name: ClassVar[str] = "vmm_abkowitz"
    prime_speed: str = eqx.field(static=True, default="approach")
    X_TERMS: ClassVar[tuple[str, ...]] = ("X0", "Xu", "Xuu", "Xuuu", "Xvv", "Xrr", "Xvr", "Xdd", "Xudd", "Xrd", "Xvd",
                                          "Xuvd")
    Y_TERMS: ClassVar[tuple[str, ...]] = ("Yv", "Yr", "Yd", "Yvvv", "Yvvr", "Yvu", "Yru", "Yddd", "Yud", "Yuud", "Yvdd",
                                          "Yvvd", "Y0")
    N_TERMS: ClassVar[tuple[str, ...]] = ("Nv", "Nr", "Nd", "Nvvv", "Nvvr", "Nvu", "Nru", "Nddd", "Nud", "Nuud", "Nvdd",
                                          "Nvvd", "N0")

