r"""One-degree-of-freedom free-decay models for the output-error path (see :mod:`diffship.decay`).

* :class:`Decay1` (``"decay1"``): :math:`m\dot x + Dx = \tau`, channel ``velocity``;
* :class:`Decay2` (``"decay2"``): :math:`I\ddot\phi + b\dot\phi + k\phi = \tau`, channels
  ``angle`` (and optionally ``rate``).

Input ``tau`` (force or moment; zero in a free decay). Each also carries its equation-error
regression (affine in the damping) so that :func:`diffship.fit.fit_equation_error` works.
"""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp
import numpy as np

from ..params import Param
from ..preprocess import smooth_and_derivative
from ._base import AbstractModel, scalar

__all__ = ["Decay1", "Decay2"]


class Decay1(AbstractModel):
    r"""First-order 1-DOF model :math:`m\dot x + Dx = \tau` (state/channel ``velocity``, input ``tau``).

    ``m`` fixed (total inertia, given), ``D`` > 0 free."""

    name: ClassVar[str] = "decay1"
    state_names: ClassVar[tuple[str, ...]] = ("velocity",)
    output_names: ClassVar[tuple[str, ...]] = ("velocity",)
    angle_outputs: ClassVar[tuple[str, ...]] = ()
    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("m", 1.0, free=False, lower=0.0, scale=1.0, unit="kg", description="total inertia (rigid + added)"),
        Param("D", 1.0, lower=0.0, scale=1.0, unit="kg/s", description="linear damping"),
    )
    m: jnp.ndarray = scalar(1.0)
    D: jnp.ndarray = scalar(1.0)

    @property
    def input_names(self) -> tuple[str, ...]:
        return ("tau",)

    def vector_field(self, t, x, u):
        return jnp.stack([(u[0] - self.D * x[0]) / self.m])

    # equation error: regression of m·ẋ + D·x = τ on the filtered derivative (affine in D)
    EQUATIONS: ClassVar[tuple[str, ...]] = ("force",)

    def equation_data(self, run, flt):
        run.require(("velocity", "tau"), f"equation error for {self.name}")
        x, xd = smooth_and_derivative(run.time, np.asarray(run["velocity"]), flt, f"run {run.name}, column velocity")
        return x[:, None], xd[:, None], np.zeros((x.size, 1)), np.asarray(run["tau"], dtype=np.float64)[:, None]

    def equation_residual(self, z, zd, zdd, u):
        return jnp.stack([self.m * zd[0] + self.D * z[0] - u[0]])


class Decay2(AbstractModel):
    r"""Second-order 1-DOF model :math:`I\ddot\phi + b\dot\phi + k\phi = \tau` (states ``angle``, ``rate``).

    ``I`` and ``k`` fixed (given), ``b`` > 0 free; free ``k`` instead when the stiffness is
    unknown and the inertia trusted."""

    name: ClassVar[str] = "decay2"
    state_names: ClassVar[tuple[str, ...]] = ("angle", "rate")
    output_names: ClassVar[tuple[str, ...]] = ("angle", "rate")
    angle_outputs: ClassVar[tuple[str, ...]] = ()
    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("I", 1.0, free=False, lower=0.0, scale=1.0, unit="kg m2", description="total inertia (rigid + added)"),
        Param("b", 0.1, lower=0.0, scale=1.0, unit="kg m2/s", description="linear damping"),
        Param("k", 1.0, free=False, lower=0.0, scale=1.0, unit="N m/rad", description="restoring stiffness"),
    )
    I: jnp.ndarray = scalar(1.0)  # noqa: E741
    b: jnp.ndarray = scalar(0.1)
    k: jnp.ndarray = scalar(1.0)

    @property
    def input_names(self) -> tuple[str, ...]:
        return ("tau",)

    def vector_field(self, t, x, u):
        return jnp.stack([x[1], (u[0] - self.b * x[1] - self.k * x[0]) / self.I])

    # equation error: I·φ̈ + b·φ̇ + k·φ = τ on filtered first and second derivatives
    EQUATIONS: ClassVar[tuple[str, ...]] = ("moment",)

    def equation_data(self, run, flt):
        run.require(("angle", "tau"), f"equation error for {self.name}")
        a, ad = smooth_and_derivative(run.time, np.asarray(run["angle"]), flt, f"run {run.name}, column angle")
        add = np.gradient(ad, np.asarray(run.time))
        return a[:, None], ad[:, None], add[:, None], np.asarray(run["tau"], dtype=np.float64)[:, None]

    def equation_residual(self, z, zd, zdd, u):
        return jnp.stack([self.I * zdd[0] + self.b * zd[0] + self.k * z[0] - u[0]])

    def states_for_channels(self, channels) -> tuple[str, ...]:
        # the initial rate shapes the whole angle trace: estimate it with the angle
        return ("angle", "rate") if "angle" in channels else tuple(c for c in channels if c in self.state_names)
