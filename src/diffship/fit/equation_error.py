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
3. minimise :math:`\sum_k \sum_j (e_j(t_k)/w_j)^2` (plus prior rows where priors are given) over
   the free parameters by the one Levenberg–Marquardt (:mod:`diffship.fit._lm`), with ``w_j`` the
   residual RMS of equation ``j`` from a first unweighted pass (feasible generalised least
   squares). Where the model has a linear regression form (``regressors``, e.g. Nomoto's
   :math:`\dot r = a r + b\delta + c`), its least-squares solution mapped back to the
   parameters (``from_regression``) is a named start of the driver (:func:`diffship.fit.fit`). Standard errors: the equation residuals of
   filtered, differentiated data are coloured by construction, so where they are not white the
   covariance is the per-run HAC sandwich (:mod:`diffship.fit.covariance`, ``kind="auto"``)
   rather than the classical ``σ̂²(JᵀJ)⁻¹``; they still ignore the errors in the regressors.

The Butterworth cut-off is chosen from the data for every run and channel unless a frequency
is given (a ``Filter("butter")`` without one is read as ``cutoff="auto"``:
:func:`diffship.preprocess.auto_cutoff`, where the spectrum meets its noise floor); the chosen
values are stated in the messages and in ``info["cutoff_hz"]``.

Parameters live in the scaled space of the spec like every estimator's, so physical bounds hold (a
sign-constrained coefficient cannot change sign; an unbounded one is estimated as in the seeds). The
driver checks that the estimate simulates the training runs: one that blows up is reported
``simulation_blew_up`` (the best-known failure of equation error). A model without an
equation-error form (e.g. MMG) is refused with a :class:`~diffship.errors.ModelError`.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from typing import Any, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Array, Float

from ..compiled import compiled
from ..data import Run
from ..errors import DiffshipError, FitError, ModelError
from ..models import AbstractModel
from ..params import ParamSpec, values_from_z
from ..preprocess import Filter, auto_cutoff, smooth_and_derivative
from ..simulate import initial_state, model_inputs
from . import status as st
from ._lm import MaterialisedLM, rms_norm
from .driver import fit
from .estimator import AbstractEstimator, Problem, Solved
from .identifiability import per_scale_columns
from .priors import Priors, prior_arrays
from .result import FitResult

