r"""Batched Levenberg–Marquardt: ``B`` independent least-squares problems of one shape, one program.

Every output-error fit in diffship is a batch: a single fit is ``B = 1``; multi-start, bootstrap
resamples, candidate structures with padded parameter vectors and fleets of vessels are ``B > 1``.
Problem ``b`` minimises :math:`\tfrac12\lVert r(z_b; D_b)\rVert^2` over its own unknowns
:math:`z_b` (data :math:`D_b` shared by all problems or given per problem), with its own damping,
acceptance, convergence test and status. The algorithm per problem is the one of
:class:`diffship.fit._lm.MaterialisedLM` (optimistix's Gauss–Newton framework with the classical
trust region and a materialised forward-mode Jacobian), re-written on arrays with a leading batch
axis so that a batch advances in lockstep *without* evaluating both branches of a step:

1. trial point :math:`z^{+}_b = z_b + \delta_b`, :math:`(J_b^\top J_b + \lambda_b I)\,\delta_b = -J_b^\top r_b`
   (batched Cholesky; :math:`\lambda_b = 1/\Delta_b`, :math:`\Delta_b` the trust-region step size);
2. **one** residual evaluation for the whole batch at the trial points;
3. classical trust-region acceptance per problem: with the predicted reduction
   :math:`p_b = \delta_b^\top J_b^\top r_b + \tfrac12\delta_b^\top J_b^\top J_b\delta_b < 0`
   and the actual one :math:`a_b = c(z^{+}_b) - c(z_b)`, accept when :math:`a_b \le 0.01\,p_b`,
   grow :math:`\Delta_b` by 3.5 when :math:`a_b < 0.99\,p_b`, shrink it by 0.25 when rejected
   (Gould et al., "Sensitivity of trust-region algorithms to their parameters", 2005; optimistix's
   defaults);
4. the Jacobian by forward mode (``n`` batched JVPs through the simulator) **only when some problem
   accepted**: a ``lax.cond`` on the scalar "any accepted" is a real branch in XLA (a cond on a
   batched predicate would be a select that runs both sides);
5. per-problem termination, :class:`~diffship.fit._lm.MaterialisedLM`'s: optimistix's
   Cauchy test (small step and small residual change) or a stalled cost, each counting only when the
   Gauss–Newton step is shorter than ``gntol`` standard errors (or negligible in ``z``). With ``bounded``
   (the kinds of the parameters' bounds) and a finite ``gntol``, also a **bound-constrained** stop: a
   parameter within ``gntol`` standard errors of its bound whose Gauss–Newton step points further towards
   it is held (:func:`_pinned`), and after three accepted steps the problem has converged when the
   Gauss–Newton step of the others is short. Its optimum lies on the bound, at infinity in ``z``, where
   the Gauss–Newton step in ``z`` keeps its length however close the value comes: without this,
   Levenberg–Marquardt crawls towards it until the stalled-cost test fires (measured on the estimator
   battery's output-error fit with T2 bounded below its truth: 74 steps, now 32, the same optimum);
6. optionally (``stall_steps`` > 0) an **early stop of a crawl**: when the cost of a problem
   falls by less than ``stall_rtol``·cost over ``stall_steps`` consecutive steps,
   :math:`c_{k-W} - c_k \le \rho\,c_k`, tested at the end of each window of W steps
   (k = W, 2W, …; a test of every step's trailing window stopped the refits of the USV
   current case 2–8 steps earlier and saved 3 % of its CPU, but changed borderline diagnoses of
   the independent grid: an extra effect after a current, a decided tie left open), it stops
   with the status ``max_steps`` (not converged) before its step cap — a mis-specified model crawls along a curved valley
   for hundreds of steps whose sum moves its cost by a fraction of a percent, while its
   Gauss–Newton step stays long. It fires only while the Gauss–Newton model still promises
   more than that, :math:`\tfrac12 r^\top J (J^\top J)^{+} J^\top r > \rho\,c_k` (the last
   steps of a convergence, where the promise is small too, go on to the ordinary tests). A
   caller tells such a stop from the step cap by its step count;
7. optionally (``stop_above``, pairs ``(i, v)``) an **end at a bound**: a problem stops, not converged, once
   its unknown ``z_i`` reaches ``v``. For an unknown clipped at ``v`` inside the residuals (a disturbance's
   damping, :data:`diffship.fit.disturbance.CLIP`) that point is absorbing: beyond the clip its Jacobian
   column is zero, so no later step moves it back (the caller decides what such an end means).

Finished problems (converged, failed, out of steps) are frozen by masks: their trial point is
their current point and nothing of theirs changes. On a CPU a frozen problem still costs its share
of each batched simulation, so the host driver (:func:`solve_batch`) runs the program in *rounds*:
it returns when the number of unfinished problems falls to a quarter of the batch, and the host drops
the finished ones and repacks the rest into the next power-of-two bucket (a few compiled sizes, reused).
On a GPU a batch costs about what one problem costs (the time-step loop is latency-bound), so the
whole batch runs to the end in one call. The choice is :func:`repack_default` (by backend).

**Padded parameters.** An optional boolean ``free`` mask ``(B, n)`` holds the masked coordinates
of a problem where they are (their rows and columns of :math:`J^\top J` are replaced by the
identity and their gradient by zero, so :math:`\delta` is exactly zero there) — candidate
structures of different sizes in one batch.

**Status** per problem, as optimistix ``RESULTS`` integer codes: ``successful`` (converged),
``nonlinear_max_steps_reached``, ``singular`` (a non-finite damped step) and
``nonlinear_divergence`` (the start's cost is not finite, or the final residuals still carry the
blow-up penalty of a simulation that diverged, when ``penalty`` is given).
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Array, Bool, Float

from ._lm import gauss_newton_step

__all__ = ["CODES", "lm_advance", "lm_start", "repack_default", "solve_batch"]


def _code(result) -> int:
    return int(jax.tree_util.tree_leaves(result)[0])


#: optimistix ``RESULTS`` integer codes used as per-problem status.
CODES = {"successful": _code(optx.RESULTS.successful),
         "max_steps": _code(optx.RESULTS.nonlinear_max_steps_reached),
         "singular": _code(optx.RESULTS.singular),
         "divergence": _code(optx.RESULTS.nonlinear_divergence)}

_LOW, _HIGH, _GROW, _SHRINK = 0.01, 0.99, 3.5, 0.25  # optimistix's ClassicalTrustRegion defaults


def _rms(x, axis=-1):
    return jnp.sqrt(jnp.mean(jnp.square(x), axis=axis))


def _per_problem(fn: Callable, z, data, data_axis):
    """``fn(z_b, data_b)`` for every problem ``b``, stacked: vmapped, or — one problem with shared
    data (every single solve) — called directly. The same program math (bit-identical results), but
    JAX then batches the simulation's scan body one layer fewer while tracing (the diagnosis
    workspace's solve: trace + lower 3.7 s instead of 6.1–7.2 s)."""
    if z.shape[0] == 1 and data_axis is None:
        return jax.tree_util.tree_map(lambda a: a[None], fn(z[0], data))
    return jax.vmap(fn, in_axes=(0, data_axis))(z, data)


