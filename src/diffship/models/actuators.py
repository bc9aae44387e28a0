"""Actuator maps: from what the controller commands to forces and moments.

An actuator map turns the model's input vector into body-frame generalised forces
``τ = (τ_x, τ_y, τ_z)`` [N, N, N·m] and may depend on the velocity state.

Propulsion maps (:class:`ThrustInput`, :class:`OpenWaterPropeller`, :class:`ConstantThrust`) give the
propeller thrust ``T`` [N] from their inputs and the surge speed, ``thrust(inp, u)``; the polynomial
models (``VMM(propulsion=...)``) apply their own thrust factor :math:`X'_T = 1 - t` to it, and
``__call__`` gives the surge force :math:`(1 - t)T` for the force-input models.
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

__all__ = ["ConstantThrust", "ForceInput", "OpenWaterPropeller", "ThrustInput", "WaterJet"]


class ForceInput(eqx.Module):
    """Forces and moment measured or commanded directly: inputs ``tau_x, tau_y, tau_z``."""

    input_names: ClassVar[tuple[str, ...]] = ("tau_x", "tau_y", "tau_z")

    def __call__(self, u, nu):
        return u

    def parts(self, us, nu):
        """:meth:`__call__` on scalar components: ``(τ_x, τ_y, τ_z)``."""
        return us[0], us[1], us[2]


class WaterJet(eqx.Module):
    r"""Twin water-jet map of the high-speed USV *Odin* (seed 002, §6.1.1, fitted by FFI).

    Inputs: ``delta_n`` nozzle angle [rad] (±27° on the real craft) and ``rpm`` jet motor
    speed [rev/min]; both jets share them. Per jet

    .. math::
        T(n, u) = c_0 + c_1 n + c_2 n^2 + u(c_3 + c_4 n + c_5 n^2) + u^2(c_6 + c_7 n + c_8 n^2)

    with the published coefficients (``u`` is used in m/s as the published polynomial is
    written; the source mentions a knots conversion ``û = 1.94u`` that the final polynomial
    does not show), and

    .. math::
        τ_x = 2T\cos δ_n,\quad τ_y = 2T\sin δ_n,\quad τ_z = -l_x τ_y,\ l_x = 3.82\ \text{m}.
    """

    input_names: ClassVar[tuple[str, ...]] = ("delta_n", "rpm")
    coefficients: tuple[float, ...] = eqx.field(
        static=True,
        default=(118.31, -2.47, 7.35e-3, -6.56, 0.14, -4.07e-4, 0.063, -1.31e-3, 3.90e-6),
    )
    lever_arm: float = eqx.field(static=True, default=3.82)
    n_jets: int = eqx.field(static=True, default=2)

    def thrust(self, rpm, u):
        """Thrust of one jet [N] at jet speed ``rpm`` [rev/min] and surge speed ``u`` [m/s]."""
        c = self.coefficients
        return (
            c[0] + c[1] * rpm + c[2] * rpm**2
            + u * (c[3] + c[4] * rpm + c[5] * rpm**2)
            + u**2 * (c[6] + c[7] * rpm + c[8] * rpm**2)
        )

    def __call__(self, u, nu):
        return jnp.stack(self.parts(u, nu))

    def parts(self, us, nu):
        """:meth:`__call__` on scalar components: ``(τ_x, τ_y, τ_z)``."""
        delta_n, rpm = us[0], us[1]
        total = self.n_jets * self.thrust(rpm, nu[0])
        tau_y = total * jnp.sin(delta_n)
        return total * jnp.cos(delta_n), tau_y, -self.lever_arm * tau_y


class ThrustInput(eqx.Module):
    """Thrust measured (or commanded) directly: input ``thrust`` [N]."""

    input_names: ClassVar[tuple[str, ...]] = ("thrust",)

    def thrust(self, inp, u, dw=0.0):
        """The measured thrust [N] (``dw``, a wake-fraction correction, does not enter)."""
        return inp[0]


class ConstantThrust(eqx.Module):
    """A constant thrust ``value`` [N] (no input column): e.g. a run at fixed propeller speed without a
    thrust measurement."""

    input_names: ClassVar[tuple[str, ...]] = ()
    value: float = eqx.field(static=True, default=0.0)

    def thrust(self, inp, u, dw=0.0):
        """The constant thrust [N] (``dw`` does not enter)."""
        return self.value + 0.0 * u


class OpenWaterPropeller(eqx.Module):
    r"""Propeller thrust from its speed through the open-water curve (input ``n`` [1/s], ahead n > 0):

    .. math::
        T = N_P\,\rho\, n|n|\, D^4 K_T(J),\qquad J = \frac{u(1 - w)}{nD},\qquad K_T(J) = \sum_i k_i J^i

    with ``count`` :math:`N_P` propellers of diameter ``diameter`` :math:`D` [m], wake fraction ``wake_fraction``
    :math:`w` (straight motion), open-water coefficients ``kt`` :math:`(k_0, k_1, \dots)` and water density
    ``rho`` [kg/m³]; ``thrust_deduction`` :math:`t` is used by :meth:`__call__` only (the VMMs have X'_T = 1 − t).
    The wake fraction is the vessel's value plus a correction :math:`\Delta w` that a fit can estimate (the
    VMMs' parameter ``dwP``, ``--free dwP``): :math:`J = u(1 - w - \Delta w)/(nD)`.
    Valid for ahead operation (0 ≤ J below the K_T zero); the advance ratio's denominator is floored at 1e-9 m/s.
    Build it from a vessel file with :func:`diffship.vessel.propeller_map`.

    Reference: J. Carlton, *Marine Propellers and Propulsion*, 4th ed., 2019, ch. 6 (open-water characteristics).
    """

    input_names: ClassVar[tuple[str, ...]] = ("n",)
    diameter: float = eqx.field(static=True, default=1.0)
    kt: tuple[float, ...] = eqx.field(static=True, default=(0.3, -0.3))
    wake_fraction: float = eqx.field(static=True, default=0.0)
    thrust_deduction: float = eqx.field(static=True, default=0.0)
    rho: float = eqx.field(static=True, default=1025.0)
    count: int = eqx.field(static=True, default=1)

    def kt_of(self, J):
        """K_T(J) (Horner form)."""
        out = 0.0 * J
        for c in reversed(self.kt):
            out = out * J + c
        return out

    def thrust(self, inp, u, dw=0.0):
        """Thrust [N] at propeller speed ``inp[0]`` [1/s] and surge speed ``u`` [m/s], with the wake fraction
        ``wake_fraction + dw`` (``dw``: the fitted correction, the VMMs' parameter ``dwP``)."""
        n = inp[0]
        nd = n * self.diameter
        J = u * (1.0 - self.wake_fraction - dw) / jnp.where(jnp.abs(nd) > 1e-9, nd, 1e-9)
        return self.count * self.rho * n * jnp.abs(n) * self.diameter**4 * self.kt_of(J)

    def __call__(self, inp, nu):
        X = (1.0 - self.thrust_deduction) * self.thrust(inp, nu[0])
        z = 0.0 * X
        return jnp.stack([X, z, z])