__all__ = ["EquationError", "equation_error_start", "fit_equation_error", "EquationSamples", "equation_data", "equation_samples", "equation_residuals",
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


def _unbounded(spec: ParamSpec) -> ParamSpec:
    """The structural spec with every bound removed (the linear space θ/scale)."""
    return ParamSpec(tuple(dataclasses.replace(p, value=0.0, lower=-math.inf, upper=math.inf) for p in spec.params))


class _Space(NamedTuple):
    """A spec's scaled space as data (:func:`diffship.params.values_from_z`): the linear space θ/scale
    and the bounded space are then one compiled program each for the solve, the residuals and the
    Jacobian, not two (the spaces differ only in these arrays; the free parameters are the same)."""

    idx: tuple[int, ...]  # positions of the free parameters among the spec's (static)
    n: int  # number of parameters in the spec (static)
    kind: Array
    lo: Array
    hi: Array
    s: Array

    @classmethod
    def of(cls, spec: ParamSpec) -> _Space:
        kind, lo, hi, s = spec.free_arrays()
        return cls(tuple(int(i) for i in spec.free_index()), len(spec.params),
                   *(jnp.asarray(a) for a in (kind, lo, hi, s)))

    def from_z(self, z):
        return values_from_z(z, self.kind, self.lo, self.hi, self.s)

    def full_values(self, z, base):
        """As :meth:`diffship.params.ParamSpec.full_values`: ``base`` with the free entries from ``z``."""
        return base.at[np.asarray(self.idx, dtype=np.int64)].set(self.from_z(z))


def _ee_residuals(z, w, prior_mean, prior_w, model, samples, space: _Space):
    """Weighted equation residuals at the scaled unknowns ``z`` (then the prior rows)."""
    theta = space.full_values(z, model.theta()[: space.n])
    m = model.with_params(jnp.concatenate([theta, model.theta()[space.n:]]))
    e = (equation_residuals(m, samples) / w).reshape(-1)
    if prior_w.shape[0]:
        e = jnp.concatenate([e, prior_w * (space.from_z(z) - prior_mean)])
    return e


def _ee_solve(z0, w, prior_mean, prior_w, model, samples, space, max_steps):
    """The one Levenberg–Marquardt (:class:`~diffship.fit._lm.MaterialisedLM`) on the equation residuals."""
    solver = MaterialisedLM(rtol=1e-8, atol=1e-10, norm=rms_norm, ftol=1e-10, gntol=float("inf"))
    sol = optx.least_squares(lambda z, a: _ee_residuals(z, *a, model, samples, space), solver, z0,
                             args=(w, prior_mean, prior_w), max_steps=max_steps, throw=False)
    return sol.value, sol.result, sol.stats["num_steps"], _ee_residuals(sol.value, w, prior_mean, prior_w, model,
                                                                        samples, space)


class _Programs(eqx.Module):
    """The equation-error programs (solve, residuals, Jacobian) as :mod:`diffship.compiled` keys them: the free
    set's positions are static, everything else is an argument. Compiled once per structure and, with the
    persistent cache on, exported between processes: the output-error fit's equation-error start then loads its
    solve instead of tracing it again (0.9 s of a warm 3-DOF USV fit's Python, beside its own compile)."""

    idx: tuple[int, ...] = eqx.field(static=True)
    n: int = eqx.field(static=True)

    def _space(self, arrays) -> _Space:
        return _Space(self.idx, self.n, *arrays)

    def solve(self, z0, w, prior_mean, prior_w, model, samples, arrays, *, max_steps: int):
        """:func:`_ee_solve` with the optimistix result as its integer code (plain arrays out: exportable)."""
        z, result, *rest = _ee_solve(z0, w, prior_mean, prior_w, model, samples, self._space(arrays), max_steps)
        return z, jax.tree_util.tree_leaves(result)[0], *rest

    def residuals(self, z, w, prior_mean, prior_w, model, samples, arrays):
        return _ee_residuals(z, w, prior_mean, prior_w, model, samples, self._space(arrays))

    def jacobian(self, z, w, prior_mean, prior_w, model, samples, arrays):
        return jax.jacfwd(_ee_residuals)(z, w, prior_mean, prior_w, model, samples, self._space(arrays))


def _program(name: str, z, w, prior_mean, prior_w, model, samples, space: _Space, **static):
    """Run the compiled ``name`` of :class:`_Programs` at these arguments (``space`` split into its static
    positions and its arrays)."""
    args = (jnp.asarray(z, dtype=jnp.float64), w, prior_mean, prior_w, model, samples,
            (space.kind, space.lo, space.hi, space.s))
    fn, _ = compiled(_Programs(space.idx, space.n), name, args, **static)
    out = fn(*args)
    if name == "solve":  # the result's integer code back to an optimistix result
        z, code, *rest = out
        return z, jax.tree_util.tree_unflatten(_RESULT_TREE, [code]), *rest
    return out


_RESULT_TREE = jax.tree_util.tree_structure(optx.RESULTS.successful)


@dataclasses.dataclass(frozen=True)
class EquationError(AbstractEstimator):
    """Equation error (module docstring): the settings of the estimator.

    Attributes:
        flt: how the data are smoothed and differentiated (a :class:`~diffship.preprocess.Filter`,
            or a :class:`~diffship.fit.smoother.KalmanSmoother` for ``--filter kalman``).
        max_steps: Levenberg–Marquardt steps per pass (two passes: unweighted, then FGLS).
        priors: explicit priors (as for output error: one row per prior, MAP estimate).
        reference_priors: the model's reference set as priors; ``False`` by default — the baseline
            is today's practice, plain least squares on the equations.
        prior_rel_sd: relative standard deviation of the reference priors.
        choose: ``"best"`` (the driver's multi-start) or ``"first"`` (the first finite start alone).

    The parameters live in the scaled space of the spec like every estimator's (so bounds hold:
    a sign-constrained coefficient cannot change sign); the linear-regression solution
    (``regressors``) is a named start.
    """

    method = "equation_error"
    simulates = False

    flt: Any = Filter()
    max_steps: int = 50
    priors: Priors | None = None
    reference_priors: bool = False
    prior_rel_sd: float = 0.5
    choose: str = "best"

    def describe(self) -> str:
        return "equation error"

    def prepare(self, model, runs, spec, channels, priors, say) -> Problem:
        t0 = time.perf_counter()
        _check_form(model)
        eq_names = tuple(model.EQUATIONS)
        flt, smoother, smoother_text = self.flt, None, None
        if getattr(flt, "kind", None) == "kalman":
            # EKF + RTS smoother over the model at its starting values (diffship.fit.smoother.KalmanSmoother):
            # the regression then differentiates the smoothed states with central differences
            smoother_text = flt.describe(runs[0].dt)
            runs, smoother = flt.apply(model, runs)
            flt = Filter("none")
        x0_flt, flt = flt, differentiation_filter(flt)
        samples = EquationSamples(*(jnp.asarray(a) for a in equation_samples(model, runs, flt)))
        flt_text = smoother_text if smoother is not None else flt.describe(runs[0].dt)
        messages = [f"derivatives: {flt_text}", f"equations: {', '.join(eq_names)}"]
        if smoother is not None:
            messages.append(_smoother_note(smoother))
        cut = cutoffs(model, runs, flt)
        if cut:
            messages.append("Butterworth cut-offs [Hz]: " + "; ".join(
                f"{run}: " + ", ".join(f"{c} {v:.2f}" for c, v in per.items()) for run, per in cut.items()))
        p_mean, p_w = prior_arrays(priors, spec)
        if not np.any(p_w):
            p_mean = p_w = np.zeros(0)
        regression = _regression_start(model, samples)
        lin = _unbounded(spec)
        return Problem(
            model=model, spec=spec, runs=tuple(runs), channels=eq_names, n_nuisance=0, nuisance_names=(),
            priors=priors, compile_seconds=0.0,
            state=dict(samples=samples, spec_s=spec.structural(), spec_lin=lin,
                       spaces={"spec_s": _Space.of(spec), "spec_lin": _Space.of(lin)}, n_eq=len(eq_names), pm=jnp.asarray(p_mean),
                       pw=jnp.asarray(p_w), messages=messages, x0_flt=x0_flt, cut=cut, flt_text=flt_text,
                       smoother=smoother, n_rows=int(samples.z.shape[0]) * len(eq_names), prep_s=time.perf_counter() - t0,
                       extra_starts={"the linear-regression estimate": regression} if regression else {}))

    def _args(self, problem, w, space="spec_s"):
        s = problem.state
        return (jnp.asarray(w, dtype=jnp.float64), s["pm"], s["pw"], problem.model, s["samples"], s["spaces"][space])

    def _solve(self, problem, z, w):
        """LM from ``z`` (the spec's scaled space): first in the unbounded linear space θ/scale (a linear
        regression, e.g. inverse dynamics in force space, is then solved in one step, as in the seeds);
        only where that optimum leaves a parameter's bounds, again in the bounded space from inside them.
        Returns ``(z, result, steps, residuals, space)``."""
        s, spec = problem.state, problem.spec
        free = spec.free_names
        theta = {n: float(v) for n, v in zip(free, np.asarray(spec.from_z(jnp.asarray(z))))}
        zl = s["spec_lin"].to_z(theta)
        zl, result, k, r = _program("solve", zl, *self._args(problem, w, "spec_lin"), max_steps=self.max_steps)
        th = np.asarray(s["spec_lin"].from_z(zl))
        if np.all(np.isfinite(th)) and all(spec[n].lower < v < spec[n].upper for n, v in zip(free, th)):
            return np.asarray(zl), result, int(k), np.asarray(r), "spec_lin"
        inside, _ = spec.nudged({**spec.values(), **{n: float(v) for n, v in zip(free, th) if np.isfinite(v)}})
        zb, result, k2, r = _program("solve", spec.to_z(inside), *self._args(problem, w), max_steps=self.max_steps)
        return np.asarray(zb), result, int(k) + int(k2), np.asarray(r), "spec_s"

    @staticmethod
    def _to_spec_z(problem, z, space):
        if space == "spec_s":
            return np.asarray(z)
        th = np.asarray(problem.state["spec_lin"].from_z(jnp.asarray(z)))
        return problem.spec.to_z(dict(zip(problem.spec.free_names, (float(v) for v in th))))

    def start_cost(self, problem, z) -> float:
        r = np.asarray(_program("residuals", z, *self._args(problem, np.ones(problem.state["n_eq"]))))
        c = 0.5 * float(r @ r)
        return c if math.isfinite(c) else math.inf

    def first_solves(self, problem, zs, say):
        if self.choose == "first":
            zs = zs[:1]
        out = []
        t0 = time.perf_counter()
        for z in zs:
            zf, result, k, r, space = self._solve(problem, z, np.ones(problem.state["n_eq"]))
            c = 0.5 * float(r @ r)
            out.append((self._to_spec_z(problem, zf, space), c if math.isfinite(c) else math.inf, k))
        problem.state["first_s"] = time.perf_counter() - t0
        return out

    def residuals(self, problem, z) -> np.ndarray:
        s = problem.state
        r = np.asarray(_program("residuals", z, *self._args(problem, s.get("w", np.ones(s["n_eq"])))))
        return r[: s["samples"].z.shape[0] * s["n_eq"]]

    def finish(self, problem, z, steps, say) -> Solved:
        s = problem.state
        model, spec = problem.model, problem.spec
        n_eq, n_p = s["n_eq"], problem.n_params
        t0 = time.perf_counter()
        r0 = np.asarray(_program("residuals", z, *self._args(problem, np.ones(n_eq))))
        # feasible GLS: each equation weighted by its residual RMS from the unweighted pass
        e = r0[: s["samples"].z.shape[0] * n_eq].reshape(-1, n_eq)
        w = np.sqrt(np.mean(e * e, axis=0)) + 1e-300
        s["w"] = w
        zs_, result, k, r, space = self._solve(problem, z, w)
        if not np.all(np.isfinite(zs_)):
            raise FitError(f"equation error for {model.name} produced non-finite parameters on runs "
                           f"{', '.join(r_.name for r_ in problem.runs)}; check the inputs and the filter")
        # the Jacobian in θ/scale units (the linear space is that already)
        J = np.asarray(_program("jacobian", zs_, *self._args(problem, w, space))) * per_scale_columns(
            s[space], zs_, n_p)
        zf = self._to_spec_z(problem, zs_, space)
        n_data = s["samples"].z.shape[0] * n_eq
        r_d, J_d, r_p, J_p = r[:n_data], J[:n_data], r[n_data:], J[n_data:]
        # residuals of filtered data are coloured: the per-run HAC sandwich where they are not white
        lengths = _trimmed_lengths(problem.runs)
        mask = np.arange(max(lengths))[None, :] < np.asarray(lengths)[:, None]
        Jp = np.zeros(mask.shape + (n_eq, J.shape[1]))
        rp = np.zeros(mask.shape + (n_eq,))
        Jp[mask] = J_d.reshape(-1, n_eq, J.shape[1])
        rp[mask] = r_d.reshape(-1, n_eq)
        conv = st.as_diffship(result) == st.RESULTS.successful
        theta = np.asarray(spec.full_values(jnp.asarray(zf), model.theta()))
        fitted = model.with_params(theta)
        x0s = tuple(initial_state(fitted, run, s["x0_flt"]) for run in problem.runs)
        eq_names = problem.channels
        fit_s = s.get("first_s", 0.0) + s["prep_s"] + time.perf_counter() - t0
        return Solved(
            z=zf, r_data=rp.reshape(-1), J_data=Jp.reshape(-1, J.shape[1]), J_extra=J_p, r_extra=r_p,
            result=st.RESULTS.successful if conv else st.RESULTS.did_not_settle, steps=steps + int(k), seconds=fit_s,
            compile_seconds=0.0, cost=0.5 * float(r_d @ r_d), channel_scales={n: float(x) for n, x in zip(eq_names, w)},
            noise_std={n: float(x) for n, x in zip(eq_names, np.sqrt(np.mean((r_d.reshape(-1, n_eq) * w) ** 2, axis=0)))},
            initial_states=x0s, run_names=tuple(r_.name for r_ in problem.runs), dof=r_d.size - J.shape[1], kind="auto",
            mask=mask, n_channels=n_eq, prior_cost=0.5 * float(r_p @ r_p), messages=tuple(s["messages"]),
            info={"filter": s["flt_text"], "equations": eq_names, "cutoff_hz": s["cut"],
                  **({"smoother": {k_: v for k_, v in s["smoother"].items() if k_ != "method"}} if s["smoother"] else {})})


def equation_error_start(model: AbstractModel, runs: Sequence[Run], spec: ParamSpec) -> tuple[dict | None, str]:
    """The equation-error estimate as a start for another estimator, or ``None`` with the reason
    (no equation-error form, a channel missing, an estimate that is not usable)."""
    if not model.EQUATIONS or not model.EQUATION_CHANNELS:
        return None, ""
    try:
        ee = fit(model, runs, EquationError(), spec=spec, n_starts=1, throw=False)
    except DiffshipError as exc:  # e.g. a channel the equations need is not measured
        return None, f"no equation-error start: {exc}"
    if not ee.usable:
        return None, f"no equation-error start: {ee.status}"
    return {n: ee.params[n] for n in ee.free}, ""


def fit_equation_error(
    model: AbstractModel,
    runs: Sequence[Run],
    *,
    spec: ParamSpec | None = None,
    flt: Filter = Filter(),
    max_steps: int = 50,
    priors: Priors | None = None,
    n_starts: int | None = 1,
    throw: bool = True,
) -> FitResult:
    """Fit ``model`` to ``runs`` by equation error: :func:`diffship.fit.fit` with :class:`EquationError`.

    ``flt`` may also be a :class:`~diffship.fit.smoother.KalmanSmoother` (``--filter kalman``): the
    runs are smoothed by an EKF + RTS smoother over ``model`` at its starting values first (noise
    levels estimated; ``info["smoother"]`` and the messages report them), then differentiated with
    central differences. One start by default: the better of the model's values and the linear
    regression (the baseline as practised); ``n_starts`` adds spread starts."""
    _check_form(model)
    return fit(model, runs, EquationError(flt=flt, max_steps=max_steps, priors=priors), spec=spec,
               n_starts=n_starts, throw=throw)


def _smoother_note(info: dict) -> str:
    """One line of the Kalman smoother's estimated noise levels (report and messages)."""
    meas = ", ".join(f"{c} {v:.3g}" for c, v in info["measurement_sd"].items())
    proc = ", ".join(f"{s} {v:.3g}" for s, v in info["process_sd"].items())
    tau = info.get("disturbance_tau")
    dist = (f"disturbance sd (Ornstein–Uhlenbeck, time constant {tau:.3g} s) {proc}" if tau is not None
            and math.isfinite(tau) else f"process sd per √s {proc}")
    return f"Kalman smoother, estimated noise: measurement sd {meas}; {dist}"