def _eval(res: Callable, z, data, data_axis):
    return _per_problem(res, z, data, data_axis)


def _jacobian(res: Callable, z, data, data_axis, jac: Callable | None = None):
    """``(J, r)`` per problem by forward mode: ``n`` JVPs batched over the tangents, or the
    problem's own ``jac(z, data) -> (J, r)`` (one that skips known zero blocks,
    :meth:`diffship.fit.kernel.Kernel.blocked_jacobian`)."""
    n = z.shape[-1]

    def one(zb, db):
        def jvp(t):
            return jax.jvp(lambda x: res(x, db), (zb,), (t,))
        r, jac = jax.vmap(jvp, out_axes=(None, 1))(jnp.eye(n, dtype=zb.dtype))
        return jac, r
    return _per_problem(one if jac is None else jac, z, data, data_axis)


def _gn_short(z, jtj, jtr, cost, rows, n_free, *, gntol, variance, gn_params, rtol, atol):
    """Per problem: the Gauss–Newton step is short in standard errors or negligible in ``z``."""
    def one(zb, a, g, c, m, nf):
        dz, chi2 = gauss_newton_step(a, g, gn_params)
        s2 = (2.0 * c / jnp.maximum(m - nf, 1).astype(c.dtype)) if variance is None else variance
        k = zb.size if gn_params is None else min(gn_params, zb.size)
        tiny = jnp.all(jnp.abs(dz[:k]) < atol + rtol * jnp.abs(zb[:k]))
        return (chi2 < gntol ** 2 * s2) | tiny
    return jax.vmap(one)(z, jtj, jtr, cost, rows, n_free)


