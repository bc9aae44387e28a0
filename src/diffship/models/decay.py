r"""One-degree-of-freedom free-decay models for the output-error path (see :mod:`diffship.decay`).

* :class:`Decay1` (``"decay1"``): :math:`m\dot x + Dx = \tau`, channel ``velocity``;
* :class:`Decay2` (``"decay2"``): :math:`I\ddot\phi + b\dot\phi + k\phi = \tau`, channels
  ``angle`` (and optionally ``rate``).

Input ``tau`` (force or moment; zero in a free decay, and taken as zero when a run has no ``tau``
column: ``INPUT_DEFAULTS``). Each also declares its equation-error
form (affine in the damping) so that :func:`diffship.fit.fit_equation_error` works:
:math:`e = m\dot x + Dx - \tau` on the filtered ``velocity`` and its derivative, and
:math:`e = I\ddot\phi + b\dot\phi + k\phi - \tau` on the filtered ``angle`` and its first
and second derivatives.
"""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp

from ..particulars import DECAY1, DECAY2
from ._base import AbstractModel, param

__all__ = ["Decay1", "Decay2"]


class Decay1(AbstractModel):
    r"""First-order 1-DOF model :math:`m\dot x + Dx = \tau` (state/channel ``velocity``, input ``tau``).

    ``m`` fixed (total inertia, given), ``D`` > 0 free."""

    name: ClassVar[str] = "decay1"
    state_names: ClassVar[tuple[str, ...]] = ("velocity",)
    output_names: ClassVar[tuple[str, ...]] = ("velocity",)
    angle_outputs: ClassVar[tuple[str, ...]] = ()
    EQUATIONS: ClassVar[tuple[str, ...]] = ("force",)
    EQUATION_CHANNELS: ClassVar[tuple[str, ...]] = ("velocity",)
    #: the DOF's total inertia is not a vessel-file quantity (which DOF decays is the test's): ``--fix m=VALUE``
    PARTICULARS: ClassVar[dict[str, str]] = DECAY1
    INPUT_DEFAULTS: ClassVar[dict[str, float]] = {"tau": 0.0}

    m: jnp.ndarray = param(1.0, free=False, lower=0.0, scale=1.0, unit="kg", description="total inertia (rigid + added)")
    D: jnp.ndarray = param(1.0, lower=0.0, scale=1.0, unit="kg/s", description="linear damping")

    @property
    def input_names(self) -> tuple[str, ...]:
        return ("tau",)

    def vector_field(self, t, x, u):
        return jnp.stack([(u[0] - self.D * x[0]) / self.m])

    def equation_residual(self, z, zd, zdd, u):
        """e = m·ẋ + D·x − τ (affine in D)."""
        return jnp.stack([self.m * zd[0] + self.D * z[0] - u[0]])


class Decay2(AbstractModel):
    r"""Second-order 1-DOF model :math:`I\ddot\phi + b\dot\phi + k\phi = \tau` (states ``angle``, ``rate``).

    ``I`` and ``k`` fixed (given), ``b`` > 0 free; free ``k`` instead when the stiffness is
    unknown and the inertia trusted."""

    name: ClassVar[str] = "decay2"
    state_names: ClassVar[tuple[str, ...]] = ("angle", "rate")
    output_names: ClassVar[tuple[str, ...]] = ("angle", "rate")
    angle_outputs: ClassVar[tuple[str, ...]] = ()
    EQUATIONS: ClassVar[tuple[str, ...]] = ("moment",)
    EQUATION_CHANNELS: ClassVar[tuple[str, ...]] = ("angle",)
    EQUATION_ORDER: ClassVar[int] = 2
    #: ``--fix`` both, or fix one and ``--free`` the other (the decay gives only k/I and b/I)
    PARTICULARS: ClassVar[dict[str, str]] = DECAY2
    INPUT_DEFAULTS: ClassVar[dict[str, float]] = {"tau": 0.0}

    I: jnp.ndarray = param(  # noqa: E741
        1.0, free=False, lower=0.0, scale=1.0, unit="kg m2", description="total inertia (rigid + added)")
    b: jnp.ndarray = param(0.1, lower=0.0, scale=1.0, unit="kg m2/s", description="linear damping")
    k: jnp.ndarray = param(1.0, free=False, lower=0.0, scale=1.0, unit="N m/rad", description="restoring stiffness")

    @property
    def input_names(self) -> tuple[str, ...]:
        return ("tau",)

    def vector_field(self, t, x, u):
        return jnp.stack([x[1], (u[0] - self.b * x[1] - self.k * x[0]) / self.I])

    def equation_residual(self, z, zd, zdd, u):
        """e = I·φ̈ + b·φ̇ + k·φ − τ (affine in b and k)."""
        return jnp.stack([self.I * zdd[0] + self.b * zd[0] + self.k * z[0] - u[0]])

    def states_for_channels(self, channels) -> tuple[str, ...]:
        # the initial rate shapes the whole angle trace: estimate it with the angle
        return ("angle", "rate") if "angle" in channels else tuple(c for c in channels if c in self.state_names)
