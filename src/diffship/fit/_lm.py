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
solvers are built), so step acceptance and results are optimistix's.

**Termination.** optimistix's Cauchy test (a small accepted step and a small change of the
residuals) and a stalled cost (an accepted step lowering it by less than ``ftol·cost``) both fire
when the trust region has just shrunk, however far the optimum still is: measured on the MMG
KVLCC2 zigzags, fits stopped "converged" 1.3 standard errors from the optimum. Either counts as
convergence here only if the undamped Gauss–Newton step from the current point,

.. math::  \delta_{GN} = -(J^\top J)^{+} J^\top r,\qquad
           \frac{\lVert J\delta_{GN}\rVert^2}{\hat\sigma^2}
           = \frac{r^\top J (J^\top J)^{+} J^\top r}{\hat\sigma^2} < \text{gntol}^2,

is short in standard-error units (the left side is the squared Mahalanobis length of
:math:`\delta_{GN}` under the Gauss–Newton covariance :math:`\hat\sigma^2 (J^\top J)^{-1}`),
with :math:`\hat\sigma^2 = 2\,\text{cost}/(m - n)` (``m`` the nonzero residual rows: padded
samples are exact zeros) or a given ``variance`` — or if it is negligible in the parameters
themselves (every :math:`|\delta_{GN,i}| < \text{atol} + \text{rtol}\,|z_i|`: noise-free data,
where :math:`\hat\sigma^2` is round-off). Otherwise LM goes on, up to ``max_steps``. Both use
the ``JᵀJ`` and ``Jᵀr`` the state already holds (one ``n × n`` eigendecomposition per step;
directions with eigenvalues below ``n·eps·max`` — unidentifiable — are left out).

With ``gn_params = k`` only the first ``k`` unknowns (the model parameters, ahead of nuisance
unknowns: initial states, segment states, noise levels) are judged, by the marginal length
:math:`\delta_{GN,\theta}^\top [(J^\top J)^{+}]_{\theta\theta}^{+}\,\delta_{GN,\theta} / \hat\sigma^2`
(never longer than the joint one). A nuisance unknown converging slowly towards a flat optimum
(a process-noise level of calm water, on its floor) then does not hold up a fit whose
parameters no longer move by a standard error.

