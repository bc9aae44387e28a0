r"""Equation-error baseline: differentiate the data, then least squares on the equations.

Today's common practice (seeds 000–004), implemented on the same data and reported with the
same metrics as output error. The model declares its equations (its *equation-error form*,
see :mod:`diffship.models._base`: ``EQUATION_CHANNELS``, ``EQUATION_ORDER``,
``EQUATION_RATE_OF``, ``EQUATION_INPUT_RATES``, ``EQUATIONS``, ``equation_residual`` and
optionally ``regressors``/``from_regression``); everything numerical happens here, the same
way for every model:

1. smooth the measured channels the equations need and differentiate them numerically
   (:class:`diffship.preprocess.Filter`: zero-phase Butterworth by default, Savitzky–Golay or
   none). Angles (the model's ``angle_outputs``) are unwrapped first. A second derivative is
   the derivative of the first, filtered again with the same filter (Butterworth; plain
   central differences for Savitzky–Golay and none). A channel that is the time derivative of
   another (``EQUATION_RATE_OF``, e.g. ``r = ψ̇``) is taken as the derivative of the smoothed
   source when it is not measured. Input rates (``EQUATION_INPUT_RATES``) are the filtered
   derivatives of those inputs, appended to the inputs;
2. drop 2 % of each run at both ends (filter edge effects), stack the runs, and evaluate the
   model's per-sample residual :math:`e(z, \dot z, \ddot z, u)` (e.g. inverse dynamics in force
   space for Fossen 3-DOF, :math:`e = M\dot\nu + C(\nu)\nu + D(\nu)\nu - \tau`, see each model);
3. minimise :math:`\sum_k \sum_j (e_j(t_k)/w_j)^2` over the free parameters by Gauss–Newton
   (one step is the exact linear least-squares solution for the affine cases), with ``w_j`` the
   residual RMS of equation ``j`` from a first unweighted pass (feasible generalised least
   squares). Where the model has a linear regression form (``regressors``, e.g. Nomoto's
   :math:`\dot r = a r + b\delta + c`), its least-squares solution mapped back to the
   parameters (``from_regression``) is the start. Standard errors: the equation residuals of
   filtered, differentiated data are coloured by construction, so where they are not white the
   covariance is the per-run HAC sandwich (:mod:`diffship.fit.covariance`, ``kind="auto"``)
   rather than the classical ``σ̂²(JᵀJ)⁻¹``; they still ignore the errors in the regressors.

The Butterworth cut-off is chosen from the data for every run and channel unless a frequency
is given (a ``Filter("butter")`` without one is read as ``cutoff="auto"``:
:func:`diffship.preprocess.auto_cutoff`, where the spectrum meets its noise floor); the chosen
values are stated in the messages and in ``info["cutoff_hz"]``.

Parameters are estimated unconstrained in model units (bounds are not imposed, as in the
seeds); a result outside a bound is reported in the messages. A model without an
equation-error form (e.g. MMG) is refused with a :class:`~diffship.errors.ModelError`.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ..data import Run
from ..errors import FitError, ModelError
from ..models import AbstractModel
from ..params import ParamSpec
from ..preprocess import Filter, auto_cutoff, smooth_and_derivative
from ..simulate import initial_state, model_inputs
from .covariance import covariance, relabelled as relabel_covariance
from .result import FitResult

__all__ = ["fit_equation_error", "EquationSamples", "equation_data", "equation_samples", "equation_residuals",
           "TRIM", "cutoffs"]

#: Fraction of each run dropped at both ends before the fit (filter edge effects).
TRIM = 0.02


class EquationSamples(NamedTuple):
    """The measured signals a model's equations are evaluated on, one row per sample.

    Attributes:
        z: smoothed ``EQUATION_CHANNELS``, shape ``(n, n_z)``.
        zd: their first time derivatives.
        zdd: their second time derivatives (zeros unless ``EQUATION_ORDER == 2``).
        u: the model inputs followed by the ``EQUATION_INPUT_RATES``, shape ``(n, n_u)``.
    """

    z: Float[np.ndarray, "n n_z"]
    zd: Float[np.ndarray, "n n_z"]
    zdd: Float[np.ndarray, "n n_z"]
    u: Float[np.ndarray, "n n_u"]


def _check_form(model: AbstractModel) -> None:
    if not model.EQUATIONS or not model.EQUATION_CHANNELS:
        raise ModelError(f"model {model.name} has no equation-error form; use output error")


def _smoothed(model: AbstractModel, run: Run, name: str, flt: Filter) -> tuple[np.ndarray, np.ndarray]:
    y = np.asarray(run[name], dtype=np.float64)
    if name in model.angle_outputs:
        y = np.unwrap(y)
    return smooth_and_derivative(run.time, y, flt, f"run {run.name}, column {name}")


def _channel(model: AbstractModel, run: Run, name: str, flt: Filter) -> tuple[np.ndarray, np.ndarray]:
    """Smoothed value and first derivative of a measured channel, or of the derivative of its source."""
    source = model.EQUATION_RATE_OF.get(name)
    if run.has(name) or source is None:
        return _smoothed(model, run, name, flt)
    run.require((source,), f"equation error for {model.name} (needs {name} or {source})")
    value = _smoothed(model, run, source, flt)[1]
    return value, smooth_and_derivative(run.time, value, Filter("none"))[1]


def equation_data(model: AbstractModel, run: Run, flt: Filter = Filter()) -> EquationSamples:
    """The signals of one run (all samples) that the model's equations are evaluated on."""
    _check_form(model)
    channels = model.EQUATION_CHANNELS
    needed = [c if run.has(c) or c not in model.EQUATION_RATE_OF else model.EQUATION_RATE_OF[c] for c in channels]
    run.require(needed, f"equation error for {model.name} (needs measured {', '.join(channels)})")
    u = model_inputs(model, run)
    cols = [_channel(model, run, c, flt) for c in channels]
    z = np.stack([c[0] for c in cols], 1)
    zd = np.stack([c[1] for c in cols], 1)
    if model.EQUATION_ORDER >= 2:
        again = flt if flt.kind != "savgol" else Filter("none")
        zdd = np.stack([smooth_and_derivative(run.time, c[1], again, f"run {run.name}, derivative of {n}")[1]
                        for c, n in zip(cols, channels)], 1)
    else:
        zdd = np.zeros_like(zd)
    if model.EQUATION_INPUT_RATES:
        rates = [_smoothed(model, run, n, flt)[1] for n in model.EQUATION_INPUT_RATES]
        u = np.concatenate([u, np.stack(rates, 1)], axis=1)
    return EquationSamples(z, zd, zdd, u)


