r"""The one driver: ``fit(model, runs, estimator) -> FitResult``.

Every estimator (:mod:`diffship.fit.estimator`) runs through :func:`fit`, which owns, once:

* **validation** — free parameters exist, the estimator's settings name real states;
* **priors** — the model's reference set where it applies (``reference_priors``) merged with the
  estimator's explicit ``priors`` (:mod:`diffship.fit.priors`); the optimum is then the MAP estimate;
* **starts** — the model's values (with the user's ``--init``), the caller's named starts, the
  estimator's own (output error: the equation-error estimate where the model has an equation-error
  form; equation error: the linear regression), the reference values, and spread starts up to ``n_starts`` (:mod:`diffship.fit.starts`); every start is simulated first and
  one that blows up is never used;
* **multi-start** — the estimator's first solve runs from every finite start together
  (:meth:`~diffship.fit.estimator.AbstractEstimator.first_solves`: the kernel's batch of solves);
  the rest of the schedule continues from the lowest cost. How many starts reached that cost (within
  half the residual variance: about one standard error along one parameter direction) and whether
  the user's own start ended higher are in :attr:`FitResult.starts`, the report and the JSON;
* **covariance** — from the estimator's linearisation (:class:`~diffship.fit.estimator.Solved`):
  the data rows' covariance (HAC where the residuals are coloured, measured-input noise
  propagated), and the posterior with the unit-variance rows (priors, continuity defects)
  stacked under the data rows scaled by σ̂:

  .. math:: \Sigma = \big(J_d^\top J_d/\hat\sigma^2 + J_e^\top J_e\big)^{-1}

  (rank deficiency → infinite standard errors, never pseudo-inverse zeros);
* **relabelling** to the model's canonical parametrisation (e.g. Nomoto T1 ≥ T2), values and
  covariance together;
* **identifiability**, the prior table, **status** (:class:`~diffship.fit.status.RESULTS`: a fit
  whose parameters the data do not identify is ``not_identifiable``; one whose simulation blows up
  at the optimum is ``simulation_blew_up``) and the :class:`~diffship.fit.FitResult` — typed,
  complete, not edited afterwards.
* **positions** — output error with the default channels, where every run logs positions, refits from its optimum
  with them and answers with the refit where a Hausman test finds the two agree (:mod:`diffship.fit.positions`).

``throw=True`` (default) raises :class:`~diffship.errors.FitError` where no start can be used;
``throw=False`` returns a result whose ``result`` says so (``all_starts_blew_up``).
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import time
from collections.abc import Callable, Iterable, Mapping, Sequence

import jax.numpy as jnp
import numpy as np

from ..data import Run
from ..errors import DataError, FitError
from ..models import AbstractModel
from ..params import ParamSpec
from .covariance import covariance, relabelled
from .estimator import AbstractEstimator, Problem, Solved
from .identifiability import identifiability
from .priors import Priors, default_priors, prior_table
from .problem import NOT_FITTED_BY_DEFAULT, unfitted_positions
from .result import FitResult, StartsReport
from .starts import checked_start, named_starts, spread_starts
from .status import RESULTS, as_diffship, message

__all__ = ["fit", "fit_priors", "DEFAULT_STARTS"]

#: Starts tried by default (``--starts N``): the named ones, then spread ones up to this count.
DEFAULT_STARTS = 4


def fit_priors(model: AbstractModel, spec: ParamSpec, estimator) -> tuple[Priors, str]:
    """The priors of a fit (reference set unless turned off, merged with ``estimator.priors``) and a
    one-line note for the report."""
    e = estimator
    priors, note = (default_priors(model, spec, e.prior_rel_sd) if e.reference_priors
                    else (Priors({}, "none"), "priors from the reference set not used"
                          + (" (--no-prior)" if getattr(e, "method", "") != "equation_error" else
                             " (the equation-error baseline takes only explicit priors)")))
    priors = priors.merged(e.priors)
    if e.priors is not None and len(e.priors):
        note += f"; {len(e.priors)} prior(s) from {e.priors.source}"
    return priors, note


def _checked_runs(runs) -> list[Run]:
    """``runs`` as a list of :class:`~diffship.data.Run`, or :class:`DataError` saying what was given."""
    if isinstance(runs, Run):
        raise DataError(f"runs: a single Run ({runs.name}) given; pass a list of runs, e.g. [run]")
    if isinstance(runs, (str, bytes, Mapping)) or not isinstance(runs, Iterable):
        raise DataError(f"runs: expected a list of diffship Run objects, got {type(runs).__name__}")
    runs = list(runs)
    bad = [f"item {i} ({type(r).__name__})" for i, r in enumerate(runs) if not isinstance(r, Run)]
    if bad:
        raise DataError(f"runs: {', '.join(bad)} not a diffship Run; read runs with diffship.data "
                        "(e.g. load_runs) and pass a list of them")
    return runs


def _checked_channels(channels) -> tuple[str, ...] | None:
    """``channels`` as a tuple of names (``None`` stays ``None``), or :class:`DataError`."""
    if channels is None:
        return None
    if isinstance(channels, str):
        raise DataError(f"channels={channels!r}: a single string; give a sequence of names, e.g. ({channels!r},)")
    if not isinstance(channels, Iterable) or isinstance(channels, Mapping):
        raise DataError(f"channels: expected a sequence of channel names, got {type(channels).__name__}")
    channels = tuple(channels)
    bad = [repr(c) for c in channels if not isinstance(c, str)]
    if bad:
        raise DataError(f"channels: {', '.join(bad)} not a channel name (a string)")
    return channels


def _reference(model: AbstractModel) -> dict[str, float]:
    """The model's declared (reference) values: the class's, or for a model whose parameters are
    per instance (a base model with effects or terms) its base's declared values and the null values."""
    params = type(model).PARAMS
    return {p.name: p.value for p in (params if isinstance(params, tuple) else model.PARAMS)}


