"""Actuator maps: from what the controller commands to forces and moments.

An actuator map turns the model's input vector into body-frame generalised forces
``τ = (τ_x, τ_y, τ_z)`` [N, N, N·m] and may depend on the velocity state.
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

__all__ = ["ForceInput", "WaterJet"]


class ForceInput(eqx.Module):
    """Forces and moment measured or commanded directly: inputs ``tau_x, tau_y, tau_z``."""

    input_names: ClassVar[tuple[str, ...]] = ("tau_x", "tau_y", "tau_z")

    def __call__(self, u, nu):
        return u


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
        delta_n, rpm = u[0], u[1]
        total = self.n_jets * self.thrust(rpm, nu[0])
        tau_y = total * jnp.sin(delta_n)
        return jnp.stack([total * jnp.cos(delta_n), tau_y, -self.lever_arm * tau_y])