def _pinned(z, jtj, jtr, cost, rows, n_free, *, bounded, gntol, variance):
    r"""Per problem: the bounded parameters pressed against their bound, ``(B, n)``.

    A parameter bounded on one side runs in ``θ = a + s·exp(z)`` (or ``b − s·exp(z)``), so its distance to the
    bound equals :math:`|d\theta/dz|` and, by the delta method, the distance in its own standard errors is
    :math:`1/\sigma_z` (two-sided: the same near either bound, where the sigmoid's tail is an exponential). One
    whose :math:`\sigma_z` exceeds ``1/gntol`` and whose Gauss–Newton step points further into the tail lies
    within ``gntol`` standard errors of its bound and can gain no more than that: its optimum is on the bound,
    at :math:`z = \mp\infty`, where the Gauss–Newton step in ``z`` keeps its length (the column of ``J`` and
    the gradient shrink together). ``bounded``: each unknown's :attr:`diffship.params.Param.kind` (0 for the
    unbounded and for the nuisance unknowns)."""
    kind = jnp.asarray(bounded + (0,) * (z.shape[-1] - len(bounded)), jnp.int32)[: z.shape[-1]]

    def one(zb, a, g, c, m, nf):
        w, V = jnp.linalg.eigh(a)
        keep = w > a.shape[-1] * jnp.finfo(a.dtype).eps * jnp.max(jnp.abs(w))
        inv = jnp.where(keep, 1.0 / jnp.where(keep, w, 1.0), 0.0)
        dz = -(V @ (inv * (V.T @ g)))
        s2 = (2.0 * c / jnp.maximum(m - nf, 1).astype(c.dtype)) if variance is None else variance
        se = jnp.sqrt(s2 * ((V * V) @ inv))
        toward = jnp.where(kind == 3, dz * zb > 0, dz < 0)
        return (kind != 0) & toward & (se * gntol > 1.0)
    return jax.vmap(one)(z, jtj, jtr, cost, rows, n_free)


def _masked(jtj, jtr, free):
    """Normal equations with held coordinates decoupled (identity rows, zero gradient)."""
    f = free.astype(jtj.dtype)
    outer = f[:, :, None] * f[:, None, :]
    eye = jnp.eye(jtj.shape[-1], dtype=jtj.dtype)
    return jtj * outer + eye * (1.0 - f)[:, None, :], jtr * f


def _step(jtj, jtr, step_size):
    """Damped step per problem and whether it is finite."""
    eps = jnp.finfo(jtr.dtype).eps
    lam = jnp.where(step_size > eps, 1.0 / jnp.maximum(step_size, eps), 1.0 / eps)
    a = jtj + lam[:, None, None] * jnp.eye(jtr.shape[-1], dtype=jtr.dtype)
    chol = jnp.linalg.cholesky(a)
    diff = -jax.vmap(lambda c, g: jax.scipy.linalg.cho_solve((c, True), g))(chol, jtr)
    ok = jnp.all(jnp.isfinite(diff), axis=-1)
    return jnp.where(ok[:, None], diff, 0.0), ok