Measured on the fossen3 benchmark problem: see ``benchmarks/fossen3_speed.py``.
"""

from __future__ import annotations

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import optimistix as optx
from jaxtyping import Array, Float

__all__ = ["MaterialisedLM", "gauss_newton_step", "result_message", "rms_norm"]


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
    rows: Array  # nonzero residual rows (the data count; padded and masked rows are exact zeros)


class MaterialisedDampedNewton(optx.AbstractDescent):
    """Damped Gauss–Newton descent with a dense, once-per-step Jacobian (kept in the state
    only when ``keep_jacobian``: a batch of vmapped solves would otherwise carry every fit's)."""

    keep_jacobian: bool = eqx.field(static=True, default=False)

    def init(self, y, f_info_struct):
        n = y.size
        m = f_info_struct.residual.size if self.keep_jacobian else 0
        inf = jnp.array(jnp.inf, y.dtype)
        return _State(jnp.zeros((m, n), y.dtype), jnp.zeros((n, n), y.dtype), jnp.zeros((n,), y.dtype), inf, inf,
                      jnp.array(0), jnp.array(0))

    def query(self, y, f_info, state):
        n = y.size
        jac = jax.vmap(f_info.jac.mv, out_axes=1)(jnp.eye(n, dtype=y.dtype))
        r = f_info.residual
        cost = 0.5 * jnp.sum(r * r)
        kept = jac if self.keep_jacobian else state.jac
        return _State(kept, jac.T @ jac, jac.T @ r, cost, state.cost, state.accepted + 1, jnp.sum(r != 0))

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


def gauss_newton_step(jtj: Float[Array, "n n"], jtr: Float[Array, " n"],
                      k: int | None = None) -> tuple[Float[Array, " n"], Float[Array, ""]]:
    r"""``(δ_GN, ‖J δ_GN‖²)``: the undamped Gauss–Newton step :math:`-(J^\top J)^{+} J^\top r` and
    the squared length of its predicted residual change, :math:`r^\top J (J^\top J)^{+} J^\top r`
    (pseudo-inverse: eigenvalues below ``n·eps·max`` are left out). With ``k``, the second is the
    marginal length of the first ``k`` components instead,
    :math:`\delta_{1:k}^\top [(J^\top J)^{+}]_{1:k,1:k}^{+}\,\delta_{1:k}`."""
    w, V = jnp.linalg.eigh(jtj)
    n = jtr.size
    keep = w > n * jnp.finfo(jtr.dtype).eps * jnp.max(jnp.abs(w))
    q = V.T @ jtr
    inv = jnp.where(keep, 1.0 / jnp.where(keep, w, 1.0), 0.0)
    dz = -(V @ (inv * q))
    if k is None or k >= n:
        return dz, jnp.sum(inv * q * q)
    cov = (V[:k] * inv) @ V[:k].T
    d = dz[:k]
    return dz, d @ jnp.linalg.pinv(cov, hermitian=True) @ d


class MaterialisedLM(optx.AbstractGaussNewton):
    """Levenberg–Marquardt (classical trust region + materialised damped Newton descent).

    Arguments:
        rtol, atol: optimistix's Cauchy termination tolerances on the parameters and residuals.
        ftol: also stop when an accepted step lowers the cost by less than ``ftol·cost``
            (a parameter drifting towards a bound in the log-scaled space otherwise never
            meets the parameter tolerance).
        gntol: either stop counts only when the Gauss–Newton step from the current point is
            shorter than ``gntol`` standard errors (module docstring); ``inf`` turns the check off.
        variance: residual variance σ² of that check; ``None`` estimates it as ``2·cost/(m − n)``.
        gn_params: judge only the first ``gn_params`` unknowns (marginally); ``None``: all.
        keep_jacobian: keep the last accepted step's Jacobian in the state (``state.descent_state.jac``).
    """

    def terminate(self, fn, y, args, options, state, tags):
        ds = state.descent_state
        stalled = (ds.accepted >= 3) & ((ds.prev_cost - ds.cost) <= self.ftol * ds.cost)
        small = state.terminate | stalled
        if self.gntol == float("inf"):
            # the plain tests, or an undamped Gauss–Newton step negligible in y: a stationary point.
            # On a linear problem (equation error's inverse dynamics) the optimum is reached in one
            # step; the trust region's acceptance there compares round-off with round-off, and
            # whether three steps are accepted (the stalled test) is then a matter of luck
            return small | self._gn_step_tiny(y, ds), state.result
        return small & self.gauss_newton_short(y, ds), state.result

    def _gn_step_tiny(self, y, ds: _State) -> Array:
        """Whether the Gauss–Newton step at ``y`` is negligible in ``y`` (``atol + rtol·|y|``), once a step
        has been accepted (before that the state holds no Jacobian)."""
        dz, _ = gauss_newton_step(ds.jtj, ds.jtr, self.gn_params)
        k = y.size if self.gn_params is None else min(self.gn_params, y.size)
        return (ds.accepted >= 1) & jnp.all(jnp.abs(dz[:k]) < self.atol + self.rtol * jnp.abs(y[:k]))

    def gauss_newton_short(self, y, ds: _State) -> Array:
        """Whether the Gauss–Newton step at ``y`` is short in standard errors or negligible in ``y``."""
        dz, chi2 = gauss_newton_step(ds.jtj, ds.jtr, self.gn_params)
        n = y.size
        s2 = (2.0 * ds.cost / jnp.maximum(ds.rows - n, 1)) if self.variance is None else self.variance
        short = chi2 < self.gntol ** 2 * s2
        k = n if self.gn_params is None else min(self.gn_params, n)
        tiny = jnp.all(jnp.abs(dz[:k]) < self.atol + self.rtol * jnp.abs(y[:k]))
        return short | tiny

    rtol: float
    atol: float
    norm: Callable = optx.max_norm
    descent: MaterialisedDampedNewton = MaterialisedDampedNewton()
    search: optx.AbstractSearch = optx.ClassicalTrustRegion()
    verbose: Callable = eqx.field(static=True, default=None)

    ftol: float = 1e-10
    gntol: float = 0.05
    variance: float | None = None
    gn_params: int | None = eqx.field(static=True, default=None)

    def __init__(
        self,
        rtol: float = 1e-8,
        atol: float = 1e-8,
        norm: Callable = optx.max_norm,
        ftol: float = 1e-10,
        keep_jacobian: bool = False,
        gntol: float = 0.05,
        variance: float | None = None,
        gn_params: int | None = None,
    ):
        self.ftol = ftol
        self.gntol = float(gntol)
        self.variance = variance
        self.gn_params = gn_params
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
