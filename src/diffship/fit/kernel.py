r"""The output-error kernel: one residual, one Jacobian, one solver for every simulation fit.

Fitting (:mod:`diffship.fit.output_error`), the diagnosis screen and refits (:mod:`diffship.diagnose.screen`)
and the estimation of initial states for evaluation all call this module; nothing else writes an output-error residual.

**Unknowns.** One flat vector :math:`z = (z_\theta, w, d)`:

* :math:`z_\theta` — the free parameters in the scaled unconstrained space of a
  :class:`~diffship.params.ParamSpec` (:math:`\theta = \theta(z_\theta)`, fixed ones held);
* :math:`w` — ``n_extra`` coordinates that move further parameters linearly,
  :math:`\varphi = \mathrm{clip}(\varphi_0 + s_\varphi \odot S w,\ \varphi_{lo}, \varphi_{hi})`,
  with a selection matrix ``S`` given as data (so switching which effect parameters are free
  does not recompile); empty for ordinary fits;
* :math:`d` — per-run offsets of the initial values of the states ``x0_idx``, in units of
  ``x0_scale``: :math:`x_{0,i} = \hat x_{0,i} + s_x \odot d_i`.

**Residual.** For runs :math:`i`, samples :math:`k` and fitted channels :math:`c`,

.. math::
    e_{ikc} = \frac{\hat y_c(t_{ik}; \theta, \varphi, x_{0,i}) - y_{ikc}}{s_c}

from the whole-horizon simulation (:func:`diffship.simulate.simulate`, vmapped over runs),
heading errors wrapped to (−π, π], padded samples masked out and every sample after a blow-up
set to :data:`PENALTY`. Gaussian prior rows follow the data rows (:meth:`Kernel.split` separates them):
:math:`w_j(\theta_j(z) - \mu_j)` per free parameter with a prior (:mod:`diffship.fit.priors`; the
optimum is then the MAP estimate), and per estimated initial state :math:`w_k(d_k - \bar d_k)`
(:mod:`diffship.initial`).

**Solver.** The batched Levenberg–Marquardt of :mod:`diffship.fit.batched` (a single fit is a
batch of one; :meth:`Kernel.solve_many` runs many starts or resamples in one program), the
forward-mode Jacobian materialised once per accepted step, the algorithm of
:class:`~diffship.fit._lm.MaterialisedLM`. The compiled programs hold no host callback (no progress print
inside the solve): JAX does not keep programs with host callbacks in its persistent cache, and a solve
loaded from the cache saves a new process more time than per-step progress would show. Progress is
reported between passes by the caller. All compiled programs come from the one cache,
:func:`diffship.compiled.compiled`.
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Array, Bool, Float, Int

from ..compiled import compiled as _compiled
from ..compiled import compiled_many
from ..integrators import AbstractIntegrator, Diffrax
from ..models import AbstractModel
from ..params import ParamSpec
from ..progress import heartbeat, per_start
from ..simulate import Solution, simulate
from .batched import lm_advance, lm_start, solve_batch

__all__ = ["Kernel", "KernelData", "kernel_data", "PENALTY", "stalled", "wrap_angle"]

#: Normalised residual assigned to every sample after a simulation blew up (exactly: a blow-up is ``r == PENALTY``).
PENALTY = 1e3

_RESULT_TREE = jax.tree_util.tree_structure(optx.RESULTS.successful)  # to rebuild a result from its integer code

def stalled(result, steps, max_steps: int) -> bool:
    """Whether a solve that reports the step cap stopped before it (a crawl's early stop, ``stall_steps``)."""
    return (int(jax.tree_util.tree_leaves(result)[0]) == int(jax.tree_util.tree_leaves(
        optx.RESULTS.nonlinear_max_steps_reached)[0]) and int(steps) < int(max_steps))


def wrap_angle(e):
    """Angle difference wrapped to (−π, π]."""
    return jnp.arctan2(jnp.sin(e), jnp.cos(e))


class KernelData(eqx.Module):
    """Everything an output-error residual needs that is data (arrays; no recompiles).

    Attributes:
        model: the model; its parameter values are those of the fixed parameters (and the
            starting values of nothing: the free ones come from ``z``).
        ts, us, ys, mask: padded runs, shapes ``(R, N)``, ``(R, N, n_u)``, ``(R, N, n_c)``, ``(R, N)``.
        x0: initial states ``(R, n_x)`` before the offsets ``d``.
        x0_scale: scale of each estimated initial-state offset ``(n_d,)``.
        scales: per-channel normalisation ``s_c`` ``(n_c,)``.
        S, phi0, phi_scale, lo, hi: the extra coordinates (see the module docstring); shapes
            ``(n_phi, n_extra)`` and ``(n_phi,)``.
        prior_mean, prior_w: prior means and inverse standard deviations of the free
            parameters ``(n_theta,)``, or empty ``(0,)`` for a fit without priors (no prior rows).
        x0_prior_w, x0_prior_mean: inverse standard deviations and means (``x0_scale`` units, ``(R·n_d,)``,
            or empty) of the initial-state offsets: rows :math:`w_k (d_k - \bar d_k)` after the parameters'
            prior rows (:mod:`diffship.initial`; ``w_k = 0``: a state no channel measures, free).
        horizon: ``None`` (the whole padded runs), or a traced sample count: only the first
            ``horizon`` samples of every run are simulated and scored (:meth:`with_horizon`, :meth:`head`), so a
            growing-horizon warm-up and the whole runs share one compiled program.
        step_cap: ``None``, or a traced cap on :meth:`Kernel.solve`'s steps under its static
            ``max_steps``: one compiled solve serves solves of any length (``1``: the residuals and
            Jacobian at ``z0``, no step), so a caller needs no Jacobian program of its own.
        stall_gate: ``None``, or a traced factor (1, 0: off) on the solve's static ``stall_rtol`` (:meth:`with_step_cap`).
    """

    model: AbstractModel
    ts: Float[Array, "R N"]
    us: Float[Array, "R N n_u"]
    ys: Float[Array, "R N n_c"]
    mask: Bool[Array, "R N"]
    x0: Float[Array, "R n_x"]
    x0_scale: Float[Array, " n_d"]
    scales: Float[Array, " n_c"]
    S: Float[Array, "n_phi n_extra"]
    phi0: Float[Array, " n_phi"]
    phi_scale: Float[Array, " n_phi"]
    lo: Float[Array, " n_phi"]
    hi: Float[Array, " n_phi"]
    prior_mean: Float[Array, " n_prior"]
    prior_w: Float[Array, " n_prior"]
    x0_prior_w: Float[Array, " n_x0_prior"]
    x0_prior_mean: Float[Array, " n_x0_prior"]
    horizon: Int[Array, ""] | None
    step_cap: Int[Array, ""] | None
    stall_gate: Float[Array, ""] | None

    @property
    def n_prior(self) -> int:
        """Number of prior rows at the end of the residual vector (parameters' then initial states')."""
        return int(self.prior_w.shape[0]) + int(self.x0_prior_w.shape[0])

    def replace(self, **changes) -> KernelData:
        """A copy with some fields replaced."""
        return dataclasses.replace(self, **changes)

    def head(self, n: int) -> KernelData:
        """The first ``n`` samples of every run (growing-horizon warm-up): sliced, or — for data
        with a ``horizon`` — the same shapes with the later samples masked and not simulated."""
        if self.horizon is not None:
            return self.with_horizon(n)
        return self.replace(ts=self.ts[:, :n], us=self.us[:, :n], ys=self.ys[:, :n], mask=self.mask[:, :n])

    def with_horizon(self, n: int | None = None) -> KernelData:
        """These data with a traced horizon of ``n`` samples (default: every sample); samples
        after it are masked (residual rows zero) and not simulated."""
        N = int(self.ts.shape[-1])
        n = N if n is None else int(n)
        keep = jnp.arange(N) < n
        return dataclasses.replace(self, mask=self.mask & keep, horizon=jnp.asarray(n))

    def with_step_cap(self, n: int | None = None, stall: bool = True) -> KernelData:
        """These data with a traced step cap of ``n`` (default: none below the solve's static ``max_steps``) and
        stall gate (``False``: no stall rule; a finished crawl): capped, uncapped, stalling or not, one program."""
        return dataclasses.replace(self, step_cap=jnp.asarray(2 ** 30 if n is None else int(n), jnp.int32),
                                   stall_gate=jnp.asarray(float(stall)))


class Kernel(eqx.Module):
    """Static structure of an output-error problem (hashable: the compile-cache key).

    Attributes:
        spec: free/fixed split, bounds and scales of the model's first ``len(spec)``
            parameters (values irrelevant: use ``spec.structural()``).
        out_idx: index in ``model.output_names`` of each fitted channel.
        angle: whether each fitted channel is an angle (wrapped errors).
        x0_idx: states whose initial values are estimated per run.
        extra_idx: indices in ``model.param_names`` of the parameters ``φ`` moved by ``w``.
        n_extra: length of ``w``.
        integrator: how the simulation advances between samples.
    """

    spec: ParamSpec = eqx.field(static=True)
    out_idx: tuple[int, ...] = eqx.field(static=True)
    angle: tuple[bool, ...] = eqx.field(static=True)
    x0_idx: tuple[int, ...] = eqx.field(static=True, default=())
    extra_idx: tuple[int, ...] = eqx.field(static=True, default=())
    n_extra: int = eqx.field(static=True, default=0)
    integrator: AbstractIntegrator = eqx.field(static=True, default=Diffrax())

    @property
    def n_theta(self) -> int:
        return len(self.spec.free_names)

    # -- the map z -> model, initial states ------------------------------------------------
    def model_at(self, z: Float[Array, " n_z"], data: KernelData) -> AbstractModel:
        theta = data.model.theta()
        n = self.n_theta
        if n:
            theta = self.spec.full_values(z[:n], theta[: len(self.spec.params)])
            theta = jnp.concatenate([theta, data.model.theta()[len(self.spec.params):]])
        if self.n_extra:
            phi = jnp.clip(data.phi0 + data.phi_scale * (data.S @ z[n:n + self.n_extra]), data.lo, data.hi)
            theta = theta.at[jnp.asarray(self.extra_idx)].set(phi)
        return data.model.with_params(theta)

    def initial_states(self, z: Float[Array, " n_z"], data: KernelData) -> Float[Array, "R n_x"]:
        if not self.x0_idx:
            return data.x0
        k = self.n_theta + self.n_extra
        d = z[k:].reshape(data.x0.shape[0], len(self.x0_idx))
        return data.x0.at[:, jnp.asarray(self.x0_idx)].add(d * data.x0_scale)

    # -- simulation and residuals -----------------------------------------------------------
    def simulate(self, z: Float[Array, " n_z"], data: KernelData) -> Solution:
        """Every run simulated at ``z`` (a batched :class:`~diffship.simulate.Solution`)."""
        model = self.model_at(z, data)
        x0 = self.initial_states(z, data)
        return jax.vmap(lambda t, u, x: simulate(model, t, u, x, self.integrator, horizon=data.horizon))(
            data.ts, data.us, x0)

    def residuals(self, z: Float[Array, " n_z"], data: KernelData) -> Float[Array, " m"]:
        """Normalised output errors, flattened in (run, sample, channel) order."""
        return self.with_prior_rows(self.output_errors(self.simulate(z, data), data), z, data)

    def output_errors(self, sol: Solution, data: KernelData) -> Float[Array, " m_data"]:
        """The data rows of :meth:`residuals` from a batched simulation (flattened)."""
        return self._errors(sol.ys, sol.valid, data.ys, data.mask, data.scales).reshape(-1)

    def _errors(self, ys_sim, valid, ys, mask, scales):
        """Normalised output errors of simulated outputs ``ys_sim`` (any leading shape), padded
        samples zero, samples after a blow-up :data:`PENALTY`."""
        err = ys_sim[..., jnp.asarray(self.out_idx)] - ys
        err = jnp.where(jnp.asarray(self.angle), wrap_angle(err), err)
        good = (valid & mask)[..., None]
        bad = ((~valid) & mask)[..., None]
        return jnp.where(good, err / scales, 0.0) + jnp.where(bad, PENALTY, 0.0)

    def with_prior_rows(self, e: Float[Array, " m_data"], z: Float[Array, " n_z"],
                        data: KernelData) -> Float[Array, " m"]:
        """``e`` followed by the prior rows (none when ``data.n_prior == 0``)."""
        if not data.n_prior:
            return e
        rows = [e]  # then the parameters' prior rows, then the initial states' (mean 0 where none is given)
        if data.prior_w.shape[0]:
            rows.append(data.prior_w * (self.spec.from_z(z[: self.n_theta]) - data.prior_mean))
        if data.x0_prior_w.shape[0]:
            d = z[self.n_theta + self.n_extra:]
            rows.append(data.x0_prior_w * ((d - data.x0_prior_mean) if data.x0_prior_mean.shape[0] else d))
        return jnp.concatenate(rows)

    @staticmethod
    def split(r, data: KernelData):
        """``(data rows, prior rows)`` of a residual vector (NumPy or JAX)."""
        n = r.shape[0] - data.n_prior
        return r[:n], r[n:]

    def jacobian(self, z: Float[Array, " n_z"], data: KernelData) -> Float[Array, "m n_z"]:
        """Forward-mode Jacobian of :meth:`residuals` (:meth:`blocked_jacobian` where it applies)."""
        return self.residuals_and_jacobian(z, data)[1]

    def residuals_and_jacobian(self, z: Float[Array, " n_z"], data: KernelData) -> tuple[Array, Array]:
        """``(r, J)`` from one program (the Jacobian's JVP primal is ``r``): a solver needing both at
        every trial point (the held-out start rule, :mod:`diffship.diagnose.start`) compiles one."""
        jac = self.own_jacobian() or jax.jacfwd(lambda x, d: (self.residuals(x, d),) * 2, has_aux=True)
        return jac(z, data)[::-1]

    def n_rows(self, data: KernelData) -> int | None:
        """Length of :meth:`residuals` without tracing it (``None``: a subclass's own residuals)."""
        return int(np.prod(data.ys.shape)) + data.n_prior if type(self).residuals is Kernel.residuals else None

    def own_jacobian(self) -> Callable | None:
        """``(z, data) -> (J, r)`` the LM and :meth:`jacobian` use: :meth:`blocked_jacobian` for
        this kernel's residuals; ``None`` (forward mode over every unknown) for a subclass with
        residuals of its own, unless it gives its own (multiple shooting's per-segment blocks)."""
        return self.blocked_jacobian if type(self).residuals is Kernel.residuals else None

    def blocked_jacobian(self, z: Float[Array, " n_z"], data: KernelData
                               ) -> tuple[Float[Array, "m n_z"], Float[Array, " m"]]:
        r"""``(J, r)``: the forward-mode Jacobian of :meth:`residuals` and the residuals.

        The rows of run :math:`i` depend on the shared unknowns :math:`(z_\theta, w)` (``k`` of
        them) and on that run's own initial-state offsets :math:`d_i` (``n_d``) only, so

        .. math::
            J = \begin{pmatrix} J^{(1)}_{c} & J^{(1)}_{d} & & \\ \vdots & & \ddots & \\
                J^{(R)}_{c} & & & J^{(R)}_{d} \end{pmatrix}

        and each run is differentiated along its ``k + n_d`` directions, not all ``k + R·n_d``
        (the zero blocks are never computed): the same columns as ``jax.jacfwd`` of
        :meth:`residuals`, with ``R·n_d`` fewer tangents per run. (A 3-run fossen3 fit: 16
        instead of 28 directions.) Prior rows, when there are any, are differentiated apart.
        """
        R, nd, k = data.x0.shape[0], len(self.x0_idx), self.n_theta + self.n_extra
        if not nd or R < 2 or z.shape[0] != k + R * nd:
            r, J = jax.vmap(lambda t: jax.jvp(lambda x: self.residuals(x, data), (z,), (t,)),
                            out_axes=(None, 1))(jnp.eye(z.shape[0], dtype=z.dtype))
            return J, r
        pad = jnp.zeros((R * nd,), z.dtype)  # model_at reads the first k unknowns only
        idx = jnp.asarray(self.x0_idx)

        def run_errors(v, t, u, y, mask, x0):
            model = self.model_at(jnp.concatenate([v[:k], pad]), data)
            sol = simulate(model, t, u, x0.at[idx].add(v[k:] * data.x0_scale), self.integrator, horizon=data.horizon)
            return self._errors(sol.ys, sol.valid, y, mask, data.scales).reshape(-1)

        def one(t, u, y, mask, x0, d):
            v = jnp.concatenate([z[:k], d])
            return jax.vmap(lambda tan: jax.jvp(lambda w: run_errors(w, t, u, y, mask, x0), (v,), (tan,)),
                            out_axes=(None, 1))(jnp.eye(k + nd, dtype=z.dtype))
        e, Jr = jax.vmap(one)(data.ts, data.us, data.ys, data.mask, data.x0, z[k:].reshape(R, nd))
        m = e.shape[1]
        Jd = jnp.einsum("rmj,rq->rmqj", Jr[..., k:], jnp.eye(R, dtype=z.dtype)).reshape(R * m, R * nd)
        J = jnp.concatenate([Jr[..., :k].reshape(R * m, k), Jd], axis=1)
        r = e.reshape(-1)
        if data.n_prior:
            rp, Jp = jax.vmap(lambda t: jax.jvp(lambda x: self.with_prior_rows(r[:0], x, data), (z,), (t,)),
                              out_axes=(None, 1))(jnp.eye(z.shape[0], dtype=z.dtype))
            r, J = jnp.concatenate([r, rp]), jnp.concatenate([J, Jp], axis=0)
        return J, r

    def _lm_static(self, *, max_steps: int, rtol: float, atol: float, ftol: float = 1e-9, jacobian: bool = False,
                   gntol: float = 0.05, variance: float | None = None, gn_params: int | None = -1,
                   stall_steps: int = 0, stall_rtol: float = 0.0, stop_above=()) -> dict:
        """The batched LM's static options from :meth:`solve`'s keywords (``stop_above``: only where given)."""
        k = self.n_theta + self.n_extra if gn_params == -1 else gn_params
        return dict(max_steps=int(max_steps), rtol=float(rtol), atol=float(atol), ftol=float(ftol), gn_params=k,
                    keep_jacobian=bool(jacobian), gntol=float(gntol), variance=None if variance is None else float(variance),
                    stall_steps=int(stall_steps), stall_rtol=float(stall_rtol),
                    bounded=tuple(int(p.kind) for p in self.spec.params if p.free),
                    **({"stop_above": tuple((int(i), float(v)) for i, v in stop_above)} if stop_above else {}))

    def solve(self, z0: Float[Array, " n_z"], data: KernelData, *, max_steps: int, rtol: float, atol: float,
              ftol: float = 1e-9, jacobian: bool = False, gntol: float = 0.05, variance: float | None = None,
              gn_params: int | None = -1, stall_steps: int = 0, stall_rtol: float = 0.0):
        """Levenberg–Marquardt from ``z0``: ``(z, result, steps, residuals)``, and with
        ``jacobian=True`` also the Jacobian :meth:`jacobian` at ``z`` (the one the last accepted
        step formed: no second forward-mode pass, no second compiled program). A small step or a
        stalled cost stops it only when the Gauss–Newton step is shorter than ``gntol`` standard
        errors (residual variance ``variance``, estimated when ``None``; :mod:`diffship.fit._lm`), judged
        on the first ``gn_params`` unknowns (default ``-1``: the parameters ``(z_θ, w)``, not the
        nuisance unknowns after them; ``None``: all). With ``stall_steps`` > 0 a crawl stops early: a cost falling
        by less than ``stall_rtol``·cost over ``stall_steps`` steps ends the solve with the status
        ``nonlinear_max_steps_reached`` before ``max_steps`` (:mod:`diffship.fit.batched`, item 6; :func:`stalled`).

        The batched LM (:mod:`diffship.fit.batched`) at ``B = 1``; a final point that still blows up has the status
        ``nonlinear_divergence``; ``data.step_cap``/``stall_gate`` set the cap and the stall rule at run time."""
        lm = self._lm_static(max_steps=max_steps, rtol=rtol, atol=atol, ftol=ftol, jacobian=jacobian, gntol=gntol,
                             variance=variance, gn_params=gn_params, stall_steps=stall_steps, stall_rtol=stall_rtol)
        z0 = jnp.asarray(z0)[None]
        st = self.batch_start(z0, data, jnp.ones(z0.shape, bool), **lm)
        cap = lm["max_steps"] if data.step_cap is None else jnp.minimum(data.step_cap, lm["max_steps"])
        gate = {} if data.stall_gate is None else {"stall_rtol": lm["stall_rtol"] * data.stall_gate}
        st = self.batch_advance(st, data, jnp.asarray(0, jnp.int32), **dict(lm, max_steps=cap, **gate))
        result = jax.tree_util.tree_unflatten(_RESULT_TREE, [st["status"][0]])
        out = (st["z"][0], result, st["steps"][0], st["r"][0])
        return (*out, st["jac"][0]) if jacobian else out

    def batch_start(self, z0s: Float[Array, "B n_z"], data: KernelData, free: Bool[Array, "B n_z"], *,
                    per_problem: bool = False, **lm) -> dict:
        """State of the batched LM (:func:`diffship.fit.batched.lm_start`) from ``B`` starts;
        ``data`` shared, or with a leading batch axis on every array when ``per_problem``."""
        return lm_start(self.residuals, z0s, data, free, data_axis=0 if per_problem else None, penalty=PENALTY,
                        jac=self.own_jacobian(), rows=self.n_rows(data) if not per_problem else None, **lm)

    def batch_advance(self, state: dict, data: KernelData, stop_below, *, per_problem: bool = False, **lm) -> dict:
        """The batched LM advanced until at most ``stop_below`` problems are unfinished
        (:func:`diffship.fit.batched.lm_advance`)."""
        return lm_advance(self.residuals, state, data, stop_below, data_axis=0 if per_problem else None,
                          jac=self.own_jacobian(), penalty=PENALTY, **lm)

    def solve_coded(self, z0: Float[Array, " n_z"], data: KernelData, **lm):
        """:meth:`solve` with the optimistix result as its integer code (plain arrays out: the
        form :mod:`diffship.compiled` can export and reload in a new process without tracing)."""
        z, result, *rest = self.solve(z0, data, **lm)
        return z, jax.tree_util.tree_leaves(result)[0], *rest

    def solve_many(self, z0s: Float[Array, "B n_z"], data: KernelData, *, workers: int | None = None,
                   method: str = "auto", free=None, per_problem: bool = False, repack: bool | None = None,
                   progress: Callable[[str], None] | None = None, label: str = "solve", **lm):
        """Levenberg–Marquardt from each of ``B`` starts (multi-start, or bootstrap resamples that
        share ``data``'s shapes): ``[(z, result, steps, residuals[, jacobian]), ...]`` in start order.

        ``free`` (``(B, n_z)`` booleans) holds masked unknowns of padded problems where they start;
        with ``per_problem`` every array of ``data`` has a leading axis ``B`` (bootstrap resamples).
        Every start runs the batched LM of :mod:`diffship.fit.batched` (same steps, same optimum);
        ``method`` chooses how the batch is laid out:

        * ``"batched"``: all starts in one compiled program (per-problem damping, acceptance and
          status; on a CPU in rounds that repack unfinished problems, ``repack``);
        * ``"threads"``: one problem per program call (the ``B = 1`` program :meth:`solve`, the one
          ``fit_output_error`` compiles), spread over ``workers`` threads (default one per core or
          ``$DIFFSHIP_THREADS``, :func:`default_threads`; XLA releases the interpreter while a program runs);
        * ``"auto"`` (default): ``"threads"`` on a CPU, ``"batched"`` on a GPU/TPU. On a CPU the
          forward-mode Jacobian, most of a step, costs the same per problem in a batch as alone
          (measured in ``benchmarks/results/timing_batched.md``), so a batch gains nothing there, and
          threads use every core without compiling further programs; on a GPU the time-step loop
          is latency-bound and a batch costs about what one problem costs.

        ``progress`` (e.g. the CLI's progress line) hears, every 10 s, that the solve is still
        running, and with ``"threads"`` of each start as it finishes (steps, cost, time per step;
        :mod:`diffship.progress`: the compiled programs are the same with and without it).
        """
        with heartbeat(progress, label):
            return self._solve_many(z0s, data, workers=workers, method=method, free=free, per_problem=per_problem,
                                    repack=repack, done=per_start(progress, label, len(z0s)), **lm)

    def _solve_many(self, z0s, data, *, workers, method, free, per_problem, repack, done, **lm):
        z0s = np.asarray(z0s, dtype=np.float64)
        if z0s.ndim != 2:
            raise ValueError(f"solve_many: starts must have shape (B, n_z), got {z0s.shape}")
        if method == "auto":
            method = "threads" if jax.default_backend() == "cpu" else "batched"
        if method not in ("batched", "threads"):
            raise ValueError(f"solve_many: method must be 'auto', 'batched' or 'threads', got {method!r}")
        free = None if free is None else np.asarray(free, bool)
        if free is not None and free.shape != z0s.shape:
            raise ValueError(f"solve_many: free mask shape {free.shape} differs from the starts' {z0s.shape}")
        if method == "threads" and free is None:
            return self._solve_threads(z0s, data, workers, per_problem, done, **lm)
        static = dict(self._lm_static(**lm), per_problem=bool(per_problem))
        if data.step_cap is not None:  # the data's step cap (a warm-up round), as :meth:`solve` honours it
            static["max_steps"] = min(static["max_steps"], int(np.min(np.asarray(data.step_cap))))
        free = np.ones(z0s.shape, bool) if free is None else free
        def start(z, d, f):
            args = (jnp.asarray(z), d, jnp.asarray(f))
            return _compiled(self, "batch_start", args, **static)[0](*args)
        def advance(st, d, stop):
            args = (st, d, jnp.asarray(stop))
            return _compiled(self, "batch_advance", args, **static)[0](*args)
        if method == "threads":  # free masks: the B = 1 batched programs (compiled first), one problem per call
            d0 = jax.tree_util.tree_map(lambda a: a[:1], data) if per_problem else data
            _compiled(self, "batch_advance", (start(z0s[:1], d0, free[:1]), d0, jnp.asarray(np.int32(0))), **static)
            def one(b):
                d, t0 = jax.tree_util.tree_map(lambda a: a[b:b + 1], data) if per_problem else data, time.perf_counter()
                st = solve_batch(start, advance, z0s[b:b + 1], d, free[b:b + 1], per_problem_data=per_problem,
                                 repack=False)
                done(b, int(st["steps"][0]), 0.5 * float(np.sum(np.square(st["r"][0]))), time.perf_counter() - t0)
                return st
            parts = _pool(one, range(z0s.shape[0]), workers)
            st = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
        else:
            st = solve_batch(start, advance, z0s, data, free, per_problem_data=per_problem, repack=repack)
        out = []
        for b in range(z0s.shape[0]):
            res = jax.tree_util.tree_unflatten(_RESULT_TREE, [jnp.asarray(st["status"][b])])
            one = (jnp.asarray(st["z"][b]), res, jnp.asarray(st["steps"][b]), jnp.asarray(st["r"][b]))
            out.append((*one, jnp.asarray(st["jac"][b])) if static["keep_jacobian"] else one)
        return out

    def _solve_threads(self, z0s, data, workers, per_problem, done, **lm):
        data = jax.tree_util.tree_map(np.asarray, data) if per_problem else data  # host slices: no per-shape program
        fn, _ = self.compiled("solve", z0s[0], jax.tree_util.tree_map(lambda a: a[0], data) if per_problem else data, **lm)

        def one(b):
            d = jax.tree_util.tree_map(lambda a: a[b], data) if per_problem else data
            t0 = time.perf_counter()
            out = jax.block_until_ready(fn(jnp.asarray(z0s[b], dtype=jnp.float64), d))
            done(b, int(out[2]), 0.5 * float(np.sum(np.square(out[3]))), time.perf_counter() - t0)
            return out
        return _pool(one, range(z0s.shape[0]), workers)

    # -- compiled entry points (NumPy in, NumPy out) ----------------------------------------
    def compiled(self, name: str, z, data: KernelData, **static):
        """``(compiled function, compile seconds)`` of one of the methods above."""
        fns, seconds = self.compiled_many([(name, z, data, static)])
        return fns[0], seconds

    def compiled_many(self, requests, extra=()):
        """Several of the methods above compiled at once (in parallel where XLA has to compile:
        :func:`diffship.compiled.compiled_many`): ``requests`` is a list of
        ``(name, z, data, static keywords)``; ``extra`` further programs of other owners, as
        ``(owner, name, args, static)``, compiled in the same batch (fetch them later with
        :func:`diffship.compiled.compiled`, at no cost). Returns ``(functions, compile seconds)``."""
        fns, seconds = compiled_many(self.requests(requests) + list(extra))
        return [_with_result(fn) if name == "solve" else fn for fn, (name, *_) in zip(fns, requests)], seconds

    def requests(self, requests) -> list:
        """``(name, z, data, static)`` as :mod:`diffship.compiled` keys them (e.g. to prefetch)."""
        return [(self, "solve_coded" if name == "solve" else name, (jnp.asarray(z, dtype=jnp.float64), data), static)
                for name, z, data, static in requests]

    def call(self, name: str, z, data: KernelData, **static):
        """Run a compiled method; returns its output (JAX arrays)."""
        fn, _ = self.compiled(name, z, data, **static)
        return fn(jnp.asarray(z, dtype=jnp.float64), data)


def default_threads() -> int:
    """Threads of :meth:`Kernel.solve_many` (``"threads"``) when not given: ``$DIFFSHIP_THREADS``, else one
    per core. A process that shares the cores with others of its kind (a fleet worker,
    :mod:`diffship.fleet`) sets it to its share, so that the processes do not oversubscribe the cores;
    the answers do not depend on it (every start is its own program call)."""
    if env := os.environ.get("DIFFSHIP_THREADS", "").strip():
        if not env.isdigit() or int(env) < 1:
            raise ValueError(f"DIFFSHIP_THREADS must be a positive integer, got {env!r}")
        return int(env)
    return os.cpu_count() or 1


def _pool(fn, items, workers):
    """``[fn(i) for i in items]`` in ``workers`` threads (default :func:`default_threads`), in order."""
    items = list(items)
    workers = min(len(items), workers or default_threads())
    if workers <= 1:
        return [fn(i) for i in items]
    with ThreadPoolExecutor(workers) as pool:
        return list(pool.map(fn, items))


def _with_result(fn):
    """The compiled :meth:`Kernel.solve_coded` returning an optimistix result again."""
    def solve(z0, d):
        z, code, *rest = fn(z0, d)
        return z, jax.tree_util.tree_unflatten(_RESULT_TREE, [code]), *rest
    return solve


def kernel_data(model: AbstractModel, ts, us, ys, mask, x0, scales, *, x0_scale=None, S=None, phi0=None, phi_scale=None,
                lo=None, hi=None, prior_mean=None, prior_w=None, x0_prior_w=None, x0_prior_mean=None) -> KernelData:
    """Build :class:`KernelData` from NumPy arrays (empty extra coordinates and no priors by
    default; priors with all weights zero are dropped, so they cost nothing)."""
    if prior_w is not None and not np.any(np.asarray(prior_w)):
        prior_mean = prior_w = None
    f = lambda a: jnp.asarray(np.zeros((0,)) if a is None else a, dtype=jnp.float64)  # noqa: E731
    return KernelData(
        model=model, ts=f(ts), us=f(us), ys=f(ys), mask=jnp.asarray(mask, dtype=bool), x0=f(x0), x0_scale=f(x0_scale),
        scales=f(scales), S=f(np.zeros((0, 0)) if S is None else S), phi0=f(phi0), phi_scale=f(phi_scale), lo=f(lo),
        hi=f(hi), prior_mean=f(prior_mean), prior_w=f(prior_w), x0_prior_w=f(x0_prior_w), x0_prior_mean=f(x0_prior_mean),
        horizon=None, step_cap=None, stall_gate=None)