def _has_equation_form(model: AbstractModel) -> bool:
    return bool(getattr(model, "EQUATIONS", ()))


def fit(
    model: AbstractModel,
    runs: Sequence[Run],
    estimator: AbstractEstimator,
    *,
    spec: ParamSpec | None = None,
    init: Mapping[str, float] | None = None,
    starts: Sequence[Mapping[str, float]] | Mapping[str, Mapping[str, float]] = (),
    n_starts: int | None = None,
    channels: Sequence[str] | None = None,
    progress: Callable[[str], None] | None = None,
    throw: bool = True,
) -> FitResult:
    """Fit ``model`` to ``runs`` with ``estimator`` (e.g. :class:`~diffship.fit.OutputError`).

    Args:
        model: the model; its parameter values are the defaults of the fit.
        runs: training runs (any lengths and sample rates).
        estimator: how residuals are assembled and solved (a settings object).
        spec: free/fixed flags, bounds and scales (default ``model.spec()``); its values are the
            fixed values and the first start.
        init: the user's own start values (``--init``) of free parameters; the result says if this
            start ended higher than another. A fixed parameter named here raises :class:`~diffship.errors.ModelError`
            (its start value would silently become the value it is held at): hold it at a value with
            ``spec.fix({name: value})``, or free it to start it there.
        starts: further named starts (``{label: values}`` or a sequence).
        n_starts: how many starts in all (default :data:`DEFAULT_STARTS`; ``1``: the best named
            start alone). Named starts are never dropped.
        channels: measured channels to fit (default: the model's outputs in every run except positions).
        progress: optional ``progress(text)`` for people watching.
        throw: raise :class:`~diffship.errors.FitError` when no start can be used (else a result
            with ``result == RESULTS.all_starts_blew_up``).
    """
    say = progress or (lambda s: None)
    t_all = time.perf_counter()
    runs, channels = _checked_runs(runs), _checked_channels(channels)
    if n_starts is not None and (isinstance(n_starts, bool) or not isinstance(n_starts, numbers.Integral)
                                 or n_starts < 1):
        raise FitError(f"n_starts={n_starts!r}: give a whole number of starts, at least 1 "
                       f"(or None for the default, {DEFAULT_STARTS})")
    spec = spec or model.spec()
    if init:
        spec = spec.with_values(checked_start(spec, init, "init"))  # free parameters only: a held value is spec's
    starts = ({k: checked_start(spec, v, f"start {k!r}") for k, v in starts.items()} if isinstance(starts, Mapping)
              else [checked_start(spec, v, f"start {i + 1}") for i, v in enumerate(starts)])
    model = model.with_params(spec.nudged(spec.values())[0])  # a start beyond a bound is moved inside below
    n_p = len(spec.free_names)
    if n_p == 0:
        raise FitError("no free parameters: free at least one (remove it from --fix)")
    priors, prior_note = fit_priors(model, spec, estimator)
    problem = estimator.prepare(model, runs, spec, channels, priors, say)

    # -- candidate starts -----------------------------------------------------------------------
    named = dict(starts.items()) if isinstance(starts, Mapping) else {f"start {i + 1}": s for i, s in enumerate(starts)}
    messages: list[str] = [prior_note] + (unfitted_positions(model, runs, channels)
                                           if estimator.method != "equation_error" else [])
    for k, v in problem.state.get("extra_starts", {}).items():  # the estimator's own (a linear regression,
        named.setdefault(k, v)                                    # the equation-error estimate)
    messages.extend(problem.state.get("start_notes", ()))
    reference = _reference(model)
    first = "your start (--init)" if init else "the model's values"
    cands = named_starts(spec, named, reference, first_label=first)
    n_total = DEFAULT_STARTS if n_starts is None else int(n_starts)
    user = 0 if init else None

    # -- screen every start by its initial cost (a start that blows up is never used) ----------
    def screened(label, vals):
        vals, notes = spec.nudged(vals)
        messages.extend(f"start '{label}': {n}" for n in notes)
        try:
            z = problem.z_start(vals)
        except Exception as exc:  # start outside bounds
            messages.append(f"start '{label}' skipped: {exc}")
            return None
        c = estimator.start_cost(problem, z)
        if not math.isfinite(c):
            messages.append(f"start '{label}' rejected: its simulation blows up")
            return None
        return (label, z, c)

    tried = [screened(label, vals) for label, vals in cands]
    finite = [t for t in tried if t is not None]
    if finite and n_total > len(cands) and getattr(estimator, "choose", "best") != "first":
        best_named = min(finite, key=lambda t: t[2])
        around = dict(zip(spec.free_names, (float(v) for v in spec.from_z(best_named[1][:n_p]))))
        for i, vals in enumerate(spread_starts(spec, {**spec.values(), **around}, n_total - len(cands))):
            s = screened(f"spread start {i + 1}", vals)
            tried.append(s)
            if s is not None:
                finite.append(s)
    if not finite:
        text = (f"model {model.name} diverges from every start ({len(tried)} tried) on runs "
                f"{', '.join(r.name for r in runs)}; give a better start with --init NAME=VALUE or fix unstable parameters")
        if throw:
            raise FitError(text)
        return _failed(model, spec, estimator, problem, text, messages)
    if getattr(estimator, "choose", "best") == "first":  # the first finite start alone (e.g. a polish)
        finite = finite[:1]
    elif n_starts == 1:  # the best named start alone (the earlier single-start behaviour)
        finite = [min(finite, key=lambda t: t[2])]

    # -- the first solve from every finite start together; the rest from the best --------------
    say(f"{estimator.describe()}: first solve from {len(finite)} start(s)...")
    t_first = time.perf_counter()
    outs = estimator.first_solves(problem, [t[1] for t in finite], say)
    t_first = time.perf_counter() - t_first
    costs = [o[1] for o in outs]
    best = int(np.nanargmin(np.where(np.isfinite(costs), costs, np.inf))) if any(map(math.isfinite, costs)) else -1
    if best < 0:
        text = (f"model {model.name}: every start blows up during the fit on runs {', '.join(r.name for r in runs)}; "
                "give a better start with --init NAME=VALUE")
        if throw:
            raise FitError(text)
        return _failed(model, spec, estimator, problem, text, messages)
    m_rows = max(int(problem.state.get("n_rows", 0)) - n_p, 1)
    tol = (float(problem.state["cost_tolerance"]) if "cost_tolerance" in problem.state
           else max(costs[best] / m_rows, 1e-12 * abs(costs[best])))
    labels = tuple(t[0] for t in finite)
    report = StartsReport(labels=labels, costs=tuple(float(c) for c in costs), best=best,
                          reached=int(sum(1 for c in costs if math.isfinite(c) and c <= costs[best] + tol)),
                          tolerance=float(tol), user=(labels.index(first) if user is not None and first in labels
                                                      else None),
                          stopped=tuple(int(i) for i in problem.state.get("dominated", ())))
    label, z_best, steps0 = finite[best][0], outs[best][0], int(outs[best][2])
    messages.append(f"started from {label}")
    messages.append(report.describe())
    start_vals = dict(zip(spec.free_names, (float(v) for v in spec.from_z(finite[best][1][:n_p]))))
    solved = estimator.finish(problem, z_best, steps0, say)
    # the fit's solve time is every start's first solve and the rest from the best (compiles excluded)
    solved = dataclasses.replace(solved, seconds=float(solved.seconds) + t_first,
                                 info={**solved.info, "solve_seconds": {"first_solves": t_first,
                                                                         "from_the_best": float(solved.seconds)}})
    res = _assemble(model, spec, estimator, problem, solved, priors, prior_note, messages, report, start_vals, label)
    say(f"{estimator.describe()}: {res.status} after {res.iterations} steps in {res.fit_seconds:.2f} s "
        f"(compile {res.compile_seconds:.2f} s; {time.perf_counter() - t_all:.1f} s in all)")
    if channels is None and getattr(estimator, "positions", "off") == "test" and unfitted_positions(model, runs, None):
        res = _positions_tested(model, runs, estimator, spec, res, progress)
    return res


