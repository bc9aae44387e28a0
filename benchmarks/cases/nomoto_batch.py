"""Part of case ``nomoto``: vmapped batches of fits vs loops (variant ``batch`` of ``nomoto_linear``).

What is measured (CPU unless a GPU backend is installed):

* output error over N random starts: ``jax.vmap`` of a fixed-iteration (30) Levenberg–Marquardt
  on diffship's output-error residual (one compiled call) vs the same jitted LM in a Python loop
  vs a loop of adaptive ``fit_output_error`` calls (timed by the caller); time per fit, compile
  times, and the share of vmapped starts within 1 % of the best cost;
* equation error bootstrap: ``jax.vmap`` of the weighted normal equations of the Nomoto
  regression ṙ = a r + b δ + c over B multinomial resamples vs a NumPy ``lstsq`` loop, and the
  time of a whole ``fit_equation_error`` call.
"""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import numpy as np

from benchmarks.common.fitapi import FLT_NONE, batch_of, fit_ee, lm_problem, spread_of
from benchmarks.record import say
from diffship.models import Nomoto1
from diffship.preprocess import Filter, smooth_and_derivative


def nomoto_derivatives(train, trim=True):
    """Butterworth-filtered r, ṙ and δ per run (diffship equation error's derivatives), 2 % trimmed at both ends."""
    R, RD, D = [], [], []
    for run in train:
        r, rd = smooth_and_derivative(run.time, np.asarray(run["r"]), Filter())
        k = int(0.02 * r.size) if trim else 0
        R.append(r[k:r.size - k]); RD.append(rd[k:r.size - k]); D.append(np.asarray(run["delta"])[k:r.size - k])
    return R, RD, D


def _lm_fixed(problem, iters):
    """Fixed-iteration Levenberg–Marquardt (forward-mode Jacobian, Marquardt scaling) as one jittable function."""

    def solve(z0, args):
        res = lambda z: problem.residuals(z, args)  # noqa: E731
        r0 = res(z0)

        def body(carry, _):
            z, lam, c = carry
            r = res(z)
            J = jax.jacfwd(res)(z)
            H = J.T @ J
            g = J.T @ r
            A = H + lam * jnp.diag(jnp.diag(H) + 1e-12)
            dz = jnp.linalg.solve(A, -g)
            zn = z + dz
            rn = res(zn)
            cn = 0.5 * jnp.sum(rn * rn)
            ok = jnp.isfinite(cn) & (cn < c)
            return (jnp.where(ok, zn, z), jnp.where(ok, lam * 0.3, lam * 4.0), jnp.where(ok, cn, c)), None

        init = (z0, jnp.asarray(1e-3, dtype=jnp.float64), 0.5 * jnp.sum(r0 * r0))
        (z, _, c), _ = jax.lax.scan(body, init, None, length=iters)
        return z, c

    return solve


