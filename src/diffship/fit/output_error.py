r"""Output error (simulation error), single shooting: the :class:`OutputError` estimator.

Minimise over the free parameters θ (and optionally per-run initial states)

.. math::
    \tfrac12 \sum_{\text{runs}}\sum_k\sum_c \Big(\frac{\hat y_c(t_k;\theta) - y_c(t_k)}{s_c}\Big)^2

where :math:`\hat y` is the whole-horizon simulation from the run's initial state (no
differentiated data anywhere), ``s_c`` normalises each channel, heading errors are wrapped to
(−π, π], and the parameters live in a scaled unconstrained space (:mod:`diffship.params`).
The residual, Jacobian and solver are the one output-error kernel (:mod:`diffship.fit.kernel`).
Everything a fit shares with the other estimators (starts, priors, covariance, relabelling,
status, result) is the driver's (:func:`diffship.fit.fit`); this module says how the residuals
are assembled and which schedule of solves runs:

1. **first solve** (from every start together, :meth:`~diffship.fit.kernel.Kernel.solve_many`):
   with ``warmup``, the first part of every run (growing horizon: cheap steps, and a short
   horizon keeps LM out of the local minima of long simulations), then the whole runs, with
   ``s_c`` = the signal spread of each channel;
2. with ``weights="noise"`` (default), each channel's residual RMS ``σ_c`` is estimated (from the first
   part of the runs of the best start after a warm-up, the same weights for every start; else from the
   whole runs) and the fit solved again with ``s_c = σ_c`` — the maximum-likelihood weighting for white Gaussian channel
   noise, under which the Gauss–Newton covariance ``σ̂²(JᵀJ)⁻¹`` is an honest standard error;
3. with priors and ``effective_samples``, each channel's data are weighted by their effective
   sample size ``N/τ_c`` (:func:`~diffship.fit.weights.correlation_time`) and solved again;
4. a parameter stopped on a log-mapped bound is released by :func:`bound_escape`.

Priors (``priors``, ``reference_priors``; :mod:`diffship.fit.priors`) add one residual row per
prior, so the optimum is the MAP estimate and the standard errors are posterior ones; by default a
model with a reference set (MMG KVLCC2, USV, BlueROV2) carries its reference values as loose priors
when the fixed particulars are the reference vessel's.

:func:`fit_output_error` is :func:`diffship.fit.fit` with this estimator (its earlier signature).
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

from ..data import Run
from ..errors import FitError
from ..integrators import AbstractIntegrator, Diffrax
from ..models import AbstractModel
from ..params import ParamSpec
from ..preprocess import Filter
from ..progress import heartbeat
from . import status as st
from .driver import fit, fit_priors
from .equation_error import equation_error_start
from .estimator import AbstractEstimator, Problem, Solved
from .identifiability import per_scale_columns
from .input_noise import input_noise_levels, meat_request, measured_input_meat
from .kernel import PENALTY, Kernel, kernel_data, stalled
from .priors import Priors, prior_arrays
from .problem import make_batch
from .result import FitResult
from .warmup import same_points, warm_rounds, wrap_periodic
from .weights import channel_rms, channel_spread, correlation_time, x0_scales

__all__ = ["OutputError", "OutputErrorOptions", "bound_escape", "channel_rms", "channel_spread", "correlation_time",
           "fit_output_error", "fit_priors", "x0_scales"]


@dataclasses.dataclass(frozen=True)
class OutputError(AbstractEstimator):
    """Output error by single shooting (module docstring): the settings of the estimator.

    Attributes:
        estimate_x0: state names whose initial values are estimated per run (offsets from the
            measured values); ``()`` takes every initial state from the data.
        weights: ``"noise"`` (two passes, noise-normalised) or ``"spread"`` (one pass).
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
        effective_samples: with priors, weight each channel's data by its effective sample size
            (:func:`~diffship.fit.weights.correlation_time`): autocorrelated residuals carry less
            information than their count says, and must not outvote a prior. No effect without priors.
        ee_start: the equation-error estimate is one of the starts, where the model has an
            equation-error form (:func:`~diffship.fit.equation_error.equation_error_start`).
        stall: ``(W, ρ)``: stop a solve early when its cost falls by less than ρ·cost over W
            steps while the Gauss–Newton step is still long (a mis-specified model crawls along a
            curved valley for hundreds of steps; :mod:`diffship.fit.batched`, item 6). The fit then
            reports ``RESULTS.cost_stalled`` (not converged) and says so. ``None`` (default): off.
        warmup_round: the warm-up runs in rounds of this many Levenberg–Marquardt steps (the whole
            runs' compiled solve, with the warm-up's horizon and this step cap as data:
            :meth:`warm_data`; a start still running after a round goes on from where it is, up to
            ``max_steps`` in all). After each round, a start still running whose cost is above that of
            a start that has converged on the warm-up is stopped there (*dominated*: it goes on to no
            whole-run solve; the starts report says so, with its cost). Measured on the USV fit of
            ``benchmarks/timing``: three starts converged in 11–28 steps, the fourth (the model's reference
            values) crawled 67 steps to the same point (cost 5.2 after 30 steps against 4.29).
        x0_prior: an estimated initial state moves from the measured (filtered) one only within its
            noise: a Gaussian prior row on each offset with the standard deviation of the channel's
            sample noise (robust second-difference estimate, at least 1 % of its spread) where the state
            is a fitted channel, and one spread of its channel where it is not measured. Without it the
            offsets are free and soak up model error (measured on the SSPA zigzag: a yaw-rate offset of
            −0.46°/s, 2.7 noise standard deviations, and a fit judged from the measured start 3.5× worse).
    """

    method = "output_error"

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
    x0_prior: bool = False
    ee_start: bool = True
    stall: tuple[int, float] | None = None
    warmup_round: int = 30

    def __post_init__(self):
        object.__setattr__(self, "estimate_x0", tuple(self.estimate_x0))
        if self.weights not in ("noise", "spread"):
            raise FitError(f"weights must be 'noise' or 'spread', got {self.weights!r}")
        if not self.gntol > 0:
            raise FitError(f"gntol must be a positive number of standard errors, got {self.gntol!r}")
        if not (int(self.warmup_round) == self.warmup_round and self.warmup_round >= 1):
            raise FitError(f"warmup_round must be a positive number of steps, got {self.warmup_round!r}")
        if self.choose not in ("best", "first"):
            raise FitError(f"choose must be 'best' or 'first', got {self.choose!r}")
        if self.stall is not None:
            w, rho = self.stall
            if not (int(w) == w and w >= 2 and 0 < rho < 1):
                raise FitError(f"stall must be (steps >= 2, relative cost decrease in (0, 1)), got {self.stall!r}")
            object.__setattr__(self, "stall", (int(w), float(rho)))

    def describe(self) -> str:
        return "output error"

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
    def prepare(self, model: AbstractModel, runs: Sequence[Run], spec: ParamSpec, channels, priors: Priors,
                say: Callable[[str], None]) -> Problem:
        o = self
        unknown = [s for s in o.estimate_x0 if s not in model.state_names]
        if unknown:
            raise FitError(f"estimate_x0: {', '.join(unknown)} are not states of model {model.name} "
                           f"({', '.join(model.state_names)})")
        batch = make_batch(model, runs, channels, o.flt)
        n_p = len(spec.free_names)
        kernel = Kernel(spec=spec.structural(), out_idx=tuple(model.output_names.index(c) for c in batch.channels),
                        angle=tuple(c in model.angle_outputs for c in batch.channels),
                        x0_idx=tuple(model.state_names.index(s) for s in o.estimate_x0), integrator=o.integrator)
        spread = channel_spread(batch)
        scales = np.asarray([o.channel_scales[c] for c in batch.channels]) if o.channel_scales else spread
        p_mean, p_w = prior_arrays(priors, spec)
        x0_scale = x0_scales(model, batch, o.estimate_x0)
        x0_w = None
        if o.x0_prior and o.estimate_x0:
            noise = np.sqrt(np.maximum(np.diag(input_noise_levels(batch.ys, batch.mask)), 0.0))
            dt = float(np.median(np.diff(batch.ts[0, : batch.lengths[0]])))
            rate_of = getattr(model, "STATE_RATE_OF", {})

            def sd(s_):
                if s_ in batch.channels:
                    j = batch.channels.index(s_)
                    return max(noise[j], 1e-2 * spread[j])
                if rate_of.get(s_) in batch.channels:  # the rate of a channel: a numerical derivative's noise
                    j = batch.channels.index(rate_of[s_])
                    return math.sqrt(2.0) * max(noise[j], 1e-2 * spread[j]) / dt
                return None

            w = [x0_scale[i] / sd(s_) if sd(s_) else 1.0 for i, s_ in enumerate(o.estimate_x0)]
            x0_w = np.tile(np.asarray(w, dtype=np.float64), len(runs))
        data = kernel_data(model, batch.ts, batch.us, batch.ys, batch.mask, batch.x0, scales, x0_scale=x0_scale,
                           prior_mean=p_mean, prior_w=p_w, x0_prior_w=x0_w)
        n_x0 = len(kernel.x0_idx) * len(runs)
        n_full = batch.ts.shape[1]
        n_warm = int(o.warmup * n_full) if o.warmup and o.warmup < 1 and o.warmup * n_full >= 200 else 0
        if n_warm:
            # the warm-up's horizon and its rounds' step cap are data (:class:`~diffship.fit.kernel.KernelData`):
            # the warm-up and the whole runs share one compiled solve instead of compiling two
            data = data.with_horizon().with_step_cap()
        z_shape = np.zeros(n_p + n_x0)
        say(f"output error: compiling the fit of {model.name} ({n_p} parameters, {len(runs)} runs, "
            f"{batch.n_residuals} residuals, {o.integrator.describe()})...")
        # the full-horizon solve also returns the Jacobian at its solution (for the covariance), and
        # the input-noise covariance term's program where the measured inputs are noisy
        meat = meat_request(kernel, data, int(batch.mask.size) * len(batch.channels), n_p + n_x0)
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
        names = tuple(f"{s}(0) of run {n}" for n in batch.names for s in o.estimate_x0)
        extra, notes = {}, []
        if ee_start:
            if ee is not None:
                extra["the equation-error estimate"] = ee
            notes += [note] if note else []
        return Problem(model=model, spec=spec, runs=tuple(runs), channels=batch.channels, n_nuisance=n_x0,
                       nuisance_names=names, priors=priors, compile_seconds=compile_s,
                       state=dict(kernel=kernel, data=data, batch=batch, res_fn=res_fn, solve_fn=solve_fn,
                                  n_warm=n_warm, spread=spread, integrator=o.integrator,
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
        if self.choose == "first":
            zs = zs[:1]
        st_ = problem.state
        kernel, data, n_warm = st_["kernel"], st_["data"], st_["n_warm"]
        zs = [np.asarray(z) for z in zs]
        steps = [0] * len(zs)
        dominated: list[int] = []
        if n_warm:
            # Growing horizon: converge on the first part of every run, then the whole runs (a fit on
            # the first part that blows up on the whole runs is dropped: that start goes on from itself)
            wdata = self.warm_data(data, n_warm, self.warm_cap)
            warm, dominated = warm_rounds(kernel, zs, wdata, {"jacobian": True, **self.lm}, int(self.max_steps), say,
                                          f"output error, first {n_warm} samples", cap=self.warm_cap)
            if dominated:
                say(f"output error: start(s) {', '.join(str(i + 1) for i in dominated)} stopped on the first {n_warm} "
                    "samples: still running, above the cost of a start that had converged there")
            best_w = None
            for i, (zw, _, k, rw, *_) in enumerate(warm):
                steps[i] += int(k)
                if math.isfinite(self.start_cost(problem, np.asarray(zw))):
                    zs[i] = np.asarray(zw)
                    rw = np.asarray(kernel.split(np.asarray(rw), wdata)[0])
                    if best_w is None or rw @ rw < best_w @ best_w:
                        best_w = rw
            if best_w is not None and self.weights == "noise" and not self.channel_scales:
                # the noise weights from the best start's first part, the same for every start (costs stay
                # comparable) — the noise pass of the whole runs is then not repeated
                batch = st_["batch"]
                sigma = channel_rms(best_w, np.asarray(wdata.mask), np.asarray(data.scales))
                data = data.replace(scales=jnp.asarray(np.maximum(sigma, 1e-6 * st_["spread"])))
                st_["data"], st_["noise_done"] = data, True
            say(f"output error: first {n_warm} samples of each run fitted ({', '.join(map(str, steps))} steps); "
                "now the whole runs")
        # starts the warm-up brought to the same point (same cost, same unknowns) are one problem on the
        # whole runs: solved once (four starts of a USV fit all reached one optimum on the first quarter,
        # and each then ran 200 identical steps on the whole runs)
        # an initial angle a whole turn from the logged one is the same start: taken back to the branch
        # nearest the log (same cost; the reported start is the measured heading's)
        per = self.angle_periods(problem)
        zs = [wrap_periodic(z, per) for z in zs]
        w_costs = [self.start_cost(problem, z) for z in zs] if n_warm else []
        live = [i for i in range(len(zs)) if i not in dominated]
        rep_live = same_points([zs[i] for i in live], [w_costs[i] for i in live], period=per) if n_warm \
            else list(range(len(live)))
        rep = {i: live[j] for i, j in zip(live, rep_live)}
        uniq = sorted(set(rep.values()))
        if len(uniq) < len(live):
            say(f"output error: {len(live) - len(uniq)} start(s) reached the same point as another on the first "
                f"{n_warm} samples: {len(uniq)} whole-run solve(s)")
        solved = kernel.solve_many(np.stack([zs[i] for i in uniq]), data, jacobian=True, progress=say,
                                   label="output error", **self.lm)
        res = []
        for i in range(len(zs)):
            if i in dominated:  # stopped on the warm-up: its whole-run cost where it stopped
                res.append((np.asarray(zs[i]), w_costs[i], steps[i]))
                continue
            z, _, k, r, *_ = solved[uniq.index(rep[i])]
            r = np.asarray(r)
            bad = np.any(np.abs(kernel.split(r, data)[0]) >= PENALTY) or not np.all(np.isfinite(r))
            res.append((np.asarray(z), math.inf if bad else 0.5 * float(r @ r), steps[i] + int(k)))
        problem.state["dominated"] = tuple(dominated)  # the starts report says which (driver)
        return res

    def angle_periods(self, problem: Problem) -> np.ndarray:
        """Per unknown, the period in the scaled fit space of an estimated initial angle (2π over its
        scale; 0 elsewhere): an initial heading 2π apart is the same start of the same run (the
        vector fields see ψ through cos ψ, sin ψ and angle residuals are wrapped) — four warm-ups of a
        USV fit reached one optimum, one of them with ψ(0) 2π from the others, at equal cost."""
        data, n_p = problem.state["data"], problem.n_params
        scale = np.asarray(data.x0_scale)
        per_run = np.asarray([2 * math.pi / scale[i] if s in problem.model.angle_outputs else 0.0
                              for i, s in enumerate(self.estimate_x0)])
        n_runs = problem.n_nuisance // max(len(self.estimate_x0), 1) if self.estimate_x0 else 0
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
        spread = st_["spread"]
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
        # the first solve's point again, with its Jacobian (one compiled program: no extra compile)
        z, r = run_solve(z, data)
        taus: list[np.ndarray] = []
        if o.weights == "noise" and not o.channel_scales:
            if not st_.get("noise_done"):
                # floor: on noise-free data the residuals are round-off, which must not set the weights
                scales = np.maximum(channel_rms(r, batch.mask, scales), 1e-6 * spread)
                data = data.replace(scales=jnp.asarray(scales))
                z, r = run_solve(z, data)
            if data.prior_w.shape[0] and o.effective_samples:
                # data weight of an effective sample size N/τ_c (τ from the noise-weighted residuals)
                taus.append(correlation_time(r, batch.mask, len(batch.channels)))
                scales = scales * np.sqrt(taus[-1])
                data = data.replace(scales=jnp.asarray(scales))
                z, r = run_solve(z, data)
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
                z_try, r_try = run_solve(z_new, data)
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
        if np.any(np.abs(r) >= PENALTY):
            result = st.RESULTS.simulation_blew_up
        noise = channel_rms(r, batch.mask, scales)
        prior_rows = np.asarray(kernel.split(np.asarray(res_fn(jnp.asarray(z), data)), data)[1])
        x0_rows, prior_rows = prior_rows[n_pw:], prior_rows[:n_pw]
        x0_fit = np.asarray(kernel.initial_states(jnp.asarray(z), data))
        return Solved(
            z=z, r_data=r, J_data=J, J_extra=J_prior, r_extra=prior_rows, result=result, steps=sum(steps_per_pass),
            seconds=fit_s, compile_seconds=c, cost=0.5 * float(np.sum(r * r)),
            channel_scales={ch: float(s) for ch, s in zip(batch.channels, scales)},
            noise_std={ch: float(s) for ch, s in zip(batch.channels, noise)}, initial_states=tuple(x0_fit),
            run_names=batch.names, variance=1.0 if taus else None, dof=batch.n_residuals - J.shape[1], kind="auto",
            mask=batch.mask, n_channels=len(batch.channels), input_meat=meat, input_noise=sigma_u,
            prior_cost=0.5 * float(np.sum(prior_rows ** 2)), messages=tuple(messages),
            info={"weights": o.weights, "integrator": o.integrator.describe(), "steps_per_pass": tuple(steps_per_pass),
                  "warmup_samples": st_["n_warm"], "estimate_x0": o.estimate_x0,
                  "x0_prior_cost": 0.5 * float(np.sum(x0_rows ** 2)),
                  "correlation_time": ({ch: float(t) for ch, t in zip(batch.channels, taus[-1])} if taus else None)})


#: The earlier name of the output-error settings (the estimator is its own settings object).
OutputErrorOptions = OutputError


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
    options: OutputError = OutputError(),
    progress: Callable[[str], None] | None = None,
    init: Mapping[str, float] | None = None,
    n_starts: int | None = None,
    throw: bool = True,
) -> FitResult:
    """Fit ``model`` to ``runs`` by output error: :func:`diffship.fit.fit` with ``options`` as the
    estimator (see there for ``starts``, ``init``, ``n_starts``, ``throw``)."""
    return fit(model, runs, options, spec=spec, init=init, starts=starts, n_starts=n_starts, channels=channels,
               progress=progress, throw=throw)
