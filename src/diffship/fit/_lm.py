r"""Levenberg–Marquardt on optimistix, with the Jacobian materialised once per accepted step.

optimistix's :class:`optimistix.LevenbergMarquardt` keeps the Jacobian as a linearised function
and re-evaluates it inside every linear solve. For output-error problems (tens of thousands of
residuals, ten to thirty parameters, each residual a whole simulation) it is much cheaper to
form ``J`` once per accepted step by forward-mode (``n_params`` batched JVPs through the
simulator), keep ``JᵀJ`` and ``Jᵀr`` (``n_params²`` numbers), and solve the damped normal
equations

.. math::  (J^\top J + \lambda I)\,\delta = -J^\top r

by Cholesky for every trial step size of the classical trust-region search. The state keeps
``J`` of the last accepted point, so a caller gets the Jacobian at the solution from the solve
itself (the covariance needs it) instead of compiling a second program that forms it again. This module plugs
such a descent into optimistix's Gauss–Newton framework (composition, as optimistix's own
solvers are built), so termination, step acceptance and results are optimistix's.

Measured on the fossen3 benchmark problem: see ``benchmarks/fossen3_speed.py``.
"""

from __future__ import annotations

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import optimistix as optx
from jaxtyping import Array, Float

__all__ = ["MaterialisedLM", "result_message", "rms_norm"]


def rms_norm(x):
    """Root-mean-square norm (termination on the typical change, not the largest one)."""
    return jnp.sqrt(jnp.mean(jnp.square(x)))


class _State(eqx.Module):
    jac: Float[Array, "m n"]
    jtj: Float[Array, "n n"]
    jtr: Float[Array, " n"]
    cost: Float[Array, ""]
    prev_cost: Float[Array, ""]
    accepted: Array


class MaterialisedDampedNewton(optx.AbstractDescent):
    """Damped Gauss–Newton descent with a dense, once-per-step Jacobian (kept in the state
    only when ``keep_jacobian``: a batch of vmapped solves would otherwise carry every fit's)."""

    keep_jacobian: bool = eqx.field(static=True, default=False)

    def init(self, y, f_info_struct):
        n = y.size
        m = f_info_struct.residual.size if self.keep_jacobian else 0
        inf = jnp.array(jnp.inf, y.dtype)
        return _State(jnp.zeros((m, n), y.dtype), jnp.zeros((n, n), y.dtype), jnp.zeros((n,), y.dtype), inf, inf,
                      jnp.array(0))

    def query(self, y, f_info, state):
        n = y.size
        jac = jax.vmap(f_info.jac.mv, out_axes=1)(jnp.eye(n, dtype=y.dtype))
        r = f_info.residual
        cost = 0.5 * jnp.sum(r * r)
        kept = jac if self.keep_jacobian else state.jac
        return _State(kept, jac.T @ jac, jac.T @ r, cost, state.cost, state.accepted + 1)

    def step(self, step_size, state):
        eps = jnp.finfo(state.jtr.dtype).eps
        lam = jnp.where(step_size > eps, 1.0 / jnp.maximum(step_size, eps), 1.0 / eps)
        n = state.jtr.size
        a = state.jtj + lam * jnp.eye(n, dtype=state.jtr.dtype)
        chol = jnp.linalg.cholesky(a)
        diff = -jax.scipy.linalg.cho_solve((chol, True), state.jtr)
        ok = jnp.all(jnp.isfinite(diff))
        diff = jnp.where(ok, diff, 0.0)
        return diff, optx.RESULTS.where(ok, optx.RESULTS.successful, optx.RESULTS.singular)


class MaterialisedLM(optx.AbstractGaussNewton):
    """Levenberg–Marquardt (classical trust region + materialised damped Newton descent).

    Arguments:
        rtol, atol: optimistix's Cauchy termination tolerances on the parameters and residuals.
        ftol: also stop when an accepted step lowers the cost by less than ``ftol·cost``
            (a parameter drifting towards a bound in the log-scaled space otherwise never
            meets the parameter tolerance).
        keep_jacobian: keep the last accepted step's Jacobian in the state (``state.descent_state.jac``).
    """

    def terminate(self, fn, y, args, options, state, tags):
        ds = state.descent_state
        stalled = (ds.accepted >= 3) & ((ds.prev_cost - ds.cost) <= self.ftol * ds.cost)
        return state.terminate | stalled, state.result

    rtol: float
    atol: float
    norm: Callable = optx.max_norm
    descent: MaterialisedDampedNewton = MaterialisedDampedNewton()
    search: optx.AbstractSearch = optx.ClassicalTrustRegion()
    verbose: Callable = eqx.field(static=True, default=None)

    ftol: float = 1e-10

    def __init__(
        self,
        rtol: float = 1e-8,
        atol: float = 1e-8,
        norm: Callable = optx.max_norm,
        ftol: float = 1e-10,
        keep_jacobian: bool = False,
    ):
        self.ftol = ftol
        self.rtol = rtol
        self.atol = atol
        self.norm = norm
        self.descent = MaterialisedDampedNewton(keep_jacobian)
        self.search = optx.ClassicalTrustRegion()
        self.verbose = _quiet


def _quiet(**kwargs):
    return None


def result_message(result) -> str:
    """Readable text of an optimistix ``RESULTS`` value."""
    try:
        idx = int(result._value)
        msg = optx.RESULTS._index_to_message[idx]
    except Exception:  # pragma: no cover - defensive
        return str(result)
    return msg or "converged"
