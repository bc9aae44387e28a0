r"""The extended Kalman filter of the prediction-error method (:mod:`diffship.fit.prediction_error`).

One pass over one run: predict each sample from the past measured ones with one step of the fit's integrator over
the sample interval (first-order-hold inputs, as in simulation), transition Jacobians by ``jax.jacfwd``, the
Joseph-form update, heading innovations wrapped (Särkkä 2013, §5.2). Pure and forward-differentiable: the
prediction-error residuals are its normalised innovations.

References:
    S. Särkkä, *Bayesian Filtering and Smoothing*, Cambridge 2013, §5.2 (extended Kalman filter).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp
import jax.scipy.linalg as jsl
from jaxtyping import Array, Bool, Float

from ..integrators import AbstractIntegrator
from ..simulate import MAX_ABS
from .kernel import PENALTY, wrap_angle

__all__ = ["FilterPass", "ekf"]


class FilterPass(NamedTuple):
    """One extended-Kalman-filter pass over a run (per sample ``k``).

    Attributes:
        eps: normalised innovations :math:`L_k^{-1}e_k` ``(N, n_c)`` (0 on masked samples,
            ``PENALTY`` after a blow-up).
        logdet: :math:`\\log\\det S_k` ``(N,)`` (0 on masked samples).
        valid: no blow-up up to sample ``k``.
        xf, Pf: filtered state and covariance at ``k`` (``keep=True`` only, else empty).
        xp, Pp: prediction of sample ``k + 1`` from ``k`` and its covariance.
        A: the transition Jacobian from ``k`` to ``k + 1``.
    """

    eps: Float[Array, "N n_c"]
    logdet: Float[Array, " N"]
    valid: Bool[Array, " N"]
    xf: Array
    Pf: Array
    xp: Array
    Pp: Array
    A: Array


def ekf(f: Callable, h: Callable, integrator: AbstractIntegrator, angle: tuple[bool, ...],
        q_var: Float[Array, " n_x"], r_var: Float[Array, " n_c"], ts: Float[Array, " N"], us: Float[Array, "N n_u"],
        ys: Float[Array, "N n_c"], mask: Bool[Array, " N"], x0: Float[Array, " n_x"], P0: Float[Array, "n_x n_x"],
        keep: bool = False) -> FilterPass:
    """The extended Kalman filter over one run (module docstring); pure, forward-differentiable.

    ``f(t, x, u)`` is the vector field, ``h(x, u)`` the fitted channels, ``q_var`` the
    continuous process-noise intensity per state (variance per second), ``r_var`` the
    measurement variance per channel; heading innovations (``angle``) are wrapped.
    """
    ang = jnp.asarray(angle)
    n_x = x0.shape[0]
    eye = jnp.eye(n_x, dtype=x0.dtype)
    R = jnp.diag(r_var)

    def step(carry, inp):
        x, P, ok = carry
        t0, t1, u0, u1, y, m = inp
        H = jax.jacfwd(h)(x, u0)
        e = y - h(x, u0)
        e = jnp.where(ang, wrap_angle(e), e)
        S = H @ P @ H.T + R
        L = jnp.linalg.cholesky(0.5 * (S + S.T))
        eps = jsl.solve_triangular(L, e, lower=True)
        logdet = 2.0 * jnp.sum(jnp.log(jnp.diag(L)))
        K = jsl.cho_solve((L, True), H @ P).T
        IKH = eye - K @ H
        xf = jnp.where(m, x + K @ e, x)
        Pf = jnp.where(m, IKH @ P @ IKH.T + K @ R @ K.T, P)

        def F(xx):
            return integrator.interval(f, t0, t1, xx, u0, u1)

        xp = F(xf)
        A = jax.jacfwd(F)(xf)
        Pp = A @ Pf @ A.T + jnp.diag(q_var) * (t1 - t0)
        Pp = 0.5 * (Pp + Pp.T)
        ok_now = ok & jnp.all(jnp.isfinite(xp)) & jnp.all(jnp.abs(xp) < MAX_ABS) & jnp.all(jnp.isfinite(Pp))
        eps = jnp.where(ok, jnp.where(m, eps, 0.0), PENALTY)
        logdet = jnp.where(ok & m, logdet, 0.0)
        out = (eps, logdet, ok) + ((xf, Pf, xp, Pp, A) if keep else ())
        return (jnp.where(ok_now, xp, x), jnp.where(ok_now, Pp, P), ok_now), out

    dt_last = ts[-1:] - ts[-2:-1]
    t1 = jnp.concatenate([ts[1:], ts[-1:] + dt_last])
    u1 = jnp.concatenate([us[1:], us[-1:]])
    _, out = jax.lax.scan(step, (x0, P0, jnp.array(True)), (ts, t1, us, u1, ys, mask))
    empty = jnp.zeros((0,))
    return FilterPass(*out) if keep else FilterPass(out[0], out[1], out[2], empty, empty, empty, empty, empty)