def lm_start(res: Callable, z0: Float[Array, "B n"], data, free: Bool[Array, "B n"], *, data_axis=None,
             keep_jacobian: bool = False, penalty: float | None = None, stall_steps: int = 0, stall_rtol: float = 0.0,
             jac: Callable | None = None, rows: int | None = None, bounded: tuple[int, ...] = (), **tol) -> dict:
    """State of the batched LM at the starts, before any evaluation: the first pass of
    :func:`lm_advance` forms the residuals and Jacobian there (optimistix's first step: the
    residuals compared with zeros, no step in z), so a compiled solve holds the model's
    forward-mode Jacobian once, not once for the start and once for the steps (half the
    compile time of a solve). ``jac``: the problem's own ``(J, r)`` (:func:`lm_advance`); ``rows``: the
    length of the residual vector when the caller knows it (else one trace of ``res`` finds it)."""
    del penalty, stall_steps, stall_rtol, jac, bounded, tol
    B, n = z0.shape
    # the residual count: given (``rows``), or from the residual function's shape (a trace of it)
    m = rows if rows is not None else jax.eval_shape(lambda z: _eval(res, z, data, data_axis), z0).shape[-1]
    r0 = jnp.zeros((B, m), z0.dtype)
    inf = jnp.full((B,), jnp.inf, z0.dtype)
    st = dict(z=z0, z_eval=z0, r=r0, cost=inf, prev_cost=inf, jtj=jnp.zeros((B, n, n), z0.dtype),
              jtr=jnp.zeros((B, n), z0.dtype), rows=jnp.sum(r0 != 0, axis=-1), n_free=jnp.sum(free, axis=-1),
              free=free, step_size=jnp.ones((B,), z0.dtype), accepted=jnp.zeros((B,), jnp.int32),
              steps=jnp.zeros((B,), jnp.int32), done=jnp.zeros((B,), bool),
              status=jnp.full((B,), CODES["successful"], jnp.int32), win_cost=inf,
              win_steps=jnp.zeros((B,), jnp.int32), first=jnp.ones((B,), bool))
    if keep_jacobian:
        st["jac"] = jnp.zeros((B, m, n), z0.dtype)
    return st


def _finish_step(st, converged, diverged, *, penalty, max_steps, stalled=None):
    """Mark newly finished problems and form the next trial step of the others (``stalled``:
    problems whose cost crawls, stopped as not converged)."""
    active = ~st["done"]
    a, g = _masked(st["jtj"], st["jtr"], st["free"])
    diff, ok = _step(a, g, st["step_size"])
    status = st["status"]
    blown = jnp.zeros_like(converged) if penalty is None else jnp.any(st["r"] == penalty, axis=-1)
    newly = active & converged
    status = jnp.where(newly & blown, CODES["divergence"], status)
    fail = active & ~converged & diverged
    status = jnp.where(fail, CODES["divergence"], status)
    sing = active & ~converged & ~diverged & ~ok
    status = jnp.where(sing, CODES["singular"], status)
    done = st["done"] | newly | fail | sing
    out = active & ~done & (st["steps"] >= max_steps)
    if stalled is not None:
        out = out | (active & ~done & stalled)
    status = jnp.where(out, jnp.where(blown, CODES["divergence"], CODES["max_steps"]), status)
    done = done | out
    st = dict(st, done=done, status=status)
    st["z_eval"] = jnp.where(done[:, None], st["z"], st["z"] + diff)
    return st


