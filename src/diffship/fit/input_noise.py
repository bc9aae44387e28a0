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

The noise of each input is estimated from the data (:func:`input_noise`): white noise has
:math:`\mathrm{Var}\,\Delta^2 w = 6\sigma^2`, while a rate-limited rudder or a ramped thrust
has zero second differences except at its corners. Per channel, second differences beyond five
robust scales (1.4826·MAD) are taken for corners and dropped; the noise variance at every
sample is the mean of :math:`(\Delta^2\tilde u)^2/6` over a window of ``window`` samples around
it, so that noise proportional to the reading (a thrust gauge's 1 %) is followed in time; the
correlation between channels (jet forces computed from one measured thrust) is that of the kept
second differences. A noise-free input gives σ̂ = 0 and no correction.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float

from ..compiled import compiled
from ..integrators import RK4
from .kernel import Kernel, KernelData

__all__ = ["InputSensitivity", "input_noise", "input_noise_levels", "input_noise_meat", "measured_input_meat"]


def input_noise(us: Float[np.ndarray, "R N n_u"], mask: Bool[np.ndarray, "R N"], window: int = 51
                ) -> tuple[np.ndarray, np.ndarray]:
    """Local noise scale ``(R, N, n_u)`` of every input sample and the channels' noise correlation
    ``(n_u, n_u)`` (see the module docstring)."""
    us = np.asarray(us, dtype=np.float64)
    mask = np.asarray(mask, dtype=bool)
    R, N, n_u = us.shape
    scale = np.zeros((R, N, n_u))
    d2s = [np.diff(us[i, mask[i]], 2, axis=0) for i in range(R)]
    pooled = np.concatenate(d2s) if d2s else np.zeros((0, n_u))
    if pooled.shape[0] < 3:
        return scale, np.eye(n_u)
    centre = np.median(pooled, axis=0)
    robust = 1.4826 * np.median(np.abs(pooled - centre), axis=0)
    keep_all = []
    for i, d2 in enumerate(d2s):
        d2 = d2 - centre
        ok = np.abs(d2) <= 5 * robust
        keep_all.append(np.all(ok, axis=1))
        v = np.where(ok, d2 * d2 / 6.0, 0.0)
        c_v = np.concatenate([np.zeros((1, n_u)), np.cumsum(v, 0)])
        c_n = np.concatenate([np.zeros((1, n_u)), np.cumsum(ok, 0)])
        n = d2.shape[0]
        k = np.arange(n)
        lo, hi = np.clip(k - window // 2, 0, n), np.clip(k + window // 2 + 1, 0, n)
        var = (c_v[hi] - c_v[lo]) / np.maximum(c_n[hi] - c_n[lo], 1)
        var = np.concatenate([var[:1], var, var[-1:]])  # the two end samples take their neighbours'
        idx = np.flatnonzero(mask[i])
        scale[i, idx] = np.sqrt(var)
    x = (pooled - centre)[np.concatenate(keep_all)]
    corr = np.eye(n_u)
    if x.shape[0] > 2:
        cov = x.T @ x
        d = np.sqrt(np.diag(cov))
        corr = np.divide(cov, np.outer(d, d), out=np.eye(n_u), where=np.outer(d, d) > 0)
    return scale, corr


def input_noise_levels(us: Float[np.ndarray, "R N n_u"], mask: Bool[np.ndarray, "R N"]) -> np.ndarray:
    """Overall noise covariance of the input channels ``(n_u, n_u)`` (RMS of the local scales)."""
    scale, corr = input_noise(us, mask)
    rms = np.sqrt(np.mean(scale[np.asarray(mask, dtype=bool)] ** 2, axis=0)) if np.any(mask) else np.zeros(corr.shape[0])
    return corr * np.outer(rms, rms)


class InputSensitivity(eqx.Module):
    """Static owner of the compiled ``A = (∂r/∂ũ)ᵀ J`` program (hashable: the cache key)."""

    kernel: Kernel = eqx.field(static=True)

    @property
    def reversible(self) -> Kernel:
        """The kernel with the scan-based RK4 (diffrax's forward-mode adjoint has no reverse mode);
        the sensitivity only scales a covariance term, so the integrator difference is immaterial."""
        return dataclasses.replace(self.kernel, integrator=RK4(getattr(self.kernel.integrator, "substeps", 1)))

    def meat(self, z: Float[Array, " n_z"], data: KernelData, J: Float[Array, "m n_z"],
             scale: Float[Array, "R N n_u"], corr: Float[Array, "n_u n_u"]) -> Float[Array, "n_z n_z"]:
        """:math:`\\Omega_u = A^\\top \\Sigma_u A` (see the module docstring)."""
        m = J.shape[0]  # data rows (prior rows, if any, follow them and do not depend on the inputs)
        _, vjp = jax.vjp(lambda us: self.reversible.residuals(z, data.replace(us=us))[:m], data.us)
        A = jax.vmap(lambda c: vjp(c)[0])(J.T)  # (n_z, R, N, n_u)
        A = jnp.where(data.mask[None, :, :, None], A * scale[None], 0.0)
        return jnp.einsum("prnu,qrnv,uv->pq", A, A, corr)


def input_noise_meat(kernel: Kernel, z, data: KernelData, J, scale: np.ndarray, corr: np.ndarray
                     ) -> tuple[np.ndarray, float]:
    """``(Ω_u, compile seconds)`` for local input noise scales ``(R, N, n_u)`` and correlation ``(n_u, n_u)``."""
    owner = InputSensitivity(kernel)
    f = lambda a: jnp.asarray(a, dtype=jnp.float64)  # noqa: E731
    args = (f(z), data, f(J), f(scale), f(corr))
    fn, c = compiled(owner, "meat", args)
    return np.asarray(fn(*args)), c


def meat_request(kernel: Kernel, data: KernelData, n_rows: int, n_z: int) -> tuple | None:
    """The compile request ``(owner, name, args, static)`` of the program
    :func:`measured_input_meat` will run for ``data`` (``n_rows`` data rows, ``n_z`` unknowns),
    or ``None`` where every input looks noise-free: lets a fit compile it beside its solve."""
    mask = np.asarray(data.mask, dtype=bool)
    scale, corr = input_noise(np.asarray(data.us), mask)
    if not np.any(np.sqrt(np.mean(scale[mask] ** 2, axis=0)) > 0):
        return None
    f = lambda a: jnp.asarray(a, dtype=jnp.float64)  # noqa: E731
    return InputSensitivity(kernel), "meat", (f(np.zeros(n_z)), data, f(np.zeros((n_rows, n_z))), f(scale), f(corr)), {}


def measured_input_meat(kernel: Kernel, z, data: KernelData, J, mask, names) -> tuple[np.ndarray | None, dict, float]:
    """``(Ω_u or None, {input: RMS σ̂}, compile seconds)`` with the noise estimated from the
    measured inputs of ``data`` (``None`` where every input looks noise-free)."""
    mask = np.asarray(mask, dtype=bool)
    scale, corr = input_noise(np.asarray(data.us), mask)
    rms = np.sqrt(np.mean(scale[mask] ** 2, axis=0))
    if not np.any(rms > 0):
        return None, {}, 0.0
    meat, c = input_noise_meat(kernel, z, data, J, scale, corr)
    return meat, {n: float(s) for n, s in zip(names, rms)}, c
