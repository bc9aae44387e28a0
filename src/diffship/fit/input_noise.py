r"""Measured inputs: their noise level and what it does to an output-error estimate.

An output-error fit simulates with the *measured* inputs :math:`\tilde u = u + w`. Input
noise :math:`w` (rudder-angle sensor, thrust gauge) passes through the model's dynamics into
the residuals as a low-frequency, coloured component that lies largely in the span of the
Jacobian: the fit absorbs part of it, so no estimate built from the fitted residuals alone
(white or HAC) sees it, yet it moves the parameters. Treated as errors in variables, to
first order

.. math::
    \hat z - z \approx -H^{-1} J^\top (e + G w),\qquad G = \partial r/\partial \tilde u,

so white input noise with covariance :math:`\Sigma_u` between the input channels adds

.. math::
    \Omega_u = A^\top \Sigma_u A,\qquad A = G^\top J

to the middle of the sandwich :math:`H^{-1}\Omega H^{-1}` (:mod:`diffship.fit.covariance`).
``A`` costs one reverse-mode pass through the batched simulation per unknown (``jax.vmap`` of a
VJP with the Jacobian's columns as cotangents), compiled once per problem structure.

The noise level of each input is estimated from the data (:func:`input_noise_levels`): the
median absolute second difference of the measured signal over all runs,
:math:`\hat\sigma = 1.4826\,\mathrm{MAD}(\Delta^2 \tilde u)/\sqrt 6` (white noise has
:math:`\mathrm{Var}\,\Delta^2 w = 6\sigma^2`; a rate-limited rudder or a ramped thrust has zero
second differences except at its corners, which the median ignores). A noise-free input gives
σ̂ ≈ 0 and no correction.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float

from ..compiled import compiled
from ..integrators import RK4
from .kernel import Kernel, KernelData

__all__ = ["input_noise_levels", "InputSensitivity", "input_noise_meat", "measured_input_meat"]


def input_noise_levels(us: Float[np.ndarray, "R N n_u"], mask: Bool[np.ndarray, "R N"]) -> np.ndarray:
    """Robust white-noise covariance of the measured input channels ``(n_u, n_u)``.

    Scales per channel from the MAD of the second differences; correlations between channels
    (e.g. jet forces computed from one measured thrust) from the sample covariance of the
    second differences at the samples where no channel is an outlier (5 robust scales)."""
    us = np.asarray(us, dtype=np.float64)
    mask = np.asarray(mask, dtype=bool)
    d2 = np.concatenate([np.diff(us[i, mask[i]], 2, axis=0) for i in range(us.shape[0])])
    n_u = us.shape[-1]
    if d2.shape[0] < 3:
        return np.zeros((n_u, n_u))
    d2 = d2 - np.median(d2, axis=0)
    scale = 1.4826 * np.median(np.abs(d2), axis=0)
    inlier = np.all(np.abs(d2) <= 5 * np.where(scale > 0, scale, np.inf), axis=1)
    cov = np.zeros((n_u, n_u))
    if np.sum(inlier) > 2:
        x = d2[inlier]
        cov = (x.T @ x) / x.shape[0] / 6.0
    # the diagonal from the robust scales (the inlier cut trims the tails)
    sd = scale / np.sqrt(6.0)
    corr = np.divide(cov, np.sqrt(np.outer(np.diag(cov), np.diag(cov))), out=np.zeros_like(cov),
                     where=np.outer(np.diag(cov), np.diag(cov)) > 0)
    return corr * np.outer(sd, sd) + np.diag(np.where(np.diag(corr) == 0, sd**2, 0.0))


class InputSensitivity(eqx.Module):
    """Static owner of the compiled ``A = (∂r/∂ũ)ᵀ J`` program (hashable: the cache key)."""

    kernel: Kernel = eqx.field(static=True)

    @property
    def reversible(self) -> Kernel:
        """The kernel with the scan-based RK4 (diffrax's forward-mode adjoint has no reverse mode);
        the sensitivity only scales a covariance term, so the integrator difference is immaterial."""
        k = self.kernel
        return Kernel(spec=k.spec, out_idx=k.out_idx, angle=k.angle, x0_idx=k.x0_idx, extra_idx=k.extra_idx,
                      n_extra=k.n_extra, integrator=RK4(getattr(k.integrator, "substeps", 1)))

    def meat(self, z: Float[Array, " n_z"], data: KernelData, J: Float[Array, "m n_z"],
             sigma2: Float[Array, "n_u n_u"]) -> Float[Array, "n_z n_z"]:
        """:math:`\\Omega_u = A^\\top \\Sigma_u A` (see the module docstring)."""
        _, vjp = jax.vjp(lambda us: self.reversible.residuals(z, data.replace(us=us)), data.us)
        A = jax.vmap(lambda c: vjp(c)[0])(J.T)  # (n_z, R, N, n_u)
        A = jnp.where(data.mask[None, :, :, None], A, 0.0)
        return jnp.einsum("prnu,qrnv,uv->pq", A, A, sigma2)


def input_noise_meat(kernel: Kernel, z, data: KernelData, J, sigma: np.ndarray) -> tuple[np.ndarray, float]:
    """``(Ω_u, compile seconds)`` for the input noise covariance ``sigma`` ``(n_u, n_u)``."""
    owner = InputSensitivity(kernel)
    args = (jnp.asarray(z, dtype=jnp.float64), data, jnp.asarray(J, dtype=jnp.float64),
            jnp.asarray(sigma, dtype=jnp.float64))
    fn, c = compiled(owner, "meat", args)
    return np.asarray(fn(*args)), c


def measured_input_meat(kernel: Kernel, z, data: KernelData, J, mask, names) -> tuple[np.ndarray | None, dict, float]:
    """``(Ω_u or None, {input: σ̂}, compile seconds)`` with the noise levels estimated from the
    measured inputs of ``data`` (``None`` where every input looks noise-free)."""
    cov = input_noise_levels(np.asarray(data.us), mask)
    if not np.any(np.diag(cov) > 0):
        return None, {}, 0.0
    meat, c = input_noise_meat(kernel, z, data, J, cov)
    return meat, {n: float(np.sqrt(s)) for n, s in zip(names, np.diag(cov))}, c