def lm_advance(res: Callable, st: dict, data, stop_below: Array, *, data_axis=None, keep_jacobian: bool = False,
               penalty: float | None = None, rtol, atol, ftol, gntol, variance, gn_params, max_steps,
               stall_steps: int = 0, stall_rtol: float = 0.0, jac: Callable | None = None,
               bounded: tuple[int, ...] = (), stop_above: tuple[tuple[int, float], ...] = ()) -> dict:
    """Advance every unfinished problem until all are done or no more than ``stop_below`` remain
    unfinished (a dynamic scalar: the host repacks then; ``0`` runs to the end); with
    ``stall_steps`` > 0 a problem whose cost falls by less than ``stall_rtol``·cost over that many
    steps stops, not converged (module docstring, item 6). ``bounded``: the kinds of the first unknowns'
    bounds (:func:`_pinned`; module docstring, item 5); ``stop_above``: item 7."""
    tol = dict(rtol=rtol, atol=atol, gntol=gntol, variance=variance, gn_params=gn_params)

    def body(st):
        active = ~st["done"]
        z, z_eval = st["z"], st["z_eval"]
        r_eval = _eval(res, z_eval, data, data_axis)
        cost_eval = 0.5 * jnp.sum(r_eval * r_eval, axis=-1)
        d = z_eval - z
        pred = jnp.einsum("bi,bi->b", d, st["jtr"]) + 0.5 * jnp.einsum("bi,bij,bj->b", d, st["jtj"], d)
        actual = cost_eval - st["cost"]
        first = st["first"]  # the starts themselves (lm_start): accepted, step size 1
        accept = active & ((actual <= _LOW * pred) | first)
        good = (actual < _HIGH * pred) & (pred < 0)
        mul = jnp.where(accept, jnp.where(good, _GROW, 1.0), _SHRINK)
        step_size = jnp.where(active, jnp.where(first, 1.0, mul * st["step_size"]), st["step_size"])

        n = z.shape[-1]
        m = r_eval.shape[-1]
        zeros_j = jnp.zeros(z.shape[:1] + (m, n), z.dtype)

        def with_jac(_):
            J, _r = _jacobian(res, z_eval, data, data_axis, jac)
            return J * st["free"].astype(z.dtype)[:, None, :]
        J = jax.lax.cond(jnp.any(accept), with_jac, lambda _: zeros_j, None)
        jtj_new = jnp.einsum("bmi,bmj->bij", J, J)
        jtr_new = jnp.einsum("bmi,bm->bi", J, r_eval)

        cauchy = accept & (_rms(jnp.abs(d) / (atol + rtol * jnp.abs(z_eval))) < 1) \
            & (_rms(jnp.abs(r_eval - st["r"]) / (atol + rtol * jnp.abs(r_eval))) < 1)
        A = accept[:, None]
        new = dict(st,
                   z=jnp.where(A, z_eval, z), r=jnp.where(A, r_eval, st["r"]),
                   cost=jnp.where(accept, cost_eval, st["cost"]),
                   prev_cost=jnp.where(accept, st["cost"], st["prev_cost"]),
                   jtj=jnp.where(accept[:, None, None], jtj_new, st["jtj"]),
                   jtr=jnp.where(A, jtr_new, st["jtr"]),
                   rows=jnp.where(accept, jnp.sum(r_eval != 0, axis=-1), st["rows"]),
                   accepted=st["accepted"] + accept.astype(jnp.int32),
                   steps=st["steps"] + active.astype(jnp.int32), step_size=step_size,
                   first=first & ~active)
        if keep_jacobian:
            new["jac"] = jnp.where(accept[:, None, None], J, st["jac"])
        stalled = (new["accepted"] >= 3) & ((new["prev_cost"] - new["cost"]) <= ftol * new["cost"])
        gn = _gn_short(new["z"], *_masked(new["jtj"], new["jtr"], new["free"]), new["cost"], new["rows"],
                       new["n_free"], **tol)
        converged = (cauchy | stalled) & gn
        held = new["free"]  # the coordinates the Gauss–Newton model may still move
        if any(bounded) and gntol < float("inf"):  # with the Gauss–Newton check off, the plain tests alone
            pin = _pinned(new["z"], *_masked(new["jtj"], new["jtr"], new["free"]), new["cost"], new["rows"],
                          new["n_free"], bounded=bounded, gntol=gntol, variance=variance) & new["free"]
            held = new["free"] & ~pin
            # on its bound, a parameter's optimum is at infinity in z: the others' step decides (item 5)
            gn_rest = _gn_short(new["z"], *_masked(new["jtj"], new["jtr"], held), new["cost"], new["rows"],
                                new["n_free"], **tol)
            converged = converged | (jnp.any(pin, axis=-1) & (new["accepted"] >= 3) & gn_rest)
        crawl = None
        if stall_steps:
            win = jnp.where(first, 0, new["win_steps"] + active.astype(jnp.int32))
            full = active & (win >= stall_steps)
            # a crawl, not the last steps of a convergence: the Gauss–Newton model still promises a
            # decrease above the threshold that the steps do not deliver
            a, g = _masked(new["jtj"], new["jtr"], held)
            promise = 0.5 * jax.vmap(lambda ab, gb: gauss_newton_step(ab, gb)[1])(a, g)
            crawl = full & ((new["win_cost"] - new["cost"]) <= stall_rtol * new["cost"]) \
                & (promise > stall_rtol * new["cost"])
            new["win_cost"] = jnp.where(full | first, new["cost"], new["win_cost"])
            new["win_steps"] = jnp.where(full, 0, win)
        for i, v in stop_above:  # item 7: past an absorbing bound
            crawl = (new["z"][:, i] >= v) if crawl is None else crawl | (new["z"][:, i] >= v)
        diverged = active & first & ~jnp.isfinite(cost_eval)  # a start whose cost is not finite
        return _finish_step(new, converged, diverged, penalty=penalty,
                            max_steps=max_steps, stalled=crawl)

    def cond(st):
        left = jnp.sum(~st["done"])
        return (left > 0) & (left > jnp.asarray(stop_below).astype(left.dtype))

    return jax.lax.while_loop(cond, body, st)


