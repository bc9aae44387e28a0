"""Every call from the benchmarks into diffship's fitting API, in one place.

The suite's case modules, its peers and the standalone scripts (``fossen3_speed.py``,
``fossen3_coverage.py``, ``simulate_speed.py``, the timing modes of ``timing/``) reach ``fit_output_error``,
``fit_equation_error``, ``fit_both``, ``make_batch``, ``channel_spread``, the output-error
kernel (``diffship.fit.kernel``, for the vmapped fixed-iteration LM and the vmapped ``Kernel.solve``),
``FitResult`` fields and the KVLCC2 study only through the functions below. When the library's
signatures change, edit here.

The keyword arguments are forwarded exactly as the callers give them: an argument a caller
leaves out is not passed, so the library's default applies (as in the calls these replace).
"""

from __future__ import annotations

import numpy as np

import diffship  # noqa: F401  (enables float64)
from diffship.fit import OutputErrorOptions, fit_both, fit_equation_error, fit_output_error
from diffship.fit.kernel import PENALTY, Kernel, kernel_data
from diffship.fit.output_error import channel_spread, x0_scales
from diffship.fit.problem import make_batch
from diffship.preprocess import Filter

__all__ = ["FLT_NONE", "PENALTY", "fit_oe", "fit_ee", "fit_oe_and_ee", "batch_of", "spread_of", "lm_problem",
           "oe_kernel", "kernel_residuals", "kernel_jacobian", "kernel_solver", "initial_states", "fitted_model",
           "fitted_params", "fit_numbers", "kvlcc2_study"]

#: raw first samples as initial states, no smoothing of the fitted channels (the scipy peer's problem)
FLT_NONE = Filter("none")
_UNSET = object()


def _given(**kw):
    return {k: v for k, v in kw.items() if v is not _UNSET}


def fit_oe(model, runs, *, spec=_UNSET, estimate_x0=_UNSET, weights=_UNSET, flt=_UNSET, channels=_UNSET,
           starts=_UNSET, max_steps=_UNSET, rtol=_UNSET, atol=_UNSET, reference_priors=_UNSET, x0_prior=_UNSET,
           adaptive=_UNSET, effective_samples=_UNSET):
    """``diffship.fit.fit_output_error(model, runs, spec=..., channels=..., starts=..., options=...)``."""
    options = OutputErrorOptions(**_given(estimate_x0=estimate_x0, weights=weights, flt=flt, max_steps=max_steps,
                                          rtol=rtol, atol=atol, reference_priors=reference_priors,
                                          x0_prior=x0_prior, adaptive=adaptive,
                                          effective_samples=effective_samples))
    return fit_output_error(model, runs, options=options, **_given(spec=spec, channels=channels, starts=starts))


def fit_ee(model, runs, *, spec=_UNSET):
    """``diffship.fit.fit_equation_error(model, runs, **given)``."""
    return fit_equation_error(model, runs, **_given(spec=spec))


def fit_oe_and_ee(model, runs):
    """``diffship.fit.fit_both(model, runs)``: ``{"output_error": ..., "equation_error": ...}``."""
    return fit_both(model, runs)


def batch_of(model, runs, channels, flt):
    """``diffship.fit.problem.make_batch(model, runs, channels, flt)``: stacked runs (ts, us, ys, mask, x0)."""
    return make_batch(model, runs, channels, flt)


def spread_of(batch) -> np.ndarray:
    """Per-channel spread of a batch (diffship's ``weights="spread"`` scales)."""
    return channel_spread(batch)


def lm_problem(spec, model, batch, scales, *, out_idx, angle, x0_idx):
    """diffship's output-error kernel as ``(kernel, data)`` with ``kernel.residuals(z, data)`` jittable.

    ``z`` = scaled free parameters followed by the per-run initial-state offsets (RK4, one step
    per sample; offsets in units of the channel ``scales``); used by the vmapped fixed-iteration
    LM of the Nomoto batch benchmark.
    """
    kernel = Kernel(spec=spec.structural(), out_idx=out_idx, angle=angle, x0_idx=x0_idx)
    data = kernel_data(model, batch.ts, batch.us, batch.ys, batch.mask, batch.x0, scales, x0_scale=scales)
    return kernel, data


