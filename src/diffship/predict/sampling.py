r"""Parameter draws flown through a simulation in one vmapped program.

Monte-Carlo propagation of the parameter uncertainty of a fit: ``S`` parameter vectors
:math:`\theta_s \sim N(\hat\theta, \Sigma)` (:func:`draw_parameters`; draws outside a parameter's
bounds are redrawn) are simulated **together**, ``jax.vmap`` over the draws inside one compiled
program (:mod:`diffship.compiled` caches it per structure and shape), instead of one call per
draw in a Python loop:

* :func:`fly_draws`: a standard manoeuvre (zigzag, turning circle, pull-out) closed loop, with
  the rate-limited steering gear of :func:`diffship.manoeuvres.closed_loop` — the same law, time
  grid, helm rate and integrator as :func:`diffship.manoeuvres.zigzag` / ``turning_circle`` /
  ``pull_out`` build, so a draw equal to :math:`\hat\theta` reproduces the nominal run;
* :func:`simulate_draws`: an open-loop simulation with measured inputs
  (:func:`diffship.simulate.simulate`), for judging held-out runs
  (:mod:`diffship.predict.cross`).

Each returns one :class:`~diffship.data.Run` per draw (``None`` where the draw blew up), so the
metric code (:mod:`diffship.manoeuvres.imo`) is the same for the nominal run and the draws.
The draws are those of the loop it replaces (same generator and seed): the intervals agree with
the looped ones to rounding.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ..compiled import compiled
from ..data import Run
from ..errors import ModelError
from ..integrators import AbstractIntegrator
from ..manoeuvres import ScheduleLaw, ZigzagLaw, closed_loop
from ..models import AbstractModel
from ..simulate import simulate

__all__ = ["draw_parameters", "fly_draws", "manoeuvre_law", "simulate_draws"]


def draw_parameters(model: AbstractModel, names: Sequence[str], mean: np.ndarray, cov: np.ndarray, n: int,
                    seed: int = 0) -> np.ndarray:
    """``n`` draws ``(n, p)`` from N(mean, cov) of the parameters ``names``, inside their bounds.

    Cholesky factor (eigen-decomposition with negative eigenvalues clipped where the covariance is
    not positive definite); draws with a parameter outside its bounds are dropped and more drawn
    (at most 50 rounds).
    """
    names = tuple(names)
    mean = np.asarray(mean, dtype=np.float64)
    try:
        L = np.linalg.cholesky(cov + 1e-300 * np.eye(len(names)))
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(cov)
        L = V * np.sqrt(np.clip(w, 0.0, None))
    rng = np.random.default_rng(seed)
    spec = model.spec()
    lo = np.asarray([spec[k].lower for k in names])
    hi = np.asarray([spec[k].upper for k in names])
    out: list[np.ndarray] = []
    for _ in range(50):
        z = mean + rng.standard_normal((n, len(names))) @ L.T
        out.extend(z[np.all((z > lo) & (z < hi), axis=1)])
        if len(out) >= n:
            break
    return np.asarray(out[:n]).reshape(-1, len(names))


def _with(model: AbstractModel, names: tuple[str, ...], theta: Float[Array, " p"]) -> AbstractModel:
    return model.with_params({n: theta[i] for i, n in enumerate(names)})


class _Draws(eqx.Module):
    """Compile-cache owner: the vmapped programs for one integrator and free set."""

    integrator: AbstractIntegrator = eqx.field(static=True)
    names: tuple[str, ...] = eqx.field(static=True)
    delta_index: int = eqx.field(static=True, default=0)

    def fly(self, model, law, thetas, ts, x0, u_const, rate, max_rudder):
        def one(theta):
            m = _with(model, self.names, theta)
            xs, ds, valid = closed_loop(m, law, ts, x0, u_const, self.delta_index, rate, max_rudder,
                                        jnp.zeros(()), self.integrator)
            us = jnp.broadcast_to(u_const, (ts.shape[0], u_const.shape[0])).at[:, self.delta_index].set(ds)
            return jax.vmap(m.observe)(xs, us), ds, jnp.all(valid)

        return jax.vmap(one)(thetas)

    def open_loop(self, model, thetas, ts, us, x0):
        def one(theta):
            sol = simulate(_with(model, self.names, theta), ts, us, x0, self.integrator)
            return sol.ys, sol.ok

        return jax.vmap(one)(thetas)


def manoeuvre_law(model: AbstractModel, kind: str, *, rudder_deg: float, side: float, t_execute: float,
                  initial: Mapping[str, float], switch_deg: float | None = None, delay_s: float = 0.0,
                  turn_s: float | None = None):
    """The steering law :mod:`diffship.manoeuvres.drive` builds for ``kind`` (``zigzag``,
    ``turning_circle``, ``pull_out``); angles in degrees here, radians in the law."""
    f = jnp.float64
    if kind == "zigzag":
        psi0 = float(np.asarray(model.initial_state(dict(initial)))[model.state_names.index("psi")])
        sw = rudder_deg if switch_deg is None else switch_deg
        return ZigzagLaw(*(jnp.asarray(v, dtype=f) for v in (math.radians(rudder_deg), math.radians(sw), side,
                                                               t_execute, psi0, delay_s)))
    if kind == "turning_circle":
        times, levels = [t_execute], [side * rudder_deg]
    elif kind == "pull_out":
        times, levels = [t_execute, t_execute + float(turn_s)], [side * rudder_deg, 0.0]
    else:
        raise ModelError(f"no steering law for manoeuvre kind {kind!r} (zigzag, turning_circle, pull_out)")
    return ScheduleLaw(jnp.asarray(times, dtype=f), jnp.asarray(np.radians(levels), dtype=f))


def fly_draws(model: AbstractModel, names: Sequence[str], thetas: np.ndarray, law, *, initial: Mapping[str, float],
              inputs: Mapping[str, float], duration: float, dt: float, rudder_rate_deg_s: float,
              integrator: AbstractIntegrator, max_rudder_deg: float = 35.0,
              metadata: Mapping | None = None) -> list[Run | None]:
    """Fly ``law`` closed loop once per row of ``thetas`` (values of ``names``), vmapped.

    The time grid ``0, dt, ..., duration``, initial state, constant inputs, helm rate and
    saturation are those of :func:`diffship.manoeuvres.drive.zigzag` and friends. Returns a
    :class:`~diffship.data.Run` per draw with the model outputs and inputs (``None``: blew up).
    """
    names = tuple(names)
    in_names = tuple(model.input_names)
    if "delta" not in in_names:
        raise ModelError(f"model {model.name} has inputs {in_names}: a manoeuvre needs a rudder input 'delta'")
    d_idx = in_names.index("delta")
    u_const = np.array([float(inputs.get(n, 0.0)) for n in in_names], dtype=np.float64)
    x0 = np.asarray(model.initial_state(dict(initial)), dtype=np.float64)
    ts = np.arange(0.0, duration + 0.5 * dt, dt)
    if len(thetas) == 0:
        return []
    args = (model, law, jnp.asarray(thetas, dtype=jnp.float64), jnp.asarray(ts), jnp.asarray(x0),
            jnp.asarray(u_const), jnp.asarray(math.radians(rudder_rate_deg_s)), jnp.asarray(math.radians(max_rudder_deg)))
    fn, _ = compiled(_Draws(integrator, names, d_idx), "fly", args)
    ys, ds, ok = (np.asarray(a) for a in fn(*args))
    out: list[Run | None] = []
    for s in range(len(thetas)):
        if not ok[s]:
            out.append(None)
            continue
        ch = {c: ys[s, :, j] for j, c in enumerate(model.output_names)}
        for j, n in enumerate(in_names):
            ch[n] = ds[s] if j == d_idx else np.full(ts.size, u_const[j])
        out.append(Run(f"draw {s}", ts, ch, {"simulated": True, "model": model.name, **(metadata or {})},
                       check_units=False))
    return out


def simulate_draws(model: AbstractModel, names: Sequence[str], thetas: np.ndarray, ts: np.ndarray, us: np.ndarray,
                   x0: np.ndarray, integrator: AbstractIntegrator) -> tuple[np.ndarray, np.ndarray]:
    """Open-loop simulations with the measured inputs ``us`` ``(N, n_u)`` from ``x0``, one per row of
    ``thetas``; returns the outputs ``(S, N, n_y)`` and the per-draw no-blow-up flags ``(S,)``."""
    if len(thetas) == 0:
        return np.zeros((0, len(ts), len(model.output_names))), np.zeros((0,), dtype=bool)
    args = (model, jnp.asarray(thetas, dtype=jnp.float64), jnp.asarray(ts, dtype=jnp.float64),
            jnp.asarray(us, dtype=jnp.float64), jnp.asarray(x0, dtype=jnp.float64))
    fn, _ = compiled(_Draws(integrator, tuple(names)), "open_loop", args)
    ys, ok = fn(*args)
    return np.asarray(ys), np.asarray(ok)