def repack_default() -> bool:
    """Whether the host repacks unfinished problems into smaller batches between rounds: on a CPU
    (work grows with the batch, so frozen problems cost time), not on a GPU or TPU (a batch step
    costs about one problem's step: repacking would only add compiles)."""
    return jax.default_backend() == "cpu"


def _bucket(k: int) -> int:
    return 1 << max(0, int(k) - 1).bit_length()


def solve_batch(start: Callable, advance: Callable, z0s, data, free, *, per_problem_data: bool,
                repack: bool | None = None, min_bucket: int = 1, factor: int = 4) -> dict:
    """Host driver of the batched LM: ``start(z0, data, free)`` and ``advance(state, data, stop)`` are
    the compiled programs (one per bucket size, the callables compile on first use). Runs rounds,
    repacking unfinished problems into power-of-two buckets when ``repack`` (default
    :func:`repack_default`) once no more than ``1/factor`` of a bucket is unfinished (each new
    bucket size is a new compiled program: seconds on a CPU). Returns the final state with NumPy arrays, rows in start order."""
    repack = repack_default() if repack is None else repack
    z0s = np.asarray(z0s, dtype=np.float64)
    B = z0s.shape[0]
    take = (lambda tree, idx: jax.tree_util.tree_map(lambda a: np.asarray(a)[idx], tree))
    bucket = _bucket(B) if repack else B
    idx = np.concatenate([np.arange(B), np.zeros(bucket - B, int)])
    d = take(data, idx) if per_problem_data else data
    st = start(z0s[idx], d, np.asarray(free)[idx])
    if bucket > B:  # padding copies of problem 0: frozen from the start
        st = dict(st, done=jnp.asarray(np.arange(bucket) >= B) | st["done"])
    final = {}
    rows = np.arange(bucket)
    rows = np.where(rows < B, rows, -1)
    while True:
        stop = bucket // factor if (repack and bucket > min_bucket) else 0
        st = advance(st, d, np.asarray(stop, dtype=np.int32))
        host = {k: np.asarray(v) for k, v in st.items()}
        done = host["done"]
        for i in np.flatnonzero(done & (rows >= 0)):
            final[int(rows[i])] = {k: v[i] for k, v in host.items()}
            rows[i] = -1
        left = np.flatnonzero(rows >= 0)
        if left.size == 0:
            break
        bucket = max(_bucket(left.size), min_bucket)
        pick = np.concatenate([left, np.full(bucket - left.size, left[0])])
        rows = np.concatenate([rows[left], np.full(bucket - left.size, -1)])
        host["done"] = np.concatenate([np.zeros(left.size, bool), np.ones(bucket - left.size, bool)])
        host = {k: (v[pick] if k != "done" else v) for k, v in host.items()}
        st = {k: jnp.asarray(v) for k, v in host.items()}
        d = take(d, pick) if per_problem_data else d
    return {k: np.stack([final[b][k] for b in range(B)]) for k in final[0]}