def differentiation_filter(flt: Filter) -> Filter:
    """The filter equation error differentiates with: a Butterworth without a cut-off gets ``"auto"``."""
    return dataclasses.replace(flt, cutoff="auto") if flt.kind == "butter" and flt.cutoff is None else flt


def cutoffs(model: AbstractModel, runs: Sequence[Run], flt: Filter = Filter()) -> dict[str, dict[str, float]]:
    """``{run: {channel: Hz}}``: the Butterworth cut-off each measured equation channel is
    smoothed with by :func:`fit_equation_error` with ``flt``; empty for other filters."""
    flt = differentiation_filter(flt)
    if flt.kind != "butter":
        return {}
    out = {}
    for run in runs:
        per = {}
        for c in model.EQUATION_CHANNELS:
            name = c if run.has(c) or c not in model.EQUATION_RATE_OF else model.EQUATION_RATE_OF[c]
            if not run.has(name):
                continue
            y = np.asarray(run[name], dtype=np.float64)
            y = np.unwrap(y) if name in model.angle_outputs else y
            dt = float(np.median(np.diff(run.time)))
            per[name] = auto_cutoff(y, dt) if flt.cutoff == "auto" else float(flt.cutoff)
        out[run.name] = per
    return out


def _trimmed_lengths(runs: Sequence[Run]) -> list[int]:
    return [len(r.time) - 2 * int(TRIM * len(r.time)) for r in runs]


def equation_samples(model: AbstractModel, runs: Sequence[Run], flt: Filter = Filter()) -> EquationSamples:
    """:func:`equation_data` of every run, trimmed at both ends (``TRIM``) and stacked (with the
    filter :func:`fit_equation_error` differentiates with: a Butterworth without cut-off is ``"auto"``)."""
    flt = differentiation_filter(flt)
    parts = []
    for run in runs:
        d = equation_data(model, run, flt)
        n = d.z.shape[0]
        k = int(TRIM * n)
        parts.append([a[k:n - k] for a in d])
    return EquationSamples(*(np.concatenate([p[i] for p in parts]) for i in range(4)))


