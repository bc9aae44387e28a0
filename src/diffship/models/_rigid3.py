r"""The 3-DOF (surge, sway, yaw) mass matrix shared by the planar ship models.

Every 3-DOF model here (Fossen 3-DOF, the VMMs, MMG) has, about its origin on the centre
line, a mass matrix with surge decoupled from a 2×2 sway–yaw block:

.. math::
    M = \begin{bmatrix} a & 0 & 0\\ 0 & b & c\\ 0 & d & e \end{bmatrix},\qquad
    M^{-1}\tau = \Big(\frac{\tau_1}{a},\ \frac{e\tau_2 - c\tau_3}{be - cd},\
    \frac{b\tau_3 - d\tau_2}{be - cd}\Big)

(:math:`a = m - X_{\dot u}`, :math:`b = m - Y_{\dot v}`, :math:`c = m x_G - Y_{\dot r}`,
:math:`d = m x_G - N_{\dot v}`, :math:`e = I_z - N_{\dot r}` in Fossen's notation). The solve
is written out in closed form: no LAPACK call inside the integrator loop.

:class:`AbstractShip3` is the shared base: states ``(x0, y0, psi, u, v, r)``, a model-specific
:meth:`AbstractShip3.mass_entries`, and the public :meth:`~AbstractShip3.mass_matrix` and
:meth:`~AbstractShip3.solve_mass` built on it.
"""

from __future__ import annotations

from typing import ClassVar, NamedTuple

import jax.numpy as jnp
from jaxtyping import Array, Float

from ._base import AbstractModel

__all__ = ["AbstractShip3", "Mass3", "mass_matrix3", "solve_mass3", "solve_mass3_parts"]


class Mass3(NamedTuple):
    """Entries of ``M = [[a, 0, 0], [0, b, c], [0, d, e]]`` (scalars)."""

    a: Float[Array, ""]
    b: Float[Array, ""]
    c: Float[Array, ""]
    d: Float[Array, ""]
    e: Float[Array, ""]


def mass_matrix3(M: Mass3) -> Float[Array, "3 3"]:
    """The dense 3×3 matrix (for tests and reports; the vector fields use :func:`solve_mass3`)."""
    z = jnp.zeros_like(M.a)
    return jnp.stack([jnp.stack([M.a, z, z]), jnp.stack([z, M.b, M.c]), jnp.stack([z, M.d, M.e])])


def solve_mass3(M: Mass3, rhs: Float[Array, " 3"]) -> Float[Array, " 3"]:
    """:math:`M^{-1}\\,\\mathrm{rhs}` in closed form (module docstring)."""
    return jnp.stack(solve_mass3_parts(M, rhs[0], rhs[1], rhs[2]))


def solve_mass3_parts(M: Mass3, X, Y, N) -> tuple:
    """:func:`solve_mass3` on scalar components: ``(u̇, v̇, ṙ)``."""
    # reciprocals of the parameters, then products: inside the time step a quotient whose value has
    # several users (its forward-mode tangents) is a kernel of its own on a CPU
    inv_a, inv_det = 1.0 / M.a, 1.0 / (M.b * M.e - M.c * M.d)
    return X * inv_a, (M.e * Y - M.c * N) * inv_det, (M.b * N - M.d * Y) * inv_det


class AbstractShip3(AbstractModel):
    """Base of the planar ship models: states ``(x0, y0, psi, u, v, r)`` and the mass solve."""

    state_names: ClassVar[tuple[str, ...]] = ("x0", "y0", "psi", "u", "v", "r")
    output_names: ClassVar[tuple[str, ...]] = ("x0", "y0", "psi", "u", "v", "r")

    def mass_entries(self) -> Mass3:
        """The entries a, b, c, d, e of the model's mass matrix (SI units)."""
        raise NotImplementedError

    def mass_matrix(self) -> Float[Array, "3 3"]:
        """M = M_RB + M_A (3×3, SI units)."""
        return mass_matrix3(self.mass_entries())

    def solve_mass(self, rhs: Float[Array, " 3"]) -> Float[Array, " 3"]:
        """M⁻¹·rhs (accelerations from generalised forces), closed form."""
        return solve_mass3(self.mass_entries(), rhs)

    def solve_mass_parts(self, X, Y, N) -> tuple:
        """:meth:`solve_mass` on scalar components."""
        return solve_mass3_parts(self.mass_entries(), X, Y, N)

    @staticmethod
    def position_rates(psi: Float[Array, ""], u: Float[Array, ""], v: Float[Array, ""]) -> tuple[Float[Array, ""], ...]:
        r"""Earth-fixed position rates :math:`\dot x_0 = u\cos\psi - v\sin\psi,\ \dot y_0 = u\sin\psi + v\cos\psi`."""
        c, s = jnp.cos(psi), jnp.sin(psi)
        return c * u - s * v, s * u + c * v
