r"""Simulate one trajectory of a model over a sample grid.

Inputs are given at the sample times and interpolated linearly in between (first-order
hold). Two integrators sit behind one interface:

* ``"rk4"`` (default): classical fixed-step Runge–Kutta 4 in :func:`jax.lax.scan` on the
  sample grid, ``substeps`` steps per sample interval; forward-differentiable. Measured on the
  fossen3 fit problem (3 runs × 300 s at 10 Hz, batched with vmap, 2-core CPU): simulation
  11 ms vs 44 ms for Tsit5, forward-mode Jacobian 62 ms vs 169 ms
  (``benchmarks/simulate_speed.py``). Tsit5 wins on a single unbatched run with smooth inputs
  (fewer, larger steps), RK4 wherever every sample is needed anyway.
* ``"tsit5"``: diffrax's Tsitouras 5(4) with a PID step-size controller (``rtol``, ``atol``)
  and ``adjoint=diffrax.ForwardMode()``, so that forward-mode Jacobians (what
  Levenberg–Marquardt needs) work through the solver.

A simulation that blows up (non-finite state, or ``|x| > max_abs``) does not return NaN
garbage: the state is frozen at its last good value and ``Solution.valid`` marks the samples
after the blow-up as invalid; ``Solution.ok`` is the readable status.

Models take one trajectory; batch with ``jax.vmap(simulate, ...)`` over runs or parameters.
"""

from __future__ import annotations

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float

from .data import Run
from .errors import DataError
from .models._base import AbstractModel
from .preprocess import Filter, smooth_and_derivative

__all__ = ["Solution", "simulate", "model_inputs", "initial_state"]

#: Scan unrolling for the RK4 integrator. Unrolling 4–16 steps was measured slower on CPU (XLA's
#: per-instruction cost dominates, not the loop overhead) and compiles much longer: kept at 1.
UNROLL = 1


class Solution(eqx.Module):
    """A simulated trajectory on the sample grid.

    Attributes:
        ts: sample times [s], shape ``(N,)``.
        xs: states, shape ``(N, n_x)`` (frozen after a blow-up).
        ys: predicted measured channels (``model.output_names``), shape ``(N, n_y)``.
        valid: ``False`` from the first sample at which the simulation blew up.
    """

    ts: Float[Array, " N"]
    xs: Float[Array, "N n_x"]
    ys: Float[Array, "N n_y"]
    valid: Bool[Array, " N"]

    @property
    def ok(self) -> Bool[Array, ""]:
        return jnp.all(self.valid)


def _rk4_scan(model, ts, us, x0, substeps, max_abs, unroll=UNROLL):
    def f(t, x, u):
        return model.vector_field(t, x, u)

    def interval(carry, inp):
        x, good = carry
        t0, t1, u0, u1 = inp
        h = (t1 - t0) / substeps
        du = (u1 - u0) / substeps
        y = x
        for k in range(substeps):  # static unroll, substeps is small
            t = t0 + k * h
            ua, uc = u0 + k * du, u0 + (k + 1) * du
            ub = 0.5 * (ua + uc)
            k1 = f(t, y, ua)
            k2 = f(t + 0.5 * h, y + 0.5 * h * k1, ub)
            k3 = f(t + 0.5 * h, y + 0.5 * h * k2, ub)
            k4 = f(t + h, y + h * k3, uc)
            y = y + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        good_now = good & jnp.all(jnp.isfinite(y)) & jnp.all(jnp.abs(y) < max_abs)
        y = jnp.where(good_now, y, x)
        return (y, good_now), (y, good_now)

    inputs = (ts[:-1], ts[1:], us[:-1], us[1:])
    (_, _), (xs, valid) = jax.lax.scan(interval, (x0, jnp.array(True)), inputs, unroll=unroll)
    xs = jnp.concatenate([x0[None], xs], axis=0)
    valid = jnp.concatenate([jnp.array([True]), valid])
    return xs, valid