def oe_kernel(model, runs, *, spec, channels, estimate_x0, flt):
    """``(kernel, data, z0, batch)`` built exactly as ``fit_output_error(..., weights="spread")`` builds them.

    Default ``OutputErrorOptions`` integrator (RK4, one step per sample); channel spreads as
    scales; offsets of the ``estimate_x0`` states in units of ``x0_scales``; ``z0`` = the spec's
    free values in the scaled space followed by zero offsets.
    """
    model = model.with_params(spec.values())
    batch = make_batch(model, runs, channels, flt)
    kernel = Kernel(
        spec=spec.structural(),
        out_idx=tuple(model.output_names.index(c) for c in batch.channels),
        angle=tuple(c in model.angle_outputs for c in batch.channels),
        x0_idx=tuple(model.state_names.index(s) for s in estimate_x0),
        integrator=OutputErrorOptions().integrator,
    )
    data = kernel_data(model, batch.ts, batch.us, batch.ys, batch.mask, batch.x0, channel_spread(batch),
                       x0_scale=x0_scales(model, batch, estimate_x0))
    z0 = np.concatenate([spec.to_z(), np.zeros(len(kernel.x0_idx) * len(runs))])
    return kernel, data, z0, batch


def kernel_residuals(kernel, data, z) -> np.ndarray:
    """``kernel.residuals(z, data)`` (compiled) as NumPy."""
    return np.asarray(kernel.call("residuals", z, data))


def kernel_jacobian(kernel, data, z) -> np.ndarray:
    """``kernel.jacobian(z, data)`` (compiled, forward mode) as NumPy."""
    return np.asarray(kernel.call("jacobian", z, data))


def kernel_solver(kernel, data, z0s, *, max_steps, rtol, atol, ftol=None, batched=True):
    """``kernel.solve`` compiled for the starts ``z0s`` ``(B, n_z)``: ``(fn, compile_seconds)``.

    ``batched=True``: ``jax.vmap`` over the starts (one program, all fits in lockstep);
    ``fn(z0s)`` returns ``(z, steps, cost, converged)`` each with a leading batch axis.
    ``batched=False``: the one-start program ``fit_output_error`` uses (``Kernel.compiled("solve")``);
    ``fn(z0)`` returns the same four for one start.
    """
    import time

    import jax
    import jax.numpy as jnp
    import optimistix as optx

    lm = dict(max_steps=max_steps, rtol=rtol, atol=atol, **({} if ftol is None else {"ftol": ftol}))

    def finish(out):
        z, result, steps, r = out
        return z, steps, 0.5 * jnp.sum(r * r), result == optx.RESULTS.successful

    if not batched:
        fn, c = kernel.compiled("solve", np.asarray(z0s)[0], data, **lm)
        fin = jax.jit(finish)
        return (lambda z0: jax.block_until_ready(fin(fn(jnp.asarray(z0, dtype=jnp.float64), data)))), c

    one = lambda z0, d: finish(kernel.solve(z0, d, **lm))  # noqa: E731
    t0 = time.perf_counter()
    z0s = jnp.asarray(z0s, dtype=jnp.float64)
    fn = jax.jit(jax.vmap(one, in_axes=(0, None))).lower(z0s, data).compile()
    c = time.perf_counter() - t0
    return (lambda zs: jax.block_until_ready(fn(jnp.asarray(zs, dtype=jnp.float64), data))), c


# -- FitResult fields --------------------------------------------------------------------------------------
def initial_states(res) -> np.ndarray:
    """Per-run fitted initial states, stacked ``(R, n_states)`` in ``model.state_names`` order."""
    return np.stack(res.initial_states)


def fitted_model(res):
    return res.model


def fitted_params(res) -> dict:
    return res.params


def fit_numbers(res) -> dict:
    """The numbers the suite records of a fit: compile_s, fit_s, cost, iterations, converged."""
    return dict(compile_s=res.compile_seconds, fit_s=res.fit_seconds, cost=res.cost, iterations=res.iterations,
                converged=res.converged)


def kvlcc2_study():
    """``diffship.studies.kvlcc2.kvlcc2_study()`` (MMG output-error fit + predictions); raises ImportError."""
    from diffship.studies.kvlcc2 import kvlcc2_study as study

    return study()
