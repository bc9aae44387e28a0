r"""Simulate one trajectory of a model over a sample grid.

Inputs are given at the sample times and held linearly in between (first-order hold); the
state is advanced from sample to sample by an integrator object
(:mod:`diffship.integrators`: by default :class:`~diffship.integrators.Diffrax`, diffrax's
classical RK4 tableau stepped once per sample; the hand-written :class:`~diffship.integrators.RK4`
and the adaptive :class:`~diffship.integrators.Tsit5` as options), in one :func:`jax.lax.scan` over the sample
intervals. Everything is forward-differentiable (Levenberg–Marquardt needs forward-mode
Jacobians through the whole simulation).

A simulation that blows up (non-finite state, or ``|x| > max_abs``) does not return NaN
garbage: the state is frozen at its last good value and ``Solution.valid`` marks the samples
after the blow-up as invalid; ``Solution.ok`` is the readable status.

Models take one trajectory; batch with ``jax.vmap(simulate, ...)`` over runs or parameters.
This module also turns a measured :class:`~diffship.data.Run` into what a simulation needs:
:func:`model_inputs` (the input columns) and :func:`initial_state` (the state at the first
sample from the filtered measurements).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from .data import Run
from .errors import DataError
from .integrators import AbstractIntegrator, Diffrax
from .models import AbstractModel
from .compiled import compiled
from .preprocess import Filter, smooth_and_derivative

__all__ = ["Solution", "simulate", "simulate_run", "integrate", "model_inputs", "initial_state", "MAX_ABS"]

#: A state component beyond this magnitude counts as a blow-up.
MAX_ABS = 1e8


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


#: intervals per block of a simulation with a horizon (:func:`integrate`)
BLOCK = 64


def integrate(
    f,
    ts: Float[Array, " N"],
    us: Float[Array, "N n_u"],
    x0: Float[Array, " n_x"],
    integrator: AbstractIntegrator,
    max_abs: float = MAX_ABS,
    horizon: Int[Array, ""] | None = None,
) -> tuple[Float[Array, "N n_x"], Bool[Array, " N"]]:
    """States of ``ẋ = f(t, x, u)`` on the grid ``ts`` and the per-sample validity flag.

    ``horizon`` (a traced sample count): the blocks of :data:`BLOCK` intervals wholly after the
    first ``horizon`` samples are not simulated (the state is held there), so one compiled
    program serves a growing-horizon warm-up and the whole runs; the caller masks the samples
    after the horizon (a few past it, up to the end of their block, are simulated; a run shorter
    than two blocks is simulated whole)."""

    def advance(x, good, t0, t1, u0, u1):
        y = integrator.interval(f, t0, t1, x, u0, u1)
        good_now = good & jnp.all(jnp.isfinite(y)) & jnp.all(jnp.abs(y) < max_abs)
        return jnp.where(good_now, y, x), good_now

    def interval(carry, inp):
        y, good_now = advance(*carry, *inp)
        return (y, good_now), (y, good_now)

    steps = (ts[:-1], ts[1:], us[:-1], us[1:])
    n = ts.shape[0] - 1
    # the carried "still finite" flag starts True, computed from x0 so that under vmap it is batched
    # like the states from the start: JAX's scan batching rule then traces the body once, not twice
    # (a NaN in x0 gives False here, as the first interval's test would)
    good0 = jnp.all(x0 == x0)
    if horizon is None or n < 2 * BLOCK:
        (_, _), (xs, valid) = jax.lax.scan(interval, (x0, good0), steps)
    else:
        # blocks of BLOCK intervals; a block wholly after the horizon is skipped (one cond per
        # block, not per step: a cond in every step cost 20 % of a Jacobian). The last block is
        # padded with unit-length intervals at the last input, whose states are dropped.
        nb = -(-n // BLOCK)
        pad = nb * BLOCK - n
        t_end = ts[-1] + jnp.arange(1, pad + 2, dtype=ts.dtype)
        ta = jnp.concatenate([ts[:-1], ts[-1:], t_end[:-1]])[:nb * BLOCK]
        tb = jnp.concatenate([ts[1:], t_end])[:nb * BLOCK]
        ue = jnp.broadcast_to(us[-1], (pad + 1,) + us.shape[1:])
        ua = jnp.concatenate([us[:-1], ue])[:nb * BLOCK]
        ub = jnp.concatenate([us[1:], ue])[:nb * BLOCK]
        blocks = tuple(a.reshape((nb, BLOCK) + a.shape[1:]) for a in (ta, tb, ua, ub))

        def block(carry, inp):
            j, b = inp

            def run(c):
                c, out = jax.lax.scan(interval, c, b)
                return c, out

            def hold(c):
                x, g = c
                return c, (jnp.broadcast_to(x, (BLOCK,) + x.shape), jnp.broadcast_to(g, (BLOCK,)))
            return jax.lax.cond(j * BLOCK + 1 < jnp.asarray(horizon).astype(j.dtype), run, hold, carry)

        (_, _), (xs, valid) = jax.lax.scan(block, (x0, good0), (jnp.arange(nb), blocks))
        xs, valid = xs.reshape((nb * BLOCK,) + xs.shape[2:])[:n], valid.reshape(-1)[:n]
    return jnp.concatenate([x0[None], xs], axis=0), jnp.concatenate([jnp.array([True]), valid])


def simulate(
    model: AbstractModel,
    ts: Float[Array, " N"],
    us: Float[Array, "N n_u"],
    x0: Float[Array, " n_x"],
    integrator: AbstractIntegrator = Diffrax(),
    *,
    max_abs: float = MAX_ABS,
    horizon: Int[Array, ""] | None = None,
) -> Solution:
    """Simulate ``model`` from ``x0`` over the strictly increasing grid ``ts``.

    A simulation that fails (the state turns non-finite or exceeds ``max_abs``, e.g. with
    parameters that make the model invalid) raises no error and returns finite numbers: the
    state is frozen at its last good value. Check ``sol.ok`` (``False`` if any sample failed)
    or ``sol.valid`` (per sample) before using ``sol.xs``/``sol.ys``.

    Called with concrete arrays, the shapes and the grid are checked first and a
    :class:`~diffship.errors.DataError` names what is wrong; under ``jax.jit``/``vmap`` only the
    shapes are (values are not known while tracing).

    Args:
        model: any :class:`~diffship.models.AbstractModel`.
        ts: sample times [s].
        us: inputs at the sample times, columns in ``model.input_names`` order.
        x0: initial state, in ``model.state_names`` order.
        integrator: :class:`~diffship.integrators.Diffrax` (default: diffrax RK4 tableau, one
            step per sample), :class:`~diffship.integrators.RK4` or :class:`~diffship.integrators.Tsit5`.
        max_abs: a state component beyond this magnitude counts as a blow-up.
        horizon: simulate the first ``horizon`` samples only, the state held after them
            (:func:`integrate`; a traced count, so it does not recompile).
    """
    ts = jnp.asarray(ts, dtype=jnp.float64)
    us = jnp.asarray(us, dtype=jnp.float64)
    x0 = jnp.asarray(x0, dtype=jnp.float64)
    _check_arguments(model, ts, us, x0)
    xs, valid = integrate(model.vector_field, ts, us, x0, integrator, max_abs, horizon)
    ys = jax.vmap(model.observe)(xs, us)
    return Solution(ts=ts, xs=xs, ys=ys, valid=valid)


def _check_arguments(model: AbstractModel, ts, us, x0) -> None:
    """Stop at ``ts``, ``us`` or ``x0`` that do not fit ``model`` or each other (shapes are known even while
    tracing; the order of ``ts`` is checked only when its values are concrete)."""
    inputs, states = tuple(model.input_names), tuple(model.state_names)
    if ts.ndim != 1 or ts.shape[0] < 1:
        raise DataError(f"simulate: ts must be a 1-D grid of sample times, got shape {ts.shape}.")
    n = ts.shape[0]
    if us.shape != (n, len(inputs)):
        raise DataError(f"simulate: us must have shape (len(ts), n_inputs) = ({n}, {len(inputs)}), one column per "
                        f"input of model {model.name} {list(inputs)} in that order, got shape {us.shape}; "
                        "build it with diffship.simulate.model_inputs(model, run).")
    if x0.shape != (len(states),):
        raise DataError(f"simulate: x0 must have shape ({len(states)},), one value per state of model {model.name} "
                        f"{list(states)} in that order, got shape {x0.shape}; build it with "
                        "diffship.simulate.initial_state(model, run).")
    if not isinstance(ts, jax.core.Tracer):
        t = np.asarray(ts)
        bad = ~np.isfinite(t)
        bad[1:] |= ~(np.diff(t) > 0)
        if bad.any():
            i = int(np.argmax(bad))
            what = f"ts[{i}] = {t[i]:.6g} s" + (f" follows ts[{i - 1}] = {t[i - 1]:.6g} s" if i else "")
            raise DataError(f"simulate: ts must be finite and strictly increasing, but {what}; "
                            "sort the times and drop repeated ones.")


def model_inputs(model: AbstractModel, run: Run) -> np.ndarray:
    """Inputs at the sample times, ``(n, n_u)``; an input the run lacks is the model's ``INPUT_DEFAULTS``
    constant where it declares one (zero force in a free decay), else a :class:`DataError`."""
    defaults = getattr(model, "INPUT_DEFAULTS", {})
    run.require([n for n in model.input_names if n not in defaults], f"the inputs of model {model.name}")
    return np.stack([np.asarray(run[n], dtype=np.float64) if run.has(n) else np.full(run.n, float(defaults[n]))
                     for n in model.input_names], axis=1)


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


class _Simulator(eqx.Module):
    """Compile-cache owner for one-run simulations with a given integrator."""

    integrator: AbstractIntegrator = eqx.field(static=True)

    def run(self, model, ts, us, x0):
        # plain arrays out (not a Solution): the form diffship.compiled exports between processes
        sol = simulate(model, ts, us, x0, self.integrator)
        return sol.ts, sol.xs, sol.ys, sol.valid


def simulation_request(model: AbstractModel, run: Run, x0: np.ndarray, integrator: AbstractIntegrator = Diffrax()):
    """The :mod:`diffship.compiled` request ``(owner, name, args, static)`` that :func:`simulate_run`
    runs: compile it ahead (:func:`diffship.compiled.prefetch`) and the simulation finds it."""
    args = (model, jnp.asarray(run.time), jnp.asarray(model_inputs(model, run)), jnp.asarray(x0, dtype=jnp.float64))
    return _Simulator(integrator), "run", args, {}


def simulate_run(model: AbstractModel, run: Run, x0: np.ndarray, integrator: AbstractIntegrator = Diffrax()):
    """Whole-horizon simulation of ``model`` on ``run`` from ``x0`` (compiled once per shape)."""
    owner, name, args, _ = simulation_request(model, run, x0, integrator)
    fn, _ = compiled(owner, name, args)
    return Solution(*fn(*args))