def _positions_tested(model, runs, estimator, spec, res: FitResult, progress) -> FitResult:
    """The fit without positions, or its refit with them where a Hausman test finds the two agree
    (:mod:`diffship.fit.positions`); either way the report and ``info["positions_test"]`` say which and why."""
    from .positions import SCREEN, PositionsTest, hausman, misfit

    say = progress or (lambda s: None)
    every = tuple(c for c in model.output_names if all(r.has(c) for r in runs))
    left = tuple(c for c in NOT_FITTED_BY_DEFAULT if c in every)
    drop = [m for m in res.messages if not m.startswith("channels: ")]
    ratios = misfit(runs, {c: res.noise_std[c] for c in res.channels if c in res.noise_std}, model.angle_outputs)
    worst = max(ratios, key=ratios.get) if ratios else None
    if not res.converged:
        test = PositionsTest(left, False, "the fit without them did not converge")
    elif worst is not None and ratios[worst] > SCREEN:
        test = PositionsTest(left, False, (
            f"the fit misses its own channels ({worst}: residual {ratios[worst]:.3g} times its sample-to-sample "
            f"noise; where the model misses, a position's drift decides the fit), so no refit with them"))
    else:
        say(f"refitting with the positions ({', '.join(left)}) from this optimum, to test whether they agree...")
        refit = dataclasses.replace(estimator, positions="off", warmup=0.0, adaptive=False, ee_start=False)
        if isinstance(refit.estimate_x0, tuple) and refit.estimate_x0:  # named states: the positions' own too
            named = set(refit.estimate_x0) | set(model.states_for_channels(left))
            refit = dataclasses.replace(refit, estimate_x0=tuple(s for s in model.state_names if s in named))
        start = spec.with_values({n: res.params[n] for n in spec.free_names})
        try:
            alt = fit(model, runs, refit, spec=start, n_starts=1, channels=every, progress=progress, throw=False)
        except Exception as exc:  # a refit that cannot start: the fit without positions stands
            alt, reason = None, f"the refit with them failed ({exc})"
        else:
            reason = "" if alt.converged else f"the refit with them did not converge ({alt.status})"
        if alt is None or not alt.converged:
            test = PositionsTest(left, False, reason)
        else:
            names = list(spec.free_names)
            test = hausman(names, [res.params[n] for n in names], res.covariance, [alt.params[n] for n in names],
                           alt.covariance, channels=left)
            if test.kept:  # the refit's answer, with the search's starts (the refit had one: this optimum)
                say(test.describe())
                own = ("started from ", "starts: ", "start '", "search: ")
                msgs = [m for m in alt.messages if not m.startswith(own)]
                msgs[1:1] = [m for m in res.messages if m.startswith(own)]
                return dataclasses.replace(
                    alt, estimator=estimator, fit_seconds=alt.fit_seconds + res.fit_seconds, starts=res.starts,
                    compile_seconds=alt.compile_seconds + res.compile_seconds, messages=(*msgs, test.describe()),
                    info={**alt.info, **{k: res.info[k] for k in ("starts", "candidates") if k in res.info},
                          "positions_test": {**test.as_json(), "misfit": ratios},
                          "without_positions": {"params": {n: res.params[n] for n in names},
                                                "stderr": dict(res.stderr), "cost": res.cost,
                                                "covariance": np.asarray(res.covariance).tolist()}})
    say(test.describe())
    return dataclasses.replace(res, messages=tuple(drop) + (test.describe(),),
                               info={**res.info, "positions_test": {**test.as_json(), "misfit": ratios}})


