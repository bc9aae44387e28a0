r"""Output-error (simulation-error) fit over several runs at once.

Minimise over the free parameters θ (and optionally per-run initial states)

.. math::
    \tfrac12 \sum_{\text{runs}}\sum_k\sum_c \Big(\frac{\hat y_c(t_k;\theta) - y_c(t_k)}{s_c}\Big)^2

where :math:`\hat y` is the whole-horizon simulation from the run's initial state (no
differentiated data anywhere), ``s_c`` normalises each channel, heading errors are wrapped to
(−π, π], and the parameters live in a scaled unconstrained space (:mod:`diffship.params`).
The solver is optimistix Levenberg–Marquardt with a forward-mode Jacobian materialised once per
accepted step (:mod:`diffship.fit._lm`); simulations are batched over runs with ``jax.vmap``.

Weights (``weights=``):

* ``"noise"`` (default): fit once with ``s_c`` = signal spread of channel c, estimate each
  channel's residual RMS ``σ_c``, and refit from there with ``s_c = σ_c`` — the maximum
  likelihood weighting for white Gaussian channel noise, under which the Gauss–Newton
  covariance ``σ̂²(JᵀJ)⁻¹`` is an honest standard error.
* ``"spread"``: only the first pass.

A start whose simulation blows up is never used: all candidate starts are simulated first and
the best finite one is taken; if every start blows up a :class:`~diffship.errors.FitError`
says so.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from ..data import Run
from ..errors import FitError
from ..models._base import AbstractModel
from ..params import ParamSpec
from ..preprocess import Filter
from ..simulate import simulate
from ._lm import MaterialisedLM, result_message, rms_norm
from .problem import Batch, make_batch
from .result import FitResult

__all__ = ["fit_output_error", "channel_spread"]

#: Normalised residual assigned to every sample after a simulation blew up.
PENALTY = 1e3

_CACHE: dict = {}


def _wrap(e):
    return jnp.arctan2(jnp.sin(e), jnp.cos(e))


def channel_spread(batch: Batch) -> np.ndarray:
    """Default channel scales: standard deviation of each channel over all runs (floored)."""
    out = []
    for j in range(len(batch.channels)):
        v = batch.ys[..., j][batch.mask]
        out.append(max(float(np.std(v)), 1e-3 * float(np.max(np.abs(v)) + 1e-12), 1e-9))
    return np.asarray(out)


class _Problem(eqx.Module):
    """Static structure of a fit (hashable): what the compiled functions close over."""

    spec: ParamSpec = eqx.field(static=True)
    out_idx: tuple[int, ...] = eqx.field(static=True)
    angle: tuple[bool, ...] = eqx.field(static=True)
    x0_idx: tuple[int, ...] = eqx.field(static=True)
    solver: str = eqx.field(static=True)
    substeps: int = eqx.field(static=True)

    def residuals(self, z, args):
        model, ts, us, ys, mask, x0, x0_scale, scales = args
        n_p = len(self.spec.free_names)
        theta = self.spec.full_values(z[:n_p], model.theta())
        mdl = model.with_params(theta)
        if self.x0_idx:
            idx = jnp.asarray(self.x0_idx)
            dz = z[n_p:].reshape(x0.shape[0], len(self.x0_idx))
            x0 = x0.at[:, idx].add(dz * x0_scale)
        sol = jax.vmap(lambda t, u, x: simulate(mdl, t, u, x, solver=self.solver, substeps=self.substeps))(ts, us, x0)
        pred = sol.ys[..., jnp.asarray(self.out_idx)]
        err = pred - ys
        err = jnp.where(jnp.asarray(self.angle), _wrap(err), err)
        good = (sol.valid & mask)[..., None]
        bad = ((~sol.valid) & mask)[..., None]
        e = jnp.where(good, err / scales, 0.0) + jnp.where(bad, PENALTY, 0.0)
        return e.reshape(-1)

    def solve(self, z0, args, max_steps, rtol, atol, callback):
        solver = MaterialisedLM(rtol=rtol, atol=atol, callback=callback, norm=rms_norm, ftol=1e-9)
        sol = optx.least_squares(self.residuals, solver, z0, args=args, max_steps=max_steps, throw=False)
        r = self.residuals(sol.value, args)
        return sol.value, sol.result, sol.stats["num_steps"], r

    def jacobian(self, z, args):
        return jax.jacfwd(self.residuals)(z, args)

    def simulate_all(self, z, args):
        return self.residuals(z, args)


def _compiled(problem: _Problem, name: str, example_args, static_kw: dict):
    """jit + AOT-compile ``problem.<name>`` once per structure and shapes; returns (fn, seconds)."""
    leaves, treedef = jax.tree_util.tree_flatten(example_args)
    key = (
        problem,
        name,
        treedef,
        tuple((np.shape(x), str(jnp.asarray(x).dtype)) for x in leaves),
        tuple(sorted(static_kw.items(), key=lambda kv: kv[0])),
    )
    if key in _CACHE:
        return _CACHE[key], 0.0
    t0 = time.perf_counter()
    fn = jax.jit(lambda *a: getattr(problem, name)(*a, **static_kw)).lower(*example_args).compile()
    _CACHE[key] = fn
    return fn, time.perf_counter() - t0


def fit_output_error(
    model: AbstractModel,
    runs: Sequence[Run],
    *,
    spec: ParamSpec | None = None,
    starts: Sequence[Mapping[str, float]] = (),
    channels: Sequence[str] | None = None,
    estimate_x0: Sequence[str] = (),
    weights: str = "noise",
    channel_scales: Mapping[str, float] | None = None,
    solver: str = "rk4",
    substeps: int = 1,
    max_steps: int = 200,
    rtol: float = 1e-6,
    atol: float = 1e-6,
    flt: Filter = Filter(),
    choose: str = "best",
    warmup: float = 0.25,
    progress: Callable[[str], None] | None = None,
) -> FitResult:
    """Fit ``model`` to ``runs`` by output error.

    Args:
        model: model whose current parameter values are the defaults of the fit.
        runs: training runs (any lengths and sample rates).
        spec: free/fixed flags, bounds and scales (default ``model.spec()``); its values are
            the fixed values and the first start.
        starts: further candidate starts (e.g. the equation-error estimate); the one whose
            simulation stays finite with the lowest cost is used.
        channels: measured channels to fit (default: every model output present in all runs
            except absolute positions).
        estimate_x0: state names whose initial values are estimated per run (offsets from
            the measured values).
        weights: ``"noise"`` (two passes, noise-normalised) or ``"spread"``.
        channel_scales: fixed per-channel normalisation (overrides ``weights``).
        solver, substeps: integrator (:func:`diffship.simulate.simulate`).
        max_steps, rtol, atol: Levenberg–Marquardt limits and tolerances.
        flt: filter used to take initial states from the data.
        choose: ``"best"`` takes the finite start with the lowest cost; ``"first"`` the first
            start (the spec's values, then ``starts`` in order) whose simulation stays finite.
        warmup: fraction of every run fitted first (growing horizon) when that is at least
            200 samples; ``0`` fits the whole runs from the start.
        progress: optional ``progress(text)`` for people watching.
    """
    say = progress or (lambda s: None)
    spec = spec or model.spec()
    model = model.with_params(spec.values())
    batch = make_batch(model, runs, channels, flt)
    n_p = len(spec.free_names)
    if n_p == 0:
        raise FitError("no free parameters: free at least one (remove it from --fix)")
    x0_idx = tuple(model.state_names.index(s) for s in estimate_x0)
    problem = _Problem(
        spec=spec.structural(),
        out_idx=tuple(model.output_names.index(c) for c in batch.channels),
        angle=tuple(c in model.angle_outputs for c in batch.channels),
        x0_idx=x0_idx,
        solver=solver,
        substeps=int(substeps),
    )
    spread = channel_spread(batch)
    scales = np.asarray([channel_scales[c] for c in batch.channels]) if channel_scales else spread
    state_channel = getattr(model, "STATE_CHANNEL", {})

    def _x0_scale(state):
        c = state if state in batch.channels else state_channel.get(state)
        return spread[batch.channels.index(c)] if c in batch.channels else 1.0

    x0_scale = np.asarray([_x0_scale(s) for s in estimate_x0], dtype=np.float64)

    def args_with(sc):
        return (model, jnp.asarray(batch.ts), jnp.asarray(batch.us), jnp.asarray(batch.ys), jnp.asarray(batch.mask),
                jnp.asarray(batch.x0), jnp.asarray(x0_scale), jnp.asarray(sc, dtype=jnp.float64))

    args = args_with(scales)
    n_x0 = len(x0_idx) * len(runs)
    messages: list[str] = []

    # -- choose a start that does not blow up ------------------------------------------
    candidates = [("model/--init values", spec.values())] + [
        (f"start {i + 1}", {**spec.values(), **{k: v for k, v in s.items() if k in spec.free_names}})
        for i, s in enumerate(starts)
    ]
    z_example = jnp.zeros((n_p + n_x0,))
    res_fn, c_res = _compiled(problem, "residuals", (z_example, args), {})
    best = None
    for label, vals in candidates:
        vals, notes = spec.nudged(vals)
        messages.extend(f"start '{label}': {n}" for n in notes)
        try:
            z = np.concatenate([spec.to_z(vals), np.zeros(n_x0)])
        except Exception as exc:  # start outside bounds
            messages.append(f"start '{label}' skipped: {exc}")
            continue
        r = np.asarray(res_fn(jnp.asarray(z), args))
        cost = 0.5 * float(np.sum(r * r))
        blew_up = np.any(np.abs(r) >= PENALTY) or not math.isfinite(cost)
        if blew_up:
            messages.append(f"start '{label}' rejected: its simulation blows up")
            continue
        if best is None or cost < best[2]:
            best = (label, z, cost)
        if choose == "first":
            break
    if best is None:
        raise FitError(
            f"model {model.name} diverges from every start ({len(candidates)} tried) on runs "
            f"{', '.join(batch.names)}; give a better start with --init NAME=VALUE or fix unstable parameters"
        )
    label, z0, _ = best
    messages.append(f"started from {label}")

    # -- Levenberg–Marquardt -------------------------------------------------------------
    t_steps = [0, time.perf_counter()]

    def cb(cost):
        t_steps[0] += 1
        if time.perf_counter() - t_steps[1] > 2.0:
            t_steps[1] = time.perf_counter()
            say(f"  LM step {t_steps[0]}: cost {float(cost):.6g}")

    kw = dict(max_steps=max_steps, rtol=rtol, atol=atol, callback=cb if progress else None)
    n_full = batch.ts.shape[1]
    n_warm = int(warmup * n_full) if warmup and warmup < 1 and warmup * n_full >= 200 else 0
    say(f"output error: compiling the fit of {model.name} ({n_p} parameters, {len(runs)} runs, "
        f"{batch.n_residuals} residuals)...")
    solve_fn, c_solve = _compiled(problem, "solve", (jnp.asarray(z0), args), kw)
    compile_s = c_res + c_solve
    passes, steps_per_pass = [], []
    t0 = time.perf_counter()
    z = jnp.asarray(z0)
    noise_pass = weights == "noise" and not channel_scales
    if n_warm:
        # Growing horizon: converge on the first part of every run (cheap steps, and a short
        # horizon keeps LM out of the local minima of long simulations), then the whole runs.
        args_w = args[:1] + tuple(a[:, :n_warm] for a in args[1:5]) + args[5:]
        t_c = time.perf_counter()
        solve_w, c_w = _compiled(problem, "solve", (z, args_w), kw)
        compile_s += c_w
        t0 += time.perf_counter() - t_c
        zw, result, steps, rw = solve_w(z, args_w)
        passes.append(result)
        steps_per_pass.append(int(steps))
        r_full = np.asarray(res_fn(zw, args))
        if not np.any(np.abs(r_full) >= PENALTY):
            z = zw
            if noise_pass:
                sigma = _channel_rms(np.asarray(rw), batch.mask[:, :n_warm], np.asarray(scales))
                scales = np.maximum(sigma, 1e-6 * spread)
                args = args_with(scales)
                noise_pass = False
        else:
            messages.append(f"the fit on the first {n_warm} samples blows up on the whole runs; restarted")
        say(f"output error: first {n_warm} samples of each run fitted in {steps_per_pass[-1]} steps; now the whole runs")
    z, result, steps, r = solve_fn(z, args)
    r = np.asarray(r)
    passes.append(result)
    steps_per_pass.append(int(steps))
    if noise_pass:
        # floor: on noise-free data the residuals are round-off, which must not set the weights
        sigma = np.maximum(_channel_rms(r, batch.mask, np.asarray(scales)), 1e-6 * spread)
        args = args_with(sigma)
        scales = sigma
        z, result, steps, r = solve_fn(z, args)
        r = np.asarray(r)
        passes.append(result)
        steps_per_pass.append(int(steps))
    iterations = sum(steps_per_pass)
    jax.block_until_ready(z)
    fit_s = time.perf_counter() - t0

    # -- covariance from the final Jacobian ----------------------------------------------
    jac_fn, c_jac = _compiled(problem, "jacobian", (z, args), {})
    compile_s += c_jac
    J = np.asarray(jac_fn(z, args))
    m_res = batch.n_residuals
    dof = max(m_res - (n_p + n_x0), 1)
    s2 = float(np.sum(r * r)) / dof
    z = np.asarray(z)
    cov_z, rank_msg = _covariance(J, s2)
    if rank_msg:
        messages.append(rank_msg)
    dth = spec.dtheta_dz(z[:n_p])
    cov = cov_z[:n_p, :n_p] * np.outer(dth, dth)
    theta = np.asarray(spec.full_values(jnp.asarray(z[:n_p]), model.theta()))
    values = {n: float(theta[i]) for i, n in enumerate(model.param_names)}
    if hasattr(model, "canonical"):
        swapped = model.canonical(values)
        if swapped != values:
            perm = [spec.free_names.index(n) for n in _swap_names(values, swapped, spec.free_names)]
            cov = cov[np.ix_(perm, perm)]
            values = swapped
    stderr = {n: float(math.sqrt(max(cov[i, i], 0.0))) for i, n in enumerate(spec.free_names)}
    fitted = model.with_params(values)
    x0_fit = np.asarray(batch.x0).copy()
    if x0_idx:
        x0_fit[:, list(x0_idx)] += z[n_p:].reshape(len(runs), len(x0_idx)) * x0_scale
    noise = _channel_rms(r, batch.mask, np.asarray(scales))
    converged = passes[-1] == optx.RESULTS.successful
    status = "converged" if converged else result_message(passes[-1])
    if np.any(np.abs(r) >= PENALTY):
        converged, status = False, "the simulation blows up at the final parameters"
    say(f"output error: {status} after {iterations} steps in {fit_s:.2f} s (compile {compile_s:.2f} s)")
    return FitResult(
        method="output_error",
        model=fitted,
        params=values,
        stderr=stderr,
        free=spec.free_names,
        converged=bool(converged),
        status=status,
        iterations=iterations,
        cost=0.5 * float(np.sum(r * r)),
        fit_seconds=fit_s,
        compile_seconds=compile_s,
        channels=batch.channels,
        channel_scales={c: float(s) for c, s in zip(batch.channels, scales)},
        noise_std={c: float(s) for c, s in zip(batch.channels, noise)},
        initial_states=tuple(x0_fit),
        run_names=batch.names,
        covariance=cov,
        messages=tuple(messages),
        info={"weights": weights, "solver": solver, "substeps": substeps, "residual_variance": s2,
              "n_residuals": m_res, "steps_per_pass": tuple(steps_per_pass), "warmup_samples": n_warm, "estimate_x0": tuple(estimate_x0)},
    )


def _swap_names(old, new, free):
    """Permutation of free names after a canonical relabelling (e.g. Nomoto T1 <-> T2)."""
    out = []
    for n in free:
        match = [m for m in free if old[m] == new[n]]
        out.append(match[0] if match else n)
    return out


def _channel_rms(r: np.ndarray, mask: np.ndarray, scales: np.ndarray) -> np.ndarray:
    n_c = len(scales)
    e = r.reshape(mask.shape + (n_c,))
    m = mask
    out = []
    for j in range(n_c):
        v = e[..., j][m] * scales[j]
        out.append(max(float(np.sqrt(np.mean(v * v))), 1e-12))
    return np.asarray(out)


def _covariance(J: np.ndarray, s2: float) -> tuple[np.ndarray, str]:
    """``s²(JᵀJ)⁻¹`` via SVD; flags (near) rank deficiency instead of returning garbage."""
    u, sv, vt = np.linalg.svd(J, full_matrices=False)
    tol = sv[0] * max(J.shape) * np.finfo(float).eps * 1e3 if sv.size else 0.0
    keep = sv > tol
    inv = (vt[keep].T / sv[keep] ** 2) @ vt[keep]
    msg = ""
    if not np.all(keep):
        inv = inv + np.diag(np.where(np.any(np.abs(vt[~keep]) > 0.3, axis=0), np.inf, 0.0))
        msg = "some parameters are not identifiable from these runs (Jacobian rank deficient): their standard errors are infinite"
    return s2 * inv, msg