def _diffrax(model, ts, us, x0, rtol, atol, max_steps, max_abs):
    control = diffrax.LinearInterpolation(ts=ts, ys=us)

    def f(t, x, args):
        return model.vector_field(t, x, control.evaluate(t))

    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(f),
        diffrax.Tsit5(),
        t0=ts[0],
        t1=ts[-1],
        dt0=ts[1] - ts[0],
        y0=x0,
        saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=diffrax.ClipStepSizeController(diffrax.PIDController(rtol=rtol, atol=atol), jump_ts=None),
        adjoint=diffrax.ForwardMode(),
        max_steps=max_steps,
        throw=False,
    )
    xs = sol.ys
    finite = jnp.all(jnp.isfinite(xs) & (jnp.abs(xs) < max_abs), axis=1) & (sol.result == diffrax.RESULTS.successful)
    valid = jnp.cumprod(finite.astype(jnp.int32)).astype(bool)
    last_good = jnp.maximum(jnp.sum(valid) - 1, 0)
    xs = jnp.where(valid[:, None], xs, xs[last_good])
    xs = jnp.where(jnp.isfinite(xs), xs, 0.0)
    return xs, valid


def simulate(
    model: AbstractModel,
    ts: Float[Array, " N"],
    us: Float[Array, "N n_u"],
    x0: Float[Array, " n_x"],
    *,
    solver: str = "rk4",
    substeps: int = 1,
    rtol: float = 1e-6,
    atol: float = 1e-8,
    max_steps: int = 100_000,
    max_abs: float = 1e8,
) -> Solution:
    """Simulate ``model`` from ``x0`` over the strictly increasing grid ``ts``.

    Args:
        model: any :class:`~diffship.models.AbstractModel`.
        ts: sample times [s].
        us: inputs at the sample times, columns in ``model.input_names`` order.
        x0: initial state, in ``model.state_names`` order.
        solver: ``"rk4"`` (fixed-step scan) or ``"tsit5"`` (diffrax, adaptive).
        substeps: RK4 steps per sample interval (``"rk4"`` only).
        rtol, atol, max_steps: diffrax step-size control (``"tsit5"`` only).
        max_abs: a state component beyond this magnitude counts as a blow-up.
    """
    ts = jnp.asarray(ts, dtype=jnp.float64)
    us = jnp.asarray(us, dtype=jnp.float64)
    x0 = jnp.asarray(x0, dtype=jnp.float64)
    if solver == "rk4":
        xs, valid = _rk4_scan(model, ts, us, x0, int(substeps), max_abs)
    elif solver == "tsit5":
        xs, valid = _diffrax(model, ts, us, x0, rtol, atol, max_steps, max_abs)
    else:
        raise ValueError(f"unknown solver {solver!r}; use 'rk4' or 'tsit5'")
    ys = jax.vmap(model.observe)(xs, us)
    return Solution(ts=ts, xs=xs, ys=ys, valid=valid)


def model_inputs(model: AbstractModel, run: Run) -> np.ndarray:
    run.require(model.input_names, f"the inputs of model {model.name}")
    return np.stack([np.asarray(run[n], dtype=np.float64) for n in model.input_names], axis=1)


def initial_state(model: AbstractModel, run: Run, flt: Filter = Filter()) -> np.ndarray:
    """Initial state from the low-pass filtered measurements at the first sample."""
    y0 = {}
    t = np.asarray(run.time)
    for c in set(model.state_names) | set(model.output_names):
        if run.has(c):
            y = np.asarray(run[c])
            if c == "psi":
                y = np.unwrap(y)
            try:
                ys, yd = smooth_and_derivative(t, y, flt, f"run {run.name}, column {c}")
            except DataError:
                ys, yd = y, np.gradient(y, t)
            y0[c] = float(ys[0])
            y0[c + "_dot"] = float(yd[0])
    return model.initial_state(y0)