def _assemble(model, spec, estimator, problem: Problem, s: Solved, priors, prior_note, messages, report,
              start_vals, label) -> FitResult:
    """Covariance, relabelling, identifiability, status and the result (module docstring)."""
    n_p = len(spec.free_names)
    z = np.asarray(s.z)
    J, r = np.asarray(s.J_data), np.asarray(s.r_data)
    n_rows = int(np.sum(r != 0)) if s.mask is None else int(np.sum(s.mask)) * s.n_channels
    dof = s.dof if s.dof is not None else max(n_rows - J.shape[1], 1)
    cov_all = covariance(J, r, dof=dof, involvement=0.05, kind=s.kind, mask=s.mask, n_channels=s.n_channels,
                         runs=s.run_names if s.mask is not None else (),
                         channels=tuple(s.channel_scales) if s.mask is not None else (),
                         input_meat=s.input_meat, input_noise=s.input_noise, variance=s.variance)
    msgs = list(messages) + list(s.messages)
    msgs.append(cov_all.describe())
    cov_info = cov_all.info()
    s2 = cov_all.residual_variance
    if s.J_extra.shape[0]:
        # posterior: (J_dᵀJ_d/σ̂² + J_eᵀJ_e)⁻¹ — prior and continuity rows have unit variance by construction
        cov_all = dataclasses.replace(
            covariance(np.vstack([J / math.sqrt(s2), s.J_extra]), np.concatenate([r / math.sqrt(s2), s.r_extra]),
                       variance=1.0, involvement=0.05,
                       input_meat=None if s.input_meat is None else s.input_meat / s2, input_noise=s.input_noise),
            residual_variance=s2)
        cov_info["covariance"] = "posterior (white data rows)" + ("+inputs" if s.input_meat is not None else "")
    result = as_diffship(s.result)
    names = [*spec.free_names, *problem.nuisance_names]
    if not cov_all.full_rank:
        msgs.append("not identifiable from these runs (Jacobian rank deficient; standard errors infinite): "
                    + ", ".join(names[i] if i < len(names) else f"unknown {i}" for i in cov_all.unidentifiable))
        if result == RESULTS.successful and any(i < n_p for i in cov_all.unidentifiable):
            result = RESULTS.not_identifiable
    scale = np.asarray([spec[n].scale for n in spec.free_names])
    cov = cov_all.matrix[:n_p, :n_p] * np.outer(scale, scale)
    theta = np.asarray(spec.full_values(jnp.asarray(z[:n_p]), model.theta()))
    values = {n: float(theta[i]) for i, n in enumerate(model.param_names)}
    swapped = model.canonical(values)
    if swapped != values:
        cov = relabelled(cov, values, swapped, spec.free_names)
        values = swapped
    stderr = {n: float(math.sqrt(cov[i, i])) if cov[i, i] >= 0 else math.nan for i, n in enumerate(spec.free_names)}
    if not getattr(estimator, "simulates", True) and result != RESULTS.simulation_blew_up:
        # an estimator that never simulates (equation error): does its estimate simulate the training runs?
        from ..simulate import simulate_run

        fitted = model.with_params(values)
        bad = [run.name for run, x0 in zip(problem.runs, s.initial_states)
               if not bool(np.all(np.asarray(simulate_run(fitted, run, x0).valid)))]
        if bad:
            result = RESULTS.simulation_blew_up
            msgs.append(f"the estimate's simulation blows up on training run(s) {', '.join(bad)}")
    ident = identifiability(J[:, :n_p] / math.sqrt(s2), spec, values, cov, start=start_vals, start_label=label,
                            priors=priors, reference=_reference(model))
    msgs.extend(ident.warnings)
    if result != RESULTS.successful:
        msgs.append(f"status: {message(result)}")
    info = {**s.info, **cov_info, "residual_variance": s2, "n_residuals": n_rows, "jacobian_rank": cov_all.rank,
            "n_unknowns": J.shape[1], "estimator": estimator.describe(),
            "priors": prior_table(priors, values, stderr, spec.free_names), "prior_source": priors.source,
            "prior_note": prior_note, "prior_cost": s.prior_cost, "identifiability": ident.as_json(),
            "starts": report.as_json()}
    return FitResult(
        method=estimator.method, model=model.with_params(values), params=values, stderr=stderr, free=spec.free_names,
        converged=result == RESULTS.successful, status=message(result), iterations=int(s.steps), cost=float(s.cost),
        fit_seconds=float(s.seconds), compile_seconds=float(problem.compile_seconds + s.compile_seconds),
        channels=tuple(s.channel_scales), channel_scales=dict(s.channel_scales), noise_std=dict(s.noise_std),
        initial_states=tuple(s.initial_states), run_names=tuple(s.run_names), covariance=cov,
        integrator=problem.state.get("integrator", getattr(estimator, "integrator", None)) or _default_integrator(),
        messages=tuple(msgs), info=info, result=result, starts=report, spec=spec, estimator=estimator)


def _default_integrator():
    from ..integrators import Diffrax

    return Diffrax()


def _failed(model, spec, estimator, problem, text, messages) -> FitResult:
    """The result of a fit that could not start (``throw=False``): the start values, unusable."""
    n = len(spec.free_names)
    return FitResult(
        method=estimator.method, model=model, params=model.param_values(), stderr={k: math.inf for k in spec.free_names},
        free=spec.free_names, converged=False, status=text, iterations=0, cost=math.inf, fit_seconds=0.0,
        compile_seconds=problem.compile_seconds, channels=problem.channels, run_names=tuple(r.name for r in problem.runs),
        covariance=np.full((n, n), np.inf), messages=tuple(messages) + (text,), info={"estimator": estimator.describe()},
        result=RESULTS.all_starts_blew_up, spec=spec, estimator=estimator)
