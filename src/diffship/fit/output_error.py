r"""Output-error (simulation-error) fit over several runs at once.

Minimise over the free parameters θ (and optionally per-run initial states)

.. math::
    \tfrac12 \sum_{\text{runs}}\sum_k\sum_c \Big(\frac{\hat y_c(t_k;\theta) - y_c(t_k)}{s_c}\Big)^2

where :math:`\hat y` is the whole-horizon simulation from the run's initial state (no
differentiated data anywhere), ``s_c`` normalises each channel, heading errors are wrapped to
(−π, π], and the parameters live in a scaled unconstrained space (:mod:`diffship.params`).
The residual, Jacobian and solver are the one output-error kernel (:mod:`diffship.fit.kernel`:
optimistix Levenberg–Marquardt with a forward-mode Jacobian materialised once per accepted step,
simulations batched over runs with ``jax.vmap``); this module chooses the start, the weights and
the horizon, and turns the optimum into a :class:`~diffship.fit.FitResult`. Options are grouped
in :class:`OutputErrorOptions`.

Weights (``OutputErrorOptions.weights``):

* ``"noise"`` (default): fit once with ``s_c`` = signal spread of channel c, estimate each
  channel's residual RMS ``σ_c``, and refit from there with ``s_c = σ_c`` — the maximum
  likelihood weighting for white Gaussian channel noise, under which the Gauss–Newton
  covariance ``σ̂²(JᵀJ)⁻¹`` is an honest standard error.
* ``"spread"``: only the first pass.

Priors (``OutputErrorOptions.priors`` and ``reference_priors``, :mod:`diffship.fit.priors`)
add one residual row per prior, so the optimum is the MAP estimate and the standard errors are
posterior ones; by default a model with a reference set (MMG KVLCC2, USV, BlueROV2) carries
its reference values as loose priors when the fixed particulars are the reference vessel's.

A start whose simulation blows up is never used: all candidate starts are simulated first and
the best finite one is taken; if every start blows up a :class:`~diffship.errors.FitError`
says so.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Mapping, Sequence

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from .. import compiled as compiled_programs
from ..data import Run
from ..errors import FitError
from ..integrators import AbstractIntegrator, Diffrax
from ..models import AbstractModel
from ..params import ParamSpec
from ..preprocess import Filter
from ._lm import result_message
from .covariance import covariance, relabelled
from .identifiability import identifiability, per_scale_columns
from .input_noise import meat_request, measured_input_meat
from .kernel import PENALTY, Kernel, kernel_data
from .priors import Priors, default_priors, prior_arrays, prior_table
from .problem import Batch, make_batch
from .result import FitResult

__all__ = ["OutputErrorOptions", "bound_escape", "channel_rms", "channel_spread", "correlation_time", "fit_output_error", "fit_priors",
           "x0_scales"]


@dataclasses.dataclass(frozen=True)
class OutputErrorOptions:
    """How an output-error fit is run.

    Attributes:
        estimate_x0: state names whose initial values are estimated per run (offsets from the
            measured values); ``()`` takes every initial state from the data.
        weights: ``"noise"`` (two passes, noise-normalised) or ``"spread"`` (one pass).
        channel_scales: fixed per-channel normalisation (overrides ``weights``).
        integrator: how simulations advance between samples (:mod:`diffship.integrators`).
        max_steps, rtol, atol: Levenberg–Marquardt limits and tolerances.
        gntol: a small step or a stalled cost ends the solve only when the Gauss–Newton step
            from there is shorter than ``gntol`` standard errors, ``‖J δ_GN‖/σ̂ < gntol``
            (:mod:`diffship.fit._lm`); otherwise LM goes on up to ``max_steps``. ``inf``: the
            plain step/cost tests.
        flt: filter used to take initial states from the data.
        choose: ``"best"`` takes the finite start with the lowest cost; ``"first"`` the first
            start (the spec's values, then ``starts`` in order) whose simulation stays finite.
        warmup: fraction of every run fitted first (growing horizon) when that is at least
            200 samples; ``0`` fits the whole runs from the start.
        priors: explicit priors (:class:`~diffship.fit.priors.Priors`), added to (and replacing)
            the reference ones.
        reference_priors: use the model's reference set as priors where it applies
            (:func:`~diffship.fit.priors.default_priors`); ``False`` is ``--no-prior``.
        prior_rel_sd: relative standard deviation of the reference priors.
        effective_samples: with priors, weight each channel's data by its effective sample size
            (:func:`correlation_time`): autocorrelated residuals carry less information than
            their count says, and must not outvote a prior. No effect without priors.
    """

    estimate_x0: tuple[str, ...] = ()
    weights: str = "noise"
    channel_scales: Mapping[str, float] | None = None
    integrator: AbstractIntegrator = Diffrax()
    max_steps: int = 200
    rtol: float = 1e-6
    atol: float = 1e-6
    gntol: float = 0.05
    flt: Filter = Filter()
    choose: str = "best"
    warmup: float = 0.25
    priors: Priors | None = None
    reference_priors: bool = True
    prior_rel_sd: float = 0.5
    effective_samples: bool = True

    def __post_init__(self):
        object.__setattr__(self, "estimate_x0", tuple(self.estimate_x0))
        if self.weights not in ("noise", "spread"):
            raise FitError(f"weights must be 'noise' or 'spread', got {self.weights!r}")
        if not self.gntol > 0:
            raise FitError(f"gntol must be a positive number of standard errors, got {self.gntol!r}")
        if self.choose not in ("best", "first"):
            raise FitError(f"choose must be 'best' or 'first', got {self.choose!r}")


def channel_spread(batch: Batch) -> np.ndarray:
    """Default channel scales: standard deviation of each channel over all runs (floored)."""
    out = []
    for j in range(len(batch.channels)):
        v = batch.ys[..., j][batch.mask]
        out.append(max(float(np.std(v)), 1e-3 * float(np.max(np.abs(v)) + 1e-12), 1e-9))
    return np.asarray(out)


def channel_rms(r: np.ndarray, mask: np.ndarray, scales: np.ndarray) -> np.ndarray:
    """Per-channel RMS (model units) of normalised residuals ``r`` over the unmasked samples."""
    e = np.asarray(r).reshape(mask.shape + (len(scales),))
    return np.asarray([max(float(np.sqrt(np.mean((e[..., j][mask] * s) ** 2))), 1e-12)
                       for j, s in enumerate(scales)])


def correlation_time(r: np.ndarray, mask: np.ndarray, n_channels: int, max_lag: int = 400) -> np.ndarray:
    r"""Integrated autocorrelation time (in samples) of each channel's residuals, pooled over runs.

    :math:`\tau_c = 1 + 2\sum_{k\ge1}\rho_c(k)`, summed up to the first lag where the pooled
    autocorrelation falls below zero (the initial positive sequence), at most ``max_lag`` or a
    quarter of the shortest run. ``N/τ`` is the effective number of independent samples: white
    residuals give τ ≈ 1; residuals dominated by a slowly varying model error give τ ≫ 1.
    """
    e = np.asarray(r).reshape(mask.shape + (n_channels,))
    n_min = int(np.min(np.sum(mask, axis=1)))
    K = max(1, min(max_lag, n_min // 4))
    out = []
    for c in range(n_channels):
        num = np.zeros(K + 1)
        den = 0.0
        for i in range(e.shape[0]):
            x = e[i, mask[i], c]
            x = x - x.mean()
            den += float(x @ x)
            for k in range(1, K + 1):
                num[k] += float(x[:-k] @ x[k:])
        rho = num[1:] / den if den > 0 else np.zeros(K)
        neg = np.flatnonzero(rho < 0)
        rho = rho[: neg[0]] if neg.size else rho
        out.append(max(1.0, 1.0 + 2.0 * float(np.sum(rho))))
    return np.asarray(out)


def x0_scales(model: AbstractModel, batch: Batch, states: Sequence[str]) -> np.ndarray:
    """Scale of each estimated initial-state offset: the spread of the channel it shows up in."""
    spread = channel_spread(batch)
    state_channel = getattr(model, "STATE_CHANNEL", {})

    def one(state):
        c = state if state in batch.channels else state_channel.get(state)
        return spread[batch.channels.index(c)] if c in batch.channels else 1.0

    return np.asarray([one(s) for s in states], dtype=np.float64)


def fit_priors(model: AbstractModel, spec: ParamSpec, options: OutputErrorOptions) -> tuple[Priors, str]:
    """The priors of a fit (reference set unless turned off, merged with ``options.priors``) and a
    one-line note for the report; shared by every estimator built on the kernel."""
    o = options
    priors, note = (default_priors(model, spec, o.prior_rel_sd) if o.reference_priors
                    else (Priors({}, "none"), "priors from the reference set turned off (--no-prior)"))
    priors = priors.merged(o.priors)
    if o.priors is not None and len(o.priors):
        note += f"; {len(o.priors)} prior(s) from {o.priors.source}"
    return priors, note


def bound_escape(spec: ParamSpec, z: np.ndarray, r: np.ndarray, J: np.ndarray, n_p: int,
                 gntol: float) -> tuple[np.ndarray, float] | None:
    r"""The Gauss–Newton step in the parameters θ (not the fit variables ``z``) where it is long.

    A bounded parameter lives in a log-mapped ``z`` (:mod:`diffship.params`): on its bound,
    :math:`\partial\theta/\partial z \to 0`, so the Jacobian in ``z`` loses that column and LM stops
    ("converged": the step in ``z`` is short) even where the cost falls steeply as the parameter
    leaves the bound. In θ/scale the step :math:`\delta = -J_\theta^{+} r` sees it: if its marginal
    length over the parameters exceeds ``gntol`` standard errors (:mod:`diffship.fit._lm`), the
    point ``θ + δ`` (kept 10⁻³ scales inside the bounds; initial-state unknowns moved by their part
    of the step) is returned with that length, else ``None``. Measured on the MMG KVLCC2 zigzag
    (``benchmarks/kvlcc2_second_minimum.py``): J'_z pinned at 10⁻⁶ on its bound 0, step 1.26 se
    long, pointing to the optimum (J'_z 0.011) that LM with J'_z unbounded reaches from there.
    """
    n = J.shape[1]
    col = per_scale_columns(spec, z, n)
    Jt = J * col
    m = int(np.sum(r != 0))
    s2 = float(r @ r) / max(m - n, 1)
    step, *_ = np.linalg.lstsq(Jt, -r, rcond=None)
    cov = np.linalg.pinv(Jt.T @ Jt, hermitian=True)[:n_p, :n_p]
    length = math.sqrt(max(float(step[:n_p] @ np.linalg.pinv(cov, hermitian=True) @ step[:n_p]) / s2, 0.0))
    if not length > gntol:
        return None
    names = spec.free_names
    theta = np.asarray(spec.from_z(jnp.asarray(z[:n_p])))
    new = {}
    for i, name in enumerate(names):
        p = spec[name]
        v = theta[i] + step[i] * p.scale
        new[name] = float(np.clip(v, p.lower + 1e-3 * p.scale, p.upper - 1e-3 * p.scale))
    try:
        z_theta = spec.to_z(new)
    except Exception:  # pragma: no cover - clipped inside the bounds
        return None
    return np.concatenate([z_theta, z[n_p:] + step[n_p:] / col[n_p:]]), length


def fit_output_error(
    model: AbstractModel,
    runs: Sequence[Run],
    *,
    spec: ParamSpec | None = None,
    starts: Sequence[Mapping[str, float]] | Mapping[str, Mapping[str, float]] = (),
    channels: Sequence[str] | None = None,
    options: OutputErrorOptions = OutputErrorOptions(),
    progress: Callable[[str], None] | None = None,
) -> FitResult:
    """Fit ``model`` to ``runs`` by output error.

    Args:
        model: model whose current parameter values are the defaults of the fit.
        runs: training runs (any lengths and sample rates).
        spec: free/fixed flags, bounds and scales (default ``model.spec()``); its values are
            the fixed values and the first start.
        starts: further candidate starts (e.g. the equation-error estimate), as a sequence or
            as ``{label: values}`` (the label is what the report says it started from); see
            ``options.choose``.
        channels: measured channels to fit (default: every model output present in all runs
            except absolute positions).
        options: see :class:`OutputErrorOptions`.
        progress: optional ``progress(text)`` for people watching.
    """
    o = options
    say = progress or (lambda s: None)
    programs = compiled_programs.cache_size(), compiled_programs.loaded()
    spec = spec or model.spec()
    model = model.with_params(spec.values())
    batch = make_batch(model, runs, channels, o.flt)
    n_p = len(spec.free_names)
    if n_p == 0:
        raise FitError("no free parameters: free at least one (remove it from --fix)")
    unknown = [s for s in o.estimate_x0 if s not in model.state_names]
    if unknown:
        raise FitError(f"estimate_x0: {', '.join(unknown)} are not states of model {model.name} "
                       f"({', '.join(model.state_names)})")
    kernel = Kernel(
        spec=spec.structural(),
        out_idx=tuple(model.output_names.index(c) for c in batch.channels),
        angle=tuple(c in model.angle_outputs for c in batch.channels),
        x0_idx=tuple(model.state_names.index(s) for s in o.estimate_x0),
        integrator=o.integrator,
    )
    spread = channel_spread(batch)
    scales = np.asarray([o.channel_scales[c] for c in batch.channels]) if o.channel_scales else spread
    x0_scale = x0_scales(model, batch, o.estimate_x0)
    messages: list[str] = []
    priors, prior_note = fit_priors(model, spec, o)
    p_mean, p_w = prior_arrays(priors, spec)
    messages.append(prior_note)
    data = kernel_data(model, batch.ts, batch.us, batch.ys, batch.mask, batch.x0, scales, x0_scale=x0_scale,
                       prior_mean=p_mean, prior_w=p_w)
    n_x0 = len(kernel.x0_idx) * len(runs)

    # -- choose a start that does not blow up ------------------------------------------
    named = starts.items() if isinstance(starts, Mapping) else ((f"start {i + 1}", s) for i, s in enumerate(starts))
    candidates = [("the model's values (with --init)", spec.values())] + [
        (label, {**spec.values(), **{k: v for k, v in s.items() if k in spec.free_names}}) for label, s in named
    ]
    # -- every program this fit needs, compiled at once (in parallel from an empty cache) ----
    lm = dict(max_steps=o.max_steps, rtol=o.rtol, atol=o.atol, gntol=float(o.gntol))
    n_full = batch.ts.shape[1]
    n_warm = int(o.warmup * n_full) if o.warmup and o.warmup < 1 and o.warmup * n_full >= 200 else 0
    z_shape = np.zeros(n_p + n_x0)
    say(f"output error: compiling the fit of {model.name} ({n_p} parameters, {len(runs)} runs, "
        f"{batch.n_residuals} residuals, {o.integrator.describe()})...")
    # the full-horizon solve also returns the Jacobian at its solution (for the covariance)
    # (and the input-noise covariance term's program, where the measured inputs are noisy)
    meat = meat_request(kernel, data, int(batch.mask.size) * len(batch.channels), n_p + n_x0)
    (res_fn, solve_fn, *solve_w), compile_s = kernel.compiled_many(
        [("residuals", z_shape, data, {}), ("solve", z_shape, data, {"jacobian": True, **lm})]
        + ([("solve", z_shape, data.head(n_warm), lm)] if n_warm else []), extra=[meat] if meat else [])
    best = None
    for label, vals in candidates:
        vals, notes = spec.nudged(vals)
        messages.extend(f"start '{label}': {n}" for n in notes)
        try:
            z = np.concatenate([spec.to_z(vals), np.zeros(n_x0)])
        except Exception as exc:  # start outside bounds
            messages.append(f"start '{label}' skipped: {exc}")
            continue
        r = np.asarray(res_fn(jnp.asarray(z), data))
        cost = 0.5 * float(np.sum(r * r))
        if np.any(np.abs(kernel.split(r, data)[0]) >= PENALTY) or not math.isfinite(cost):
            messages.append(f"start '{label}' rejected: its simulation blows up")
            continue
        if best is None or cost < best[2]:
            best = (label, z, cost)
        if o.choose == "first":
            break
    if best is None:
        raise FitError(
            f"model {model.name} diverges from every start ({len(candidates)} tried) on runs "
            f"{', '.join(batch.names)}; give a better start with --init NAME=VALUE or fix unstable parameters"
        )
    label, z, _ = best
    messages.append(f"started from {label}")

    # -- Levenberg–Marquardt -------------------------------------------------------------
    passes, steps_per_pass, last_jac = [], [], []
    noise_pass = o.weights == "noise" and not o.channel_scales
    def run_solve(fn, z, d):
        z, result, steps, r, *jac = fn(jnp.asarray(z), d)
        passes.append(result)
        steps_per_pass.append(int(steps))
        last_jac[:] = jac
        return z, np.asarray(kernel.split(np.asarray(r), d)[0])

    taus: list[np.ndarray] = []
    t0 = time.perf_counter()
    if n_warm:
        # Growing horizon: converge on the first part of every run (cheap steps, and a short
        # horizon keeps LM out of the local minima of long simulations), then the whole runs.
        data_w = data.head(n_warm)
        zw, rw = run_solve(solve_w[0], z, data_w)
        r_full = kernel.split(np.asarray(res_fn(zw, data)), data)[0]
        if not np.any(np.abs(r_full) >= PENALTY):
            z = zw
            if noise_pass:
                sigma = channel_rms(rw, batch.mask[:, :n_warm], scales)
                scales = np.maximum(sigma, 1e-6 * spread)
                data = data.replace(scales=jnp.asarray(scales))
                noise_pass = False
        else:
            messages.append(f"the fit on the first {n_warm} samples blows up on the whole runs; restarted")
        say(f"output error: first {n_warm} samples of each run fitted in {steps_per_pass[-1]} steps; now the whole runs")
    z, r = run_solve(solve_fn, z, data)
    if noise_pass:
        # floor: on noise-free data the residuals are round-off, which must not set the weights
        scales = np.maximum(channel_rms(r, batch.mask, scales), 1e-6 * spread)
        data = data.replace(scales=jnp.asarray(scales))
        z, r = run_solve(solve_fn, z, data)
    if data.n_prior and o.effective_samples and o.weights == "noise" and not o.channel_scales:
        # data weight of an effective sample size N/τ_c (τ from the noise-weighted residuals)
        taus.append(correlation_time(r, batch.mask, len(batch.channels)))
        scales = scales * np.sqrt(taus[-1])
        data = data.replace(scales=jnp.asarray(scales))
        z, r = run_solve(solve_fn, z, data)
    # -- a parameter pinned on a log-mapped bound: LM again from the Gauss–Newton step in θ ------------
    if last_jac and math.isfinite(o.gntol):
        for _ in range(2):
            r_old = np.asarray(res_fn(jnp.asarray(z), data))
            moved = bound_escape(spec, np.asarray(z), r_old, np.asarray(last_jac[0]), n_p, o.gntol)
            if moved is None:
                break
            z_new, length = moved
            # the initial-state part of the step is the most nonlinear: also try the parameters' part alone
            z_alt = np.concatenate([z_new[:n_p], np.asarray(z)[n_p:]])
            r_new, r_alt = (np.asarray(res_fn(jnp.asarray(c), data)) for c in (z_new, z_alt))
            if np.all(np.isfinite(r_alt)) and not (r_new @ r_new <= r_alt @ r_alt):
                z_new = z_alt
            kept = (z, r, list(passes), list(last_jac))
            z_try, r_try = run_solve(solve_fn, z_new, data)
            r_full = np.asarray(res_fn(jnp.asarray(z_try), data))
            if (np.all(np.isfinite(r_full)) and r_full @ r_full < r_old @ r_old
                    and not np.any(np.abs(kernel.split(r_full, data)[0]) >= PENALTY)):
                messages.append(f"LM stopped with the Gauss–Newton step in the parameters {length:.2g} standard "
                                f"errors long (a parameter on a bound); LM again from that step: cost "
                                f"{0.5 * float(r_old @ r_old):.6g} → {0.5 * float(r_full @ r_full):.6g}")
                z, r = z_try, r_try
            else:  # keep the point LM stopped at (the steps tried are counted)
                z, r, passes[:], last_jac[:] = kept[0], kept[1], kept[2], kept[3]
                break
    jax.block_until_ready(z)
    fit_s = time.perf_counter() - t0
    iterations = sum(steps_per_pass)

    # -- covariance from the final Jacobian (formed by the last accepted LM step) ---------
    z = np.asarray(z)
    # Jacobian with respect to θ/scale (not the bounded fit variable z: a parameter drifting
    # towards a log-mapped bound would otherwise hide the directions the data cannot see)
    col = per_scale_columns(spec, z, n_p + n_x0)
    J, J_prior = kernel.split(np.asarray(last_jac[0]) * col, data)
    # coloured residuals get the HAC sandwich; noise on measured inputs is propagated (errors in variables)
    meat, sigma_u, c = measured_input_meat(kernel, z, data, J, batch.mask, model.input_names)
    compile_s += c
    cov_all = covariance(J, r, dof=batch.n_residuals - J.shape[1], involvement=0.05, kind="auto", mask=batch.mask,
                         n_channels=len(batch.channels), runs=batch.names, channels=batch.channels,
                         input_meat=meat, input_noise=sigma_u)  # padded samples are not data
    messages.append(cov_all.describe())
    cov_info = cov_all.info()
    if data.n_prior:
        # posterior: (J_dᵀJ_d/σ̂² + J_pᵀJ_p)⁻¹ — prior rows are unit-variance by construction
        # (with effective-sample weighting the scales already are σ_c·√τ_c: σ̂² = 1)
        s2 = 1.0 if taus else cov_all.residual_variance
        cov_all = dataclasses.replace(
            covariance(np.vstack([J / math.sqrt(s2), J_prior]), r, variance=1.0, involvement=0.05,
                       input_meat=None if meat is None else meat / s2, input_noise=sigma_u),
            residual_variance=s2)
        cov_info["covariance"] = "posterior (white data rows)" + ("+inputs" if meat is not None else "")
    if not cov_all.full_rank:
        names = [*spec.free_names, *(f"{s}(0) of run {n}" for n in batch.names for s in o.estimate_x0)]
        messages.append("not identifiable from these runs (Jacobian rank deficient; standard errors infinite): "
                        + ", ".join(names[i] for i in cov_all.unidentifiable))
    scale = np.asarray([spec[n].scale for n in spec.free_names])
    cov = cov_all.matrix[:n_p, :n_p] * np.outer(scale, scale)
    theta = np.asarray(spec.full_values(jnp.asarray(z[:n_p]), model.theta()))
    values = {n: float(theta[i]) for i, n in enumerate(model.param_names)}
    swapped = model.canonical(values)
    if swapped != values:
        cov = relabelled(cov, values, swapped, spec.free_names)
        values = swapped
    stderr = {n: float(math.sqrt(cov[i, i])) if cov[i, i] >= 0 else math.nan for i, n in enumerate(spec.free_names)}
    x0_fit = np.asarray(kernel.initial_states(jnp.asarray(z), data))
    start_vals = {n: float(v) for n, v in zip(spec.free_names, spec.from_z(jnp.asarray(best[1][:n_p])))}
    s2_data = 1.0 if taus else cov_all.residual_variance
    ident = identifiability(J[:, :n_p] / math.sqrt(s2_data), spec, values, cov,
                            start=start_vals, start_label=label, priors=priors,
                            reference={p.name: p.value for p in type(model).PARAMS})
    messages.extend(ident.warnings)
    prior_info = prior_table(priors, values, stderr, spec.free_names)
    noise = channel_rms(r, batch.mask, scales)
    prior_rows = np.asarray(kernel.split(np.asarray(kernel.call("residuals", z, data)), data)[1])
    converged = passes[-1] == optx.RESULTS.successful
    status = "converged" if converged else result_message(passes[-1])
    if np.any(np.abs(r) >= PENALTY):
        converged, status = False, "the simulation blows up at the final parameters"
    new = compiled_programs.cache_size() - programs[0]
    loaded = compiled_programs.loaded() - programs[1]
    how = (f"{new} program(s) compiled, {loaded} of them loaded from the persistent cache" if new
           else "compiled programs reused from this process")
    say(f"output error: {status} after {iterations} steps in {fit_s:.2f} s (compile {compile_s:.2f} s: {how})")
    return FitResult(
        method="output_error",
        model=model.with_params(values),
        params=values,
        stderr=stderr,
        free=spec.free_names,
        converged=bool(converged),
        status=status,
        iterations=iterations,
        cost=0.5 * float(np.sum(r * r)),  # data rows only (the prior part is info["prior_cost"])
        fit_seconds=fit_s,
        compile_seconds=compile_s,
        channels=batch.channels,
        channel_scales={c: float(s) for c, s in zip(batch.channels, scales)},
        noise_std={c: float(s) for c, s in zip(batch.channels, noise)},
        initial_states=tuple(x0_fit),
        run_names=batch.names,
        covariance=cov,
        integrator=o.integrator,
        messages=tuple(messages),
        info={"weights": o.weights, "integrator": o.integrator.describe(), "programs": how,
              "residual_variance": cov_all.residual_variance, "n_residuals": batch.n_residuals,
              "steps_per_pass": tuple(steps_per_pass), "warmup_samples": n_warm, "estimate_x0": o.estimate_x0,
              "jacobian_rank": cov_all.rank, "n_unknowns": J.shape[1], **cov_info,
              "priors": prior_info, "prior_source": priors.source, "prior_note": prior_note,
              "prior_cost": 0.5 * float(np.sum(prior_rows ** 2)),
              "correlation_time": ({c: float(t) for c, t in zip(batch.channels, taus[-1])} if taus else None), "identifiability": ident.as_json()},
    )
