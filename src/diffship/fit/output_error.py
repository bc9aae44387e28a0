r"""Output error (simulation error), single shooting: the :class:`OutputError` estimator.

Minimise over the free parameters θ and every run's initial state :math:`x_{0}` (:mod:`diffship.initial`)

.. math::
    \sum_c \frac{N}{2\tau_c}\log\sum_{\text{runs},k}\big(\hat y_c(t_k;\theta, x_0) - y_c(t_k)\big)^2
    + \tfrac12\sum_{\text{runs}, s}\Big(\frac{x_{0,s} - y_s(t_0)}{\sigma_s}\Big)^2 + \text{priors}

— the likelihood with each channel's noise level unknown, on ``N/τ_c`` effective samples
(:func:`~diffship.fit.weights.concentrated_cost`) — where :math:`\hat y` is the whole-horizon simulation
(no differentiated data anywhere), heading errors are wrapped to (−π, π], each measured initial state is held
by its first sample within the sensor noise :math:`\sigma_s`, and the parameters live in a scaled unconstrained
space (:mod:`diffship.params`). It is solved as weighted least squares at self-consistent channel scales. The
residual, Jacobian and solver are the one output-error kernel (:mod:`diffship.fit.kernel`); everything a fit
shares with the other estimators (starts, priors, covariance, relabelling, status, result) is the driver's
(:func:`diffship.fit.fit`). The schedule:

1. **proposals**: with ``warmup``, every start fitted on the first part of every run (rounds of
   ``warmup_round`` steps, :mod:`diffship.fit.warmup`);
2. **whole-run candidates**, one per start, solved together, compared by the likelihood; the best ones
   refined at their self-consistent channel scales (:mod:`diffship.fit.search`);
3. a parameter stopped on a log-mapped bound is released by :func:`bound_escape`.

Priors (``priors``, ``reference_priors``; :mod:`diffship.fit.priors`) add one residual row per prior, so the
optimum is the MAP estimate and the standard errors are posterior ones; by default a model with a reference set
(MMG KVLCC2, USV, BlueROV2) carries its reference values as loose priors when the fixed particulars are the
reference vessel's. :func:`fit_output_error` is :func:`diffship.fit.fit` with this estimator.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from ..data import Run
from ..errors import FitError
from ..integrators import AbstractIntegrator, Diffrax
from ..models import AbstractModel
from ..params import ParamSpec
from ..preprocess import Filter
from ..progress import heartbeat
from . import status as st
from .driver import fit, fit_priors
from ..initial import channel_noise, cost_of_data_starts, estimated_states, start_prior
from .equation_error import equation_error_start
from .estimator import AbstractEstimator, Problem, Solved
from .identifiability import per_scale_columns
from .input_noise import meat_request, measured_input_meat
from .kernel import PENALTY, Kernel, kernel_data, stalled
from .priors import Priors, prior_arrays
from .problem import make_batch
from .result import FitResult
from .starts import spread_starts
from .search import DOMINATED, adaptive, bound_escape, root, candidates, objective_or_cost, reweighted_solves
from .warmup import warm_rounds, wrap_periodic
from .weights import channel_rms, channel_spread, correlation_time, x0_scales

__all__ = ["OutputError", "OutputErrorOptions", "bound_escape", "channel_rms", "channel_spread", "correlation_time",
           "fit_output_error", "fit_priors", "x0_scales"]


@dataclasses.dataclass(frozen=True)
class OutputError(AbstractEstimator):
    """Output error by single shooting (module docstring): the settings of the estimator.

    Attributes:
        estimate_x0: state names whose initial values are estimated per run (offsets from the
            measured values); ``"auto"`` (default): the one initial-state rule (:mod:`diffship.initial`),
            every state the fitted channels measure or depend on; ``()`` takes every initial state from
            the data as exact (``--x0 data``: a noisy first sample then biases the estimates).
        weights: ``"noise"`` (default: the likelihood with every channel's noise level unknown — each candidate
            solved at its self-consistent channel scales, :mod:`diffship.fit.search`) or ``"spread"`` (one solve
            at each channel's spread).
        channel_scales: fixed per-channel normalisation (overrides ``weights``).
        integrator: how simulations advance between samples (:mod:`diffship.integrators`).
        max_steps, rtol, atol: Levenberg–Marquardt limits and tolerances.
        gntol: a small step or a stalled cost ends the solve only when the Gauss–Newton step
            from there is shorter than ``gntol`` standard errors (:mod:`diffship.fit._lm`);
            ``inf``: the plain step/cost tests.
        flt: filter used to take initial states from the data.
        choose: ``"best"``: the driver's multi-start (every finite start's first solve, the lowest
            cost continues); ``"first"``: the first start whose simulation stays finite, alone.
        warmup: fraction of every run fitted first (growing horizon) when that is at least
            200 samples; ``0`` fits the whole runs from the start.
        priors: explicit priors (:class:`~diffship.fit.priors.Priors`), added to (and replacing)
            the reference ones.
        reference_priors: use the model's reference set as priors where it applies
            (:func:`~diffship.fit.priors.default_priors`); ``False`` is ``--no-prior``.
        prior_rel_sd: relative standard deviation of the reference priors.
        effective_samples: weight each channel's data by its effective sample size
            (:func:`~diffship.fit.weights.correlation_time`): autocorrelated residuals carry less information
            than their count says, and must not outvote a prior (the initial states' or the parameters').
        ee_start: the equation-error estimate is one of the starts, where the model has an
            equation-error form (:func:`~diffship.fit.equation_error.equation_error_start`).
        stall: ``(W, ρ)``: stop a solve early when its cost falls by less than ρ·cost over W
            steps while the Gauss–Newton step is still long (a mis-specified model crawls along a
            curved valley for hundreds of steps; :mod:`diffship.fit.batched`, item 6). The fit then
            reports ``RESULTS.cost_stalled`` (not converged) and says so. ``None`` (default): off.
        stall_ends_fit: with ``stall``, a whole-run round that stalls at settled channel scales ends the fit, where
            the search would start another round (:func:`~diffship.fit.search.reweighted_solves`): for a model known
            to lack terms (a discovery's base fit, whose crawl over 14 further rounds moved its cost by 0.13 %).
        warmup_round: the warm-up runs in rounds of this many Levenberg–Marquardt steps (the whole
            runs' compiled solve, with the warm-up's horizon and this step cap as data:
            :meth:`warm_data`; a start still running after a round goes on from where it is, up to
            ``max_steps`` in all). After each round, a start still running whose cost is above that of
            a start that has converged on the warm-up is stopped there (*dominated*: it goes on to no
            whole-run solve; the starts report says so, with its cost). Measured on the USV fit of
            ``benchmarks/timing``: three starts converged in 11–28 steps, the fourth (the model's reference
            values) crawled 67 steps to the same point (cost 5.2 after 30 steps against 4.29).
        adaptive: while fewer than two whole-run candidates reach the best point, more are drawn (the search's
            adaptive part, :func:`~diffship.fit.search.adaptive`). ``False``: the starts' candidates only — for a
            model incomplete by design, such as structure discovery's base model, whose rugged likelihood sends
            every draw elsewhere (on an independent USV missing four terms, the one draw re-converged in 250
            steps, 19 s, to the point the start had reached).
        x0_prior: an estimated initial state that a fitted channel measures is held by the measurement
            of its first sample: a Gaussian prior row centred on the raw first sample with the channel's
            sensor noise (:func:`diffship.initial.start_prior`); states no channel measures are free.
            ``False``: every estimated state free (it then soaks up model error: on the SSPA zigzag a
            yaw-rate offset of −0.46°/s, 2.7 noise standard deviations).
        positions: ``"test"`` (default): with the default channels, positions the runs measure are added where a
            Hausman test finds the fit with them agrees with the fit without (:mod:`diffship.fit.positions`); ``"off"``.
    """

    method = "output_error"

    estimate_x0: tuple[str, ...] | str = "auto"
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
    x0_prior: bool = True
    ee_start: bool = True
    stall: tuple[int, float] | None = None
    stall_ends_fit: bool = False
    warmup_round: int = 30
    adaptive: bool = True
    positions: str = "test"

    def __post_init__(self):
        if self.estimate_x0 != "auto":
            if isinstance(self.estimate_x0, str):
                raise FitError(f"estimate_x0 must be 'auto' or a sequence of state names, got {self.estimate_x0!r}")
            object.__setattr__(self, "estimate_x0", tuple(self.estimate_x0))
        if self.weights not in ("noise", "spread"):
            raise FitError(f"weights must be 'noise' or 'spread', got {self.weights!r}")
        if not self.gntol > 0:
            raise FitError(f"gntol must be a positive number of standard errors, got {self.gntol!r}")
        if not (int(self.warmup_round) == self.warmup_round and self.warmup_round >= 1):
            raise FitError(f"warmup_round must be a positive number of steps, got {self.warmup_round!r}")
        for name, allowed in (("positions", ("test", "off")), ("choose", ("best", "first"))):
            if getattr(self, name) not in allowed:
                raise FitError(f"{name} must be {' or '.join(map(repr, allowed))}, got {getattr(self, name)!r}")
        if self.stall is not None:
            w, rho = self.stall
            if not (int(w) == w and w >= 2 and 0 < rho < 1):
                raise FitError(f"stall must be (steps >= 2, relative cost decrease in (0, 1)), got {self.stall!r}")
            object.__setattr__(self, "stall", (int(w), float(rho)))

    def describe(self) -> str:
        return "output error"

    def x0_states(self, model: AbstractModel, channels: Sequence[str]) -> tuple[str, ...]:
        """The states whose initial values this fit estimates (``estimate_x0`` with ``"auto"`` resolved
        by :func:`diffship.initial.estimated_states`)."""
        return estimated_states(model, channels) if self.estimate_x0 == "auto" else tuple(self.estimate_x0)

    @property
    def warm_cap(self) -> int:
        """Steps of one warm-up round (``warmup_round``, at most ``max_steps``)."""
        return min(int(self.warmup_round), int(self.max_steps))

    @staticmethod
    def warm_data(data, n_warm: int, cap: int):
        """The first ``n_warm`` samples of ``data`` (a traced horizon) with a traced step cap of
        ``cap`` per solve: the whole runs' compiled solve runs the warm-up's rounds."""
        return data.head(n_warm).with_step_cap(cap)

    @property
    def lm(self) -> dict:
        lm = dict(max_steps=self.max_steps, rtol=self.rtol, atol=self.atol, gntol=float(self.gntol))
        if self.stall is not None:
            lm.update(stall_steps=self.stall[0], stall_rtol=self.stall[1])
        return lm

    # -- prepare -----------------------------------------------------------------------------------
    def programs(self, model: AbstractModel, runs: Sequence[Run], spec: ParamSpec, channels=None,
                 priors: Priors | None = None) -> list:
        """The compiled programs :meth:`prepare` needs, as :mod:`diffship.compiled` requests, without compiling them
        (:func:`diffship.compiled.prefetch`): they depend on the structure (model, free set, runs' shapes, channels,
        options), not on the values. ``priors``: the fit's (:func:`~diffship.fit.driver.fit_priors`; default none)."""
        kernel, data, z_shape, meat = self._setup(model, runs, spec, channels, priors or Priors({}, "none"))[:4]
        return kernel.requests([("residuals", z_shape, data, {}),
                                ("solve", z_shape, data, {"jacobian": True, **self.lm})]) + ([meat] if meat else [])

    def _setup(self, model: AbstractModel, runs: Sequence[Run], spec: ParamSpec, channels, priors: Priors):
        """``(kernel, data, z_shape, meat request, batch, est, start prior, spread, n_warm)`` of :meth:`prepare`."""
        o = self
        batch = make_batch(model, runs, channels, o.flt)
        est = o.x0_states(model, batch.channels)
        unknown = [s for s in est if s not in model.state_names]
        if unknown:
            raise FitError(f"estimate_x0: {', '.join(unknown)} are not states of model {model.name} "
                           f"({', '.join(model.state_names)})")
        n_p = len(spec.free_names)
        kernel = Kernel(spec=spec.structural(), out_idx=tuple(model.output_names.index(c) for c in batch.channels),
                        angle=tuple(c in model.angle_outputs for c in batch.channels),
                        x0_idx=tuple(model.state_names.index(s) for s in est), integrator=o.integrator)
        spread = channel_spread(batch)
        scales = np.asarray([o.channel_scales[c] for c in batch.channels]) if o.channel_scales else spread
        p_mean, p_w = prior_arrays(priors, spec)
        x0_scale = x0_scales(model, batch, est)
        x0_w = x0_m = None
        start = None
        if o.x0_prior and est:
            start = start_prior(model, batch.channels, batch.ys, batch.mask, batch.x0, est, x0_scale, ts=batch.ts)
            x0_w, x0_m = start.weight.reshape(-1), start.mean.reshape(-1)
        data = kernel_data(model, batch.ts, batch.us, batch.ys, batch.mask, batch.x0, scales, x0_scale=x0_scale,
                           prior_mean=p_mean, prior_w=p_w, x0_prior_w=x0_w, x0_prior_mean=x0_m)
        n_x0 = len(kernel.x0_idx) * len(runs)
        n_full = batch.ts.shape[1]
        n_warm = int(o.warmup * n_full) if o.warmup and o.warmup < 1 and o.warmup * n_full >= 200 else 0
        # the warm-up's horizon and the rounds' step cap are data (:class:`~diffship.fit.kernel.KernelData`): the
        # warm-up, the whole runs' rounds and the final solves share one compiled solve instead of compiling several
        data = data.with_horizon().with_step_cap() if n_warm else data.with_step_cap()
        z_shape = np.zeros(n_p + n_x0)
        # the full-horizon solve also returns the Jacobian at its solution (for the covariance), and
        # the input-noise covariance term's program where the measured inputs are noisy
        meat = meat_request(kernel, data, int(batch.mask.size) * len(batch.channels), n_p + n_x0)
        return kernel, data, z_shape, meat, batch, est, start, spread, n_warm

    def prepare(self, model: AbstractModel, runs: Sequence[Run], spec: ParamSpec, channels, priors: Priors,
                say: Callable[[str], None]) -> Problem:
        o = self
        kernel, data, z_shape, meat, batch, est, start, spread, n_warm = self._setup(model, runs, spec, channels,
                                                                                    priors)
        n_p, n_x0 = len(spec.free_names), len(kernel.x0_idx) * len(runs)
        x0_m = None if start is None else start.mean.reshape(-1)
        say(f"output error: compiling the fit of {model.name} ({n_p} parameters, {len(runs)} runs, "
            f"{batch.n_residuals} residuals, {o.integrator.describe()})...")
        lm = self.lm
        # the equation-error start is computed in a thread beside the compile: its Python work
        # (filtering, tracing) runs while XLA compiles the fit's programs without the interpreter
        ee_start = o.ee_start and o.choose == "best"
        with ThreadPoolExecutor(1) as pool:
            ee_job = pool.submit(equation_error_start, model, runs, spec) if ee_start else None
            (res_fn, solve_fn), compile_s = kernel.compiled_many(
                [("residuals", z_shape, data, {}), ("solve", z_shape, data, {"jacobian": True, **lm})],
                extra=[meat] if meat else [])
            if ee_job is not None and not ee_job.done():
                say("output error: the equation-error estimate as a start...")
            ee, note = ee_job.result() if ee_job is not None else (None, "")
        names = tuple(f"{s}(0) of run {n}" for n in batch.names for s in est)
        extra, notes = {}, []
        if ee_start:
            if ee is not None:
                extra["the equation-error estimate"] = ee
            notes += [note] if note else []
        return Problem(model=model, spec=spec, runs=tuple(runs), channels=batch.channels, n_nuisance=n_x0,
                       nuisance_names=names, priors=priors, compile_seconds=compile_s,
                       state=dict(kernel=kernel, data=data, batch=batch, res_fn=res_fn, solve_fn=solve_fn,
                                  n_warm=n_warm, spread=spread, integrator=o.integrator, x0_states=est,
                                  start_prior=start, noise=channel_noise(batch.ys, batch.mask),
                                  # every start begins at the measured first samples (the filtered ones carry the
                                  # zero-phase filter's edge error: 2.7 noise levels of r on a Nomoto zigzag)
                                  nuisance0=np.zeros(n_x0) if x0_m is None else np.asarray(x0_m),
                                  n_rows=batch.n_residuals, extra_starts=extra, start_notes=notes))

    # -- starts --------------------------------------------------------------------------------------
    def start_cost(self, problem: Problem, z: np.ndarray) -> float:
        st_ = problem.state
        r = np.asarray(st_["res_fn"](jnp.asarray(z), st_["data"]))
        cost = 0.5 * float(np.sum(r * r))
        if np.any(np.abs(st_["kernel"].split(r, st_["data"])[0]) >= PENALTY) or not math.isfinite(cost):
            return math.inf
        return cost

    def first_solves(self, problem: Problem, zs, say) -> list[tuple[np.ndarray, float, int]]:
        """The search (module docstring): proposals, whole-run candidates, the likelihood decides.

        Returns, per start, its best whole-run candidate ``(z, objective, steps)``: the objective is the
        concentrated likelihood :func:`~diffship.fit.weights.concentrated_cost`, on one scale for every
        candidate (the smallest correlation times among them)."""
        if self.choose == "first":
            zs = zs[:1]
        st_ = problem.state
        kernel, data, n_warm = st_["kernel"], st_["data"], st_["n_warm"]
        per = self.angle_periods(problem)
        zs = [wrap_periodic(np.asarray(z), per) for z in zs]
        n = len(zs)
        steps = [0] * n
        dominated: list[int] = []
        proposals: list[tuple[int, np.ndarray, float, bool]] = []  # (start, z, warm-up cost, converged there)
        if n_warm:
            # proposals: every start converged on the first part of every run (growing horizon)
            wdata = self.warm_data(data, n_warm, self.warm_cap)
            warm, dominated = warm_rounds(kernel, zs, wdata, {"jacobian": True, **self.lm}, int(self.max_steps), say,
                                          f"output error, first {n_warm} samples", cap=self.warm_cap)
            ok = int(jax.tree_util.tree_leaves(optx.RESULTS.successful)[0])
            for i, (zw, res, k, rw, *_) in enumerate(warm):
                steps[i] += int(k)
                zw = wrap_periodic(np.asarray(zw), per)
                if not math.isfinite(self.start_cost(problem, zw)):
                    continue
                rw = np.asarray(kernel.split(np.asarray(rw), wdata)[0])
                proposals.append((i, zw, 0.5 * float(rw @ rw),
                                  int(jax.tree_util.tree_leaves(res)[0]) == ok and i not in dominated))
        cands = candidates(zs, proposals, per)
        if n_warm:
            n_w = sum(1 for c in cands if c[2] == "warm-up point")
            say(f"output error: {len(cands)} whole-run candidate(s): {n_w} distinct point(s) of the warm-up on the first "
                f"{n_warm} samples, {len(cands) - n_w} start(s) as they are")
        mask = np.asarray(data.mask)
        reweight = self.weights == "noise" and not self.channel_scales
        first = st_["noise"] if reweight else np.asarray(data.scales)

        def solve(cs):
            return reweighted_solves(kernel, [c[1] for c in cs], data, first, {"jacobian": True, **self.lm},
                                     cap=int(self.max_steps), total=3 * int(self.max_steps), floor=1e-6 * st_["spread"],
                                     reweight=reweight, effective_samples=self.effective_samples, period=per,
                                     progress=say, label="output error, whole runs",
                                     stall_ends=self.stall is not None and self.stall_ends_fit)
        spec = problem.spec

        def more(best: dict, k: int, seed: int) -> list:  # spread around the best candidate and the first start
            around = [dict(zip(spec.free_names, map(float, spec.from_z(z[:problem.n_params])))) for z in (best["z"], zs[0])]
            vals = (spread_starts(spec, {**spec.values(), **around[0]}, k - k // 2, seed=101 + seed)
                    + spread_starts(spec, {**spec.values(), **around[1]}, k // 2, seed=201 + seed))
            zz = [wrap_periodic(problem.z_start(v), per) for v in vals]
            return [z for z in zz if math.isfinite(self.start_cost(problem, z))]
        n_more = n if reweight and self.choose == "best" and self.adaptive else 0
        cands, sols = adaptive(cands, solve(cands), solve, more, mask, n_more, say)
        good = [s_ for s_ in sols if not s_["blew_up"] and s_["merged_into"] is None]
        # one scale for every candidate: the smallest correlation time of each channel among them
        tau = np.min(np.stack([s_["tau"] for s_ in good]), axis=0) if good and reweight else None
        st_["tau"] = tau
        res = [(np.asarray(zs[i]), math.inf, steps[i]) for i in range(n)]
        cand_out = []
        for (i, _, kind), s_ in zip(cands, sols):
            src = root(sols, s_)
            f = math.inf if src["blew_up"] else objective_or_cost(src["r"], src["r_prior"], mask, src["r_scales"], tau)
            cand_out.append((i, kind, src["z"], f, src))
            if f < res[i][1]:
                res[i] = (src["z"], f, steps[i] + s_["steps"])
        st_["candidates"] = cand_out
        st_["dominated"] = tuple(dominated)  # the starts report says which (driver)
        st_["cost_tolerance"] = 0.5  # one standard error along one direction of the likelihood
        n_m = sum(1 for s_ in sols if s_["merged_into"] is not None)
        n_d = sum(1 for s_ in sols if s_.get("dominated"))
        kinds = {k: sum(1 for c in cands if c[2] == k) for k in ("warm-up point", "start", "spread around the best")}
        st_["search_note"] = (f"search: {len(cands)} whole-run candidate(s) ({kinds['warm-up point']} warm-up point(s), "
                              f"{kinds['start']} start(s) as they are, {kinds['spread around the best']} drawn as the "
                              f"search went on), each solved at its own channel scales; {n_m} reached another's point"
                              + (f", {n_d} stopped far behind the best (likelihood more than {DOMINATED:g} worse)"
                                 if n_d else ""))
        return res

    def angle_periods(self, problem: Problem) -> np.ndarray:
        """Per unknown, the period in the scaled fit space of an estimated initial angle (2π over its
        scale; 0 elsewhere): an initial heading 2π apart is the same start of the same run (the
        vector fields see ψ through cos ψ, sin ψ and angle residuals are wrapped) — four warm-ups of a
        USV fit reached one optimum, one of them with ψ(0) 2π from the others, at equal cost."""
        data, n_p = problem.state["data"], problem.n_params
        scale = np.asarray(data.x0_scale)
        est = problem.state["x0_states"]
        per_run = np.asarray([2 * math.pi / scale[i] if s in problem.model.angle_outputs else 0.0
                              for i, s in enumerate(est)])
        n_runs = problem.n_nuisance // max(len(est), 1) if est else 0
        return np.concatenate([np.zeros(n_p), np.tile(per_run, n_runs), np.zeros(problem.n_nuisance - per_run.size * n_runs)])

    def residuals(self, problem: Problem, z) -> np.ndarray:
        st_ = problem.state
        d = st_.get("final_data", st_["data"])
        return np.asarray(st_["kernel"].split(np.asarray(st_["res_fn"](jnp.asarray(z), d)), d)[0])

    # -- the rest of the schedule ---------------------------------------------------------------------
    def finish(self, problem: Problem, z: np.ndarray, steps: int, say) -> Solved:
        o = self
        st_ = problem.state
        kernel, data, batch, res_fn, solve_fn = (st_[k] for k in ("kernel", "data", "batch", "res_fn", "solve_fn"))
        spec, model = problem.spec, problem.model
        n_p = problem.n_params
        scales = np.asarray(data.scales)
        messages: list[str] = []
        passes, steps_per_pass, last_jac = [], [steps], []

        def run_solve(z, d):
            with heartbeat(say, "output error, refining"):
                z, result, k, r, *jac = solve_fn(jnp.asarray(z), d)
                jax.block_until_ready(z)
            passes.append(result)
            steps_per_pass.append(int(k))
            last_jac[:] = jac
            return z, np.asarray(kernel.split(np.asarray(r), d)[0])

        t0 = time.perf_counter()
        tau = st_.get("tau")
        chosen = next((c[4] for c in st_.get("candidates", ()) if np.allclose(c[2], z, rtol=0, atol=0)), None)
        if chosen is not None and chosen["jac"] is not None:
            # the search solved this candidate at its own channel scales: its point, residuals and Jacobian
            z, r, scales = np.asarray(chosen["z"]), chosen["r"], chosen["r_scales"]
            data = data.replace(scales=jnp.asarray(scales))
            passes.append(chosen["status"])
            last_jac[:] = [chosen["jac"]]
            if tau is not None:
                # reported at the chosen point's own correlation times (the search compared the candidates at
                # their smallest: a number that depends on which other candidates there were)
                tau = chosen["tau"]
                st_["objective"] = objective_or_cost(r, chosen["r_prior"], np.asarray(batch.mask), scales, tau)
        else:
            # the first solve's point again, with its Jacobian (one compiled program: no extra compile)
            z, r = run_solve(z, data)
        if st_.get("search_note"):
            messages.append(st_["search_note"])
        taus = [tau] if tau is not None else []
        # -- a parameter pinned on a log-mapped bound: LM again from the Gauss–Newton step in θ ----------
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
                kept = (z, r, list(passes), list(last_jac), list(steps_per_pass))
                # from a point near the optimum: a quarter of the step cap (a longer solve is a crawl along a ridge)
                z_try, r_try = run_solve(z_new, data.with_step_cap(max(int(o.max_steps) // 4, 10)))
                r_full = np.asarray(res_fn(jnp.asarray(z_try), data))
                if (np.all(np.isfinite(r_full)) and r_full @ r_full < r_old @ r_old
                        and not np.any(kernel.split(r_full, data)[0] == PENALTY)):
                    messages.append(f"LM stopped with the Gauss–Newton step in the parameters {length:.2g} standard "
                                    f"errors long (a parameter on a bound); LM again from that step: cost "
                                    f"{0.5 * float(r_old @ r_old):.6g} → {0.5 * float(r_full @ r_full):.6g}")
                    z, r = z_try, r_try
                else:  # keep the point LM stopped at (the steps tried are counted)
                    z, r, passes[:], last_jac[:] = kept[0], kept[1], kept[2], kept[3]
                    break
        jax.block_until_ready(z)
        fit_s = time.perf_counter() - t0
        z = np.asarray(z)
        st_["final_data"] = data
        col = per_scale_columns(spec, z, n_p + problem.n_nuisance)
        J, J_prior = kernel.split(np.asarray(last_jac[0]) * col, data)
        n_pw = int(data.prior_w.shape[0])  # the parameters' prior rows (the initial states' follow: not in the covariance)
        J_prior = J_prior[:n_pw]
        # noise on measured inputs is propagated (errors in variables)
        meat, sigma_u, c = measured_input_meat(kernel, z, data, J, batch.mask, model.input_names)
        result = st.as_diffship(passes[-1])
        if o.stall is not None and stalled(passes[-1], steps_per_pass[-1], o.max_steps):
            result = st.RESULTS.cost_stalled
            messages.append(f"stopped early: the cost fell by less than {o.stall[1]:.0e} of itself over "
                            f"{o.stall[0]} steps (a crawl; not converged)")
        if np.any(r == PENALTY):  # the kernel marks every sample after a blow-up exactly
            result = st.RESULTS.simulation_blew_up
        noise = channel_rms(r, batch.mask, scales)
        if not st_["x0_states"] and estimated_states(model, batch.channels):  # --x0 data: say what it costs
            note = cost_of_data_starts(kernel.model_at(jnp.asarray(z), data), problem.runs, batch.channels,
                                       dict(zip(batch.channels, scales)), flt=o.flt, integrator=o.integrator)
            messages.extend([note] if note else [])
        prior_rows = np.asarray(kernel.split(np.asarray(res_fn(jnp.asarray(z), data)), data)[1])
        x0_rows, prior_rows = prior_rows[n_pw:], prior_rows[:n_pw]
        x0_fit = np.asarray(kernel.initial_states(jnp.asarray(z), data))
        return Solved(
            z=z, r_data=r, J_data=J, J_extra=J_prior, r_extra=prior_rows, result=result, steps=sum(steps_per_pass),
            seconds=fit_s, compile_seconds=c, cost=0.5 * float(np.sum(r * r)),
            channel_scales={ch: float(s) for ch, s in zip(batch.channels, scales)},
            noise_std={ch: float(s) for ch, s in zip(batch.channels, noise)}, initial_states=tuple(x0_fit),
            run_names=batch.names, variance=1.0 if (taus and n_pw) else None, dof=batch.n_residuals - J.shape[1], kind="auto",
            mask=batch.mask, n_channels=len(batch.channels), input_meat=meat, input_noise=sigma_u,
            prior_cost=0.5 * float(np.sum(prior_rows ** 2)), messages=tuple(messages),
            info={"weights": o.weights, "integrator": o.integrator.describe(), "steps_per_pass": tuple(steps_per_pass),
                  "warmup_samples": st_["n_warm"], "estimate_x0": st_["x0_states"],
                  "x0_prior_cost": 0.5 * float(np.sum(x0_rows ** 2)), "objective": st_.get("objective"),
                  "start_prior": st_["start_prior"].describe() if st_.get("start_prior") is not None else None,
                  "candidates": [{"start": int(i), "from": kind, "objective": float(f)}
                                 for i, kind, _, f, _ in st_.get("candidates", ())],
                  "correlation_time": ({ch: float(t) for ch, t in zip(batch.channels, taus[-1])} if taus else None)})


#: The earlier name of the output-error settings (the estimator is its own settings object).
OutputErrorOptions = OutputError


def fit_output_error(
    model: AbstractModel,
    runs: Sequence[Run],
    *,
    spec: ParamSpec | None = None,
    starts: Sequence[Mapping[str, float]] | Mapping[str, Mapping[str, float]] = (),
    channels: Sequence[str] | None = None,
    options: OutputError = OutputError(),
    progress: Callable[[str], None] | None = None,
    init: Mapping[str, float] | None = None,
    n_starts: int | None = None,
    throw: bool = True,
) -> FitResult:
    """Fit ``model`` to ``runs`` by output error: :func:`diffship.fit.fit` with ``options`` as the estimator."""
    return fit(model, runs, options, spec=spec, init=init, starts=starts, n_starts=n_starts, channels=channels,
               progress=progress, throw=throw)