def equation_residuals(model: AbstractModel, samples: EquationSamples) -> Float[Array, "n n_eq"]:
    """The model's equation residual at every sample (``jax.vmap`` of ``equation_residual``)."""
    z, zd, zdd, u = (jnp.asarray(a) for a in samples)
    return jax.vmap(model.equation_residual)(z, zd, zdd, u)


def _regression_start(model: AbstractModel, samples: EquationSamples) -> dict[str, float] | None:
    """Least squares of each linear form the model offers, mapped back to its parameters."""
    forms = model.regressors(*(jnp.asarray(a) for a in samples))
    if not forms:
        return None
    coefficients = {}
    for key, form in forms.items():
        c, *_ = np.linalg.lstsq(np.asarray(form.A), np.asarray(form.y), rcond=None)
        coefficients[key] = {n: float(v) for n, v in zip(form.names, c)}
    return model.from_regression(coefficients)


def fit_equation_error(
    model: AbstractModel,
    runs: Sequence[Run],
    *,
    spec: ParamSpec | None = None,
    flt: Filter = Filter(),
    max_steps: int = 50,
) -> FitResult:
    """Fit ``model`` to ``runs`` by equation error (see the module docstring).

    ``flt`` may also be a :class:`~diffship.fit.smoother.KalmanSmoother` (``--filter kalman``): the
    runs are smoothed by an EKF + RTS smoother over ``model`` at its starting values first (noise
    levels estimated; ``info["smoother"]`` and the messages report them), then differentiated with
    central differences."""
    t_start = time.perf_counter()
    _check_form(model)
    spec = spec or model.spec()
    model = model.with_params(spec.values())
    free = spec.free_names
    if not free:
        raise FitError("no free parameters: free at least one (remove it from --fix)")
    eq_names = tuple(model.EQUATIONS)
    smoother = None
    if getattr(flt, "kind", None) == "kalman":
        # EKF + RTS smoother over the model at its starting values (diffship.fit.smoother.KalmanSmoother):
        # the regression then differentiates the smoothed states with central differences
        smoother_text = flt.describe(runs[0].dt)
        runs, smoother = flt.apply(model, runs)
        flt = Filter("none")
    x0_flt, flt = flt, differentiation_filter(flt)
    samples = equation_samples(model, runs, flt)
    idx = spec.free_index()
    names = model.param_names
    base = model.theta()

    def residuals(theta_free, w):
        m = model.with_params(base.at[idx].set(theta_free))
        return (equation_residuals(m, samples) / w).reshape(-1)

    res_jit = jax.jit(residuals)
    jac_jit = jax.jit(jax.jacfwd(residuals))
    theta = np.asarray(base)[idx]
    start = _regression_start(model, samples)
    if start is not None:
        theta = np.array([start.get(n, float(base[i])) for n, i in zip(free, idx)])
    n_eq = len(eq_names)
    w = np.ones(n_eq)
    flt_text = smoother_text if smoother is not None else flt.describe(runs[0].dt)
    messages = [f"derivatives: {flt_text}", f"equations: {', '.join(eq_names)}"]
    if smoother is not None:
        messages.append(_smoother_note(smoother))
    cut = cutoffs(model, runs, flt)
    if cut:
        messages.append("Butterworth cut-offs [Hz]: " + "; ".join(
            f"{run}: " + ", ".join(f"{c} {v:.2f}" for c, v in per.items()) for run, per in cut.items()))
    iterations = 0
    converged = False
    compile_s = 0.0
    for weighting_pass in range(2):
        wj = jnp.asarray(w)
        t_c = time.perf_counter()
        r = np.asarray(res_jit(jnp.asarray(theta), wj))
        if iterations == 0:
            jac_jit(jnp.asarray(theta), wj).block_until_ready()
            compile_s = time.perf_counter() - t_c
        cost = 0.5 * float(r @ r)
        converged = False
        for _ in range(max_steps):
            J = np.asarray(jac_jit(jnp.asarray(theta), wj))
            iterations += 1
            step, *_ = np.linalg.lstsq(J, -r, rcond=None)
            scale = 1.0
            while scale > 1e-6:  # backtrack until the cost does not increase
                cand = theta + scale * step
                rc = np.asarray(res_jit(jnp.asarray(cand), wj))
                cc = 0.5 * float(rc @ rc)
                if math.isfinite(cc) and cc <= cost:
                    break
                scale *= 0.5
            else:
                break
            small = np.all(np.abs(scale * step) <= 1e-10 + 1e-8 * np.abs(theta))
            theta, r, cost = cand, rc, cc
            if small or np.all(np.abs(scale * step) <= 1e-7 * (np.abs(theta) + 1e-12)):
                converged = True
                break
        if weighting_pass == 0:
            e = r.reshape(-1, n_eq) * w
            w = np.sqrt(np.mean(e * e, axis=0)) + 1e-300
    if not np.all(np.isfinite(theta)):
        raise FitError(f"equation error for {model.name} produced non-finite parameters on runs "
                       f"{', '.join(r_.name for r_ in runs)}; check the inputs and the filter")
    J = np.asarray(jac_jit(jnp.asarray(theta), jnp.asarray(w)))
    # residuals of filtered data are coloured: the per-run HAC sandwich where they are not white
    lengths = _trimmed_lengths(runs)
    mask = np.arange(max(lengths))[None, :] < np.asarray(lengths)[:, None]
    Jp = np.zeros(mask.shape + (n_eq, J.shape[1]))
    rp = np.zeros(mask.shape + (n_eq,))
    Jp[mask] = J.reshape(-1, n_eq, J.shape[1])
    rp[mask] = r.reshape(-1, n_eq)
    cov_all = covariance(Jp.reshape(-1, J.shape[1]), rp.reshape(-1), dof=r.size - J.shape[1], kind="auto", mask=mask,
                         n_channels=n_eq, runs=tuple(r_.name for r_ in runs), channels=eq_names)
    messages.append(cov_all.describe())
    cov = cov_all.matrix
    if not cov_all.full_rank:
        messages.append("not identifiable from these equations (rank deficient; standard errors infinite): "
                        + ", ".join(free[i] for i in cov_all.unidentifiable))
    vals = {n: float(v) for n, v in zip(names, np.asarray(base))}
    vals.update({n: float(theta[i]) for i, n in enumerate(free)})
    relabelled = model.canonical(vals)
    if relabelled != vals:
        cov = relabel_covariance(cov, vals, relabelled, free)
        vals = relabelled
    stderr = {n: float(math.sqrt(cov[i, i])) if cov[i, i] >= 0 else math.nan for i, n in enumerate(free)}
    for n in free:
        p = spec[n]
        if not (p.lower < vals[n] < p.upper):
            messages.append(f"{n} = {vals[n]:.4g} lies outside its physical bounds ({p.lower:g}, {p.upper:g})")
    fitted = model.with_params(vals)
    x0s = tuple(initial_state(fitted, run, x0_flt) for run in runs)
    fit_s = time.perf_counter() - t_start - compile_s
    return FitResult(
        method="equation_error",
        model=fitted,
        params=vals,
        stderr=stderr,
        free=free,
        converged=bool(converged),
        status="converged" if converged else "Gauss–Newton did not settle",
        iterations=iterations,
        cost=0.5 * float(r @ r),
        fit_seconds=fit_s,
        compile_seconds=compile_s,
        channels=eq_names,
        channel_scales={n: float(x) for n, x in zip(eq_names, w)},
        noise_std={n: float(x) for n, x in zip(eq_names, np.sqrt(np.mean((r.reshape(-1, n_eq) * w) ** 2, axis=0)))},
        initial_states=x0s,
        run_names=tuple(r_.name for r_ in runs),
        covariance=cov,
        messages=tuple(messages),
        info={"filter": flt_text, "equations": eq_names, "cutoff_hz": cut, **cov_all.info(),
              **({"smoother": {k: v for k, v in smoother.items() if k != "method"}} if smoother else {})},
    )


def _smoother_note(info: dict) -> str:
    """One line of the Kalman smoother's estimated noise levels (report and messages)."""
    meas = ", ".join(f"{c} {v:.3g}" for c, v in info["measurement_sd"].items())
    proc = ", ".join(f"{s} {v:.3g}" for s, v in info["process_sd"].items())
    tau = info.get("disturbance_tau")
    dist = (f"disturbance sd (Ornstein–Uhlenbeck, time constant {tau:.3g} s) {proc}" if tau is not None
            and math.isfinite(tau) else f"process sd per √s {proc}")
    return f"Kalman smoother, estimated noise: measurement sd {meas}; {dist}"