def batched(rec, case, train, starts, loop_fits, quick):
    """vmap of a fixed-iteration LM over starts vs a loop of single fits; vmap of bootstrap EE vs a loop."""
    say(f"{case}: vmapped batches")
    variant = "batch"
    spec0 = Nomoto1().spec().with_values(starts[0])
    model = Nomoto1().with_params(spec0.values())
    batch = batch_of(model, train, ("psi", "r"), FLT_NONE)
    problem, args = lm_problem(spec0, model, batch, spread_of(batch), out_idx=(0, 1), angle=(True, False), x0_idx=(0, 1))
    iters = 30
    Z0 = jnp.asarray(np.stack([np.concatenate([spec0.to_z(s), np.zeros(2 * len(train))]) for s in starts]))
    solve = _lm_fixed(problem, iters)
    vm = jax.jit(jax.vmap(solve, in_axes=(0, None)))
    one = jax.jit(solve)
    t = time.perf_counter()
    vm_c = vm.lower(Z0, args).compile()
    c_vm = time.perf_counter() - t
    t = time.perf_counter()
    one_c = one.lower(Z0[0], args).compile()
    c_one = time.perf_counter() - t
    jax.block_until_ready(vm_c(Z0, args))  # warm-up run
    t = time.perf_counter()
    _, costs_vm = jax.block_until_ready(vm_c(Z0, args))
    t_vm = time.perf_counter() - t
    t = time.perf_counter()
    costs_one = [float(one_c(z, args)[1]) for z in Z0]
    t_one = time.perf_counter() - t
    n = len(starts)
    best = min(min(float(jnp.min(costs_vm)), min(costs_one)), min(c for c, _ in loop_fits))
    rec.add(case, variant, "diffship_oe", "loop_fit_output_error_time_per_fit_s", float(np.mean([s for _, s in loop_fits])),
            "s", f"{n} starts, warm diffship fits (adaptive LM, up to 200 steps) in a Python loop")
    rec.add(case, variant, "diffship_oe", "vmap_lm_time_per_fit_s", t_vm / n, "s",
            f"jax.vmap of a {iters}-iteration LM over {n} starts, one compiled call")
    rec.add(case, variant, "diffship_oe", "jit_lm_loop_time_per_fit_s", t_one / n, "s",
            f"the same {iters}-iteration LM, jitted, unbatched, Python loop over {n} starts")
    rec.add(case, variant, "diffship_oe", "vmap_lm_compile_s", c_vm, "s")
    rec.add(case, variant, "diffship_oe", "jit_lm_compile_s", c_one, "s")
    rec.add(case, variant, "diffship_oe", "vmap_lm_converged_rate",
            float(np.mean(np.asarray(costs_vm) <= 1.01 * best)), "", "within 1 % of the best cost")
    rec.add(case, variant, "diffship_oe", "n_batch", n)
    # equation error bootstrap: weighted normal equations of the Nomoto regression
    B = 64 if quick else 256
    R, RD, D = nomoto_derivatives(train, trim=False)
    A = np.stack([np.concatenate(R), np.concatenate(D), np.ones(sum(x.size for x in R))], 1)
    y = np.concatenate(RD)
    rng = np.random.default_rng(0)
    W = rng.multinomial(A.shape[0], np.full(A.shape[0], 1.0 / A.shape[0]), size=B).astype(np.float64)

    def wls(w, A, y):
        Aw = A * w[:, None]
        return jnp.linalg.solve(Aw.T @ A, Aw.T @ y)

    f = jax.jit(jax.vmap(wls, in_axes=(0, None, None)))
    Aj, yj, Wj = jnp.asarray(A), jnp.asarray(y), jnp.asarray(W)
    t = time.perf_counter()
    f_c = f.lower(Wj, Aj, yj).compile()
    c_b = time.perf_counter() - t
    jax.block_until_ready(f_c(Wj, Aj, yj))
    t = time.perf_counter()
    jax.block_until_ready(f_c(Wj, Aj, yj))
    t_b = time.perf_counter() - t
    t = time.perf_counter()
    for w in W:
        idx = np.repeat(np.arange(A.shape[0]), w.astype(int))
        np.linalg.lstsq(A[idx], y[idx], rcond=None)
    t_np = time.perf_counter() - t
    t = time.perf_counter()
    n_ee = 3 if quick else 10
    for _ in range(n_ee):
        fit_ee(Nomoto1(), train)
    t_ee = (time.perf_counter() - t) / n_ee
    rec.add(case, variant, "diffship_ee", "vmap_bootstrap_time_per_fit_s", t_b / B, "s", f"jax.vmap weighted LS, {B} resamples")
    rec.add(case, variant, "diffship_ee", "vmap_bootstrap_compile_s", c_b, "s")
    rec.add(case, variant, "numpy_ols", "loop_bootstrap_time_per_fit_s", t_np / B, "s", f"NumPy lstsq loop, {B} resamples")
    rec.add(case, variant, "diffship_ee", "loop_fit_equation_error_time_per_fit_s", t_ee, "s",
            "whole fit_equation_error call (filtering + GN + weighting pass)")
