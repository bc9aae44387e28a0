r"""Sensor effects: a heading-sensor bias.

The compass reads :math:`\psi + b_\psi`; the model's heading state is the measured one, so the
bias shows only in the positions, which follow the true heading :math:`\psi_t = \psi - b_\psi`
(applied in :meth:`~.augmented.Augmented.vector_field`).
"""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp
import numpy as np

from ._base import Effect, param

__all__ = ["HeadingBias"]


class HeadingBias(Effect):
    r"""Heading sensor bias: the compass reads :math:`\psi + b_\psi` (null: no bias)."""

    name: ClassVar[str] = "heading_bias"
    family: ClassVar[str] = "sensor"
    hook: ClassVar[str] = "kinematics"
    PROBE: ClassVar[dict[str, float]] = {"b_psi": 0.02}
    MIN_RELEVANT: ClassVar[dict[str, float]] = {"b_psi": 0.2 * np.pi / 180}
    signature: ClassVar[str] = "position drift perpendicular to the course, rotating with the ship"
    confusable_with: ClassVar[tuple[str, ...]] = ("current",)
    separating: ClassVar[str] = "a turning circle of 360° or more with GNSS positions"
    b_psi: jnp.ndarray = param(0.0, scale=0.02, unit="rad", description="heading sensor bias")
