r"""Multiple-shooting output error: short segments with free initial states, continuity as residuals.

Single-shooting output error (:mod:`diffship.fit.output_error`) simulates every run from its
first sample to its last. From a poor start, a course-unstable ship's simulation runs away
long before the end of a zigzag and Levenberg–Marquardt stalls in a local minimum. Multiple
shooting (Bock & Plitt 1984) cuts each run into segments of ``L`` sample intervals, simulates
every segment from its own initial state :math:`s_{ij}` (run *i*, segment *j*) and asks for
continuity in the residual rather than by construction:

.. math::
    \min_{\theta, s}\ \tfrac12 \sum_{ij}\sum_{k}\sum_c
        \Big(\frac{\hat y_c(t_{ijk}; \theta, s_{ij}) - y_{ijk c}}{s_c}\Big)^2
    + \tfrac12\,\mu^2 \sum_{i, j}\Big\lVert \frac{x(t_{i,j+1,0}^-; \theta, s_{ij}) - s_{i,j+1}}{\sigma_x}\Big\rVert^2

with :math:`\sigma_x` the spread of the channel each state shows up in (the scale of the
initial-state unknowns of the one kernel, :func:`~diffship.fit.output_error.x0_scales`). The
first segment of each run starts, like single shooting, from the measured state plus offsets
of the estimated states ``estimate_x0``; later segments have every state free, started from
the filtered measurements at the segment start (:func:`diffship.simulate.initial_state` on
the run from there on; unmeasured states from the model's rule). All segments have equal
length (the last one is padded and masked), so the simulation is one ``jax.vmap`` over
``runs × segments``: the one kernel's simulation with segments in place of runs.

**Continuity.** An increasing penalty :math:`\mu \in` ``penalties`` (default 1, 10, 100,
1000, 10⁴), each stage a Levenberg–Marquardt solve warm-started from the last, drives the defects
to zero; the penalty is data, not structure, so every stage reuses one compiled solve. With
``weights="noise"`` the channels are then re-weighted by their residual RMS, as single shooting
does, and the last stage is solved again (so both minimise the same weighted cost; skipped before a
polish, which re-weights as single shooting does). Then
(``polish=True``, default) the single-shooting fit is run from the multiple-shooting estimate,
so the result *is* the single-shooting optimum (its covariance, report and checks), reached
from a start that single shooting alone may not get to. The check that the multiple-shooting
stage ends where single shooting does when the model is right is in
``tests/fit/test_shooting.py`` (noise-free and noisy data, ``polish=False``).

Everything else is the one kernel's (:class:`~diffship.fit.kernel.Kernel` subclassed): the
parameter map, bounds and scaling, the prior rows, the Levenberg–Marquardt solve and the
compile cache. The unknowns are ``(z_θ, s)``. Differentiated as one function, the forward-mode
Jacobian would push one tangent per segment state through every segment (a step about
``n_x·segments/(n_θ + n_x0)`` times a single-shooting step); since a segment depends only on
``z_θ`` and its own initial state, :class:`ShootingKernel` assembles it from per-segment blocks
with ``n_θ + n_x`` tangents each (measured on the KVLCC2 zigzags, 2 × 90 s, 10 s segments,
114 unknowns: 0.10 s against 0.42 s per Jacobian, same process, shared 2-core machine).

Reference: H. G. Bock and K. J. Plitt, "A multiple shooting algorithm for direct solution of
optimal control problems", IFAC Proceedings 17(2), 1984; J. Ribeiro et al., "Multiple shooting
for training neural differential equations on time series", IEEE Control Systems Letters 2021.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Mapping, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from ..data import Run
from ..errors import FitError
from ..models import AbstractModel
from ..params import ParamSpec
from ..simulate import initial_state, simulate
from . import status as st
from .driver import fit
from .estimator import OnOutputError, Problem, Solved
from .identifiability import per_scale_columns
from .kernel import PENALTY, Kernel, KernelData, kernel_data, wrap_angle
from .output_error import OutputErrorOptions
from .priors import prior_arrays
from .problem import make_batch
from .result import FitResult
from .weights import channel_rms, channel_spread, x0_scales

__all__ = ["MultipleShooting", "ShootingOptions", "ShootingKernel", "ShootingData", "fit_multiple_shooting", "parse_shooting"]


@dataclasses.dataclass(frozen=True)
class ShootingOptions:
    """How the multiple-shooting stage is run.

    Attributes:
        segment_s: segment length [s] (converted to samples with the median sample interval).
        penalties: increasing continuity weights μ, one Levenberg–Marquardt solve each.
        polish: finish with the single-shooting fit from the multiple-shooting estimate.
        max_steps: Levenberg–Marquardt steps per penalty stage.
        stage_ftol: before a polish, a stage also ends when an accepted step lowers its cost by
            less than ``stage_ftol·cost`` (the stages only have to bring the parameters into the
            single-shooting basin; the polish converges to the optimum with the full tests).
            Without a polish the stages use the single-shooting tolerances.
    """

    segment_s: float = 20.0
    penalties: tuple[float, ...] = (1.0, 10.0, 100.0, 1e3, 1e4)
    polish: bool = True
    max_steps: int = 100
    stage_ftol: float = 1e-6

    def __post_init__(self):
        if not (math.isfinite(self.segment_s) and self.segment_s > 0):
            raise FitError(f"multiple shooting: the segment length must be a positive number of seconds, "
                           f"got {self.segment_s!r}")
        object.__setattr__(self, "penalties", tuple(float(p) for p in self.penalties))
        if not self.penalties or any(not (p > 0 and math.isfinite(p)) for p in self.penalties):
            raise FitError(f"multiple shooting: penalties must be positive numbers, got {self.penalties!r}")
        if not (0 <= self.stage_ftol < 1):
            raise FitError(f"multiple shooting: stage_ftol must be in [0, 1), got {self.stage_ftol!r}")


def parse_shooting(text: str) -> ShootingOptions | None:
    """``"single"`` → ``None``; ``"multiple"`` or ``"multiple:SEGMENT_S"`` → :class:`ShootingOptions`."""
    kind, _, arg = text.partition(":")
    if kind == "single" and not arg:
        return None
    if kind != "multiple":
        raise FitError(f"--shooting {text!r}: use 'single', 'multiple' or 'multiple:SEGMENT_S' (e.g. multiple:20)")
    if not arg:
        return ShootingOptions()
    try:
        return ShootingOptions(segment_s=float(arg))
    except ValueError:
        raise FitError(f"--shooting {text!r}: {arg!r} is not a segment length in seconds") from None


class ShootingData(KernelData):
    """:class:`~diffship.fit.kernel.KernelData` over segments (rows ``run·S + j``) plus the
    shooting arrays.

    Attributes:
        free_row, free_col: segment row and state index of each free initial-state unknown.
        state_scale: scale of each state's unknowns and defects ``(n_x,)``.
        defect_mask: whether segment ``j + 1`` of run ``i`` exists ``(R, S − 1)``.
        weight: the continuity weight μ (scalar).
    """

    free_row: Int[Array, " n_s"]
    free_col: Int[Array, " n_s"]
    state_scale: Float[Array, " n_x"]
    defect_mask: Bool[Array, "R Sm1"]
    weight: Float[Array, ""]


class ShootingKernel(Kernel):
    """The one kernel with segments in place of runs and continuity defects as residual rows.

    Unknowns ``z = (z_θ, s)`` with ``s`` the free segment initial states in units of
    ``state_scale``; residual rows: data (segment, sample, channel), then defects (run,
    segment, state), then priors.

    **Block Jacobian** (``block_jacobian=True``, default). A segment's rows depend on
    :math:`z_\theta` and on its own initial state only, so the Jacobian is assembled from
    per-segment forward-mode blocks with :math:`n_\theta + n_x` tangents each
    (:meth:`residuals_and_jacobian`) instead of pushing all :math:`n_\theta + n_s` tangents
    through every segment; :meth:`residuals` carries it as a custom JVP, so the one LM and
    ``jax.jacfwd`` use it unchanged. A step then costs about what a single-shooting step does.
    """

    n_seg: int = eqx.field(static=True, default=1)
    block_jacobian: bool = eqx.field(static=True, default=True)

    def initial_states(self, z: Float[Array, " n_z"], data: ShootingData) -> Float[Array, "RS n_x"]:
        k = self.n_theta + self.n_extra
        return data.x0.at[data.free_row, data.free_col].add(z[k:] * data.state_scale[data.free_col])

    def residuals(self, z: Float[Array, " n_z"], data: ShootingData) -> Float[Array, " m"]:
        if self.block_jacobian:
            return _block_residuals(z, data, kernel=self)
        return self.dense_residuals(z, data)

    def dense_residuals(self, z: Float[Array, " n_z"], data: ShootingData) -> Float[Array, " m"]:
        """:meth:`residuals` computed directly (differentiated as one function)."""
        sol = self.simulate(z, data)
        e = self.output_errors(sol, data)
        return self.with_prior_rows(jnp.concatenate([e, self.defects(z, data, sol.xs)]), z, data)

    def defects(self, z: Float[Array, " n_z"], data: ShootingData,
                xs: Float[Array, "RS L n_x"]) -> Float[Array, " m_d"]:
        """Weighted continuity defects ``μ (x_end(j) − s(j+1))/σ_x``, flattened."""
        x0 = self.initial_states(z, data)
        R = data.defect_mask.shape[0]
        ends = xs[:, -1].reshape(R, self.n_seg, -1)[:, :-1]
        starts = x0.reshape(R, self.n_seg, -1)[:, 1:]
        d = (ends - starts) / data.state_scale * data.weight
        return jnp.where(data.defect_mask[..., None], d, 0.0).reshape(-1)

    def own_jacobian(self):
        """The per-segment block Jacobian as the LM's ``(J, r)`` (:meth:`residuals_and_jacobian`),
        not ``J`` pushed through :meth:`residuals`' custom JVP one tangent at a time."""
        if not self.block_jacobian:
            return None
        return lambda z, data: self.residuals_and_jacobian(z, data)[::-1]

    def residuals_and_jacobian(self, z: Float[Array, " n_z"], data: ShootingData):
        """``(r, J)``: :meth:`residuals` and its Jacobian from per-segment blocks (class docstring)."""
        n = self.n_theta
        if self.n_extra:
            raise FitError("multiple shooting: extra coordinates are not supported")
        zt = z[:n]
        x0 = self.initial_states(z, data)
        oi, ang = jnp.asarray(self.out_idx), jnp.asarray(self.angle)

        def segment(zt, x, t, u, y, m):
            sol = simulate(self.model_at(zt, data), t, u, x, self.integrator)
            err = sol.ys[:, oi] - y
            err = jnp.where(ang, wrap_angle(err), err)
            e = (jnp.where((sol.valid & m)[:, None], err / data.scales, 0.0)
                 + jnp.where(((~sol.valid) & m)[:, None], PENALTY, 0.0))
            out = (e, sol.xs[-1])
            return out, out

        jac = jax.vmap(jax.jacfwd(segment, argnums=(0, 1), has_aux=True), in_axes=(None, 0, 0, 0, 0, 0))
        ((e_t, e_x), (x_t, x_x)), (e, x_end) = jac(zt, x0, data.ts, data.us, data.ys, data.mask)
        RS, n_x = x0.shape
        n_s = data.free_row.shape[0]
        # ∂x0/∂s: one entry per free segment-state unknown
        P = jnp.zeros((RS, n_x, n_s), z.dtype).at[data.free_row, data.free_col, jnp.arange(n_s)].set(
            data.state_scale[data.free_col])
        J_data = jnp.concatenate([e_t, jnp.einsum("jlcb,jbk->jlck", e_x, P)], axis=-1).reshape(-1, n + n_s)
        R, S = data.defect_mask.shape[0], self.n_seg
        ends_t = x_t.reshape(R, S, n_x, n)[:, :-1]
        ends_s = jnp.einsum("jab,jbk->jak", x_x, P).reshape(R, S, n_x, n_s)[:, :-1]
        starts_s = P.reshape(R, S, n_x, n_s)[:, 1:]
        w = (data.weight / data.state_scale)[:, None]
        keep = data.defect_mask[..., None, None]
        J_def = jnp.where(keep, jnp.concatenate([ends_t, ends_s - starts_s], axis=-1) * w, 0.0)
        J_def = J_def.reshape(-1, n + n_s)
        d = jnp.where(data.defect_mask[..., None],
                      (x_end.reshape(R, S, n_x)[:, :-1] - x0.reshape(R, S, n_x)[:, 1:]) / data.state_scale
                      * data.weight, 0.0).reshape(-1)
        r = self.with_prior_rows(jnp.concatenate([e.reshape(-1), d]), z, data)
        J = jnp.concatenate([J_data, J_def], axis=0)
        if data.n_prior:
            J = jnp.concatenate([J, jax.jacfwd(lambda zz: self.with_prior_rows(jnp.zeros((0,)), zz, data))(z)])
        return r, J


@eqx.filter_custom_jvp
def _block_residuals(z, data, *, kernel):
    """The multiple-shooting residuals with the block-assembled Jacobian as their JVP."""
    return kernel.dense_residuals(z, data)


@_block_residuals.def_jvp
def _block_residuals_jvp(primals, tangents, *, kernel):
    z, data = primals
    tz, _ = tangents  # the data are not differentiated (their tangent is ignored)
    r, J = kernel.residuals_and_jacobian(z, data)
    return r, J @ tz


def _segments(a: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """``a[:, idx]`` reshaped to one row per segment: ``(R, N, ...)`` → ``(R·S, L+1, ...)``."""
    out = a[:, idx]
    return out.reshape((-1,) + out.shape[2:])


def _segment_starts(model: AbstractModel, runs: Sequence[Run], ts: np.ndarray, x0: np.ndarray, L: int, S: int,
                    flt) -> np.ndarray:
    """Initial guess of every segment's state from the filtered measurements at its start."""
    out = np.repeat(x0[:, None, :], S, axis=1)
    angles = [(model.state_names.index(n), n) for n in model.angle_outputs if n in model.state_names]
    for i, run in enumerate(runs):
        for j in range(1, S):
            k = j * L
            if k >= run.n - 2:
                out[i, j] = out[i, j - 1]
                continue
            out[i, j] = initial_state(model, run.slice(float(run.time[k]), None), flt)
            for col, name in angles:  # align a wrapped heading with the unwrapped run
                if run.has(name):
                    ref = np.unwrap(np.asarray(run[name], dtype=np.float64))[k]
                    out[i, j, col] += 2 * np.pi * np.round((ref - out[i, j, col]) / (2 * np.pi))
    return out


def shooting_problem(model: AbstractModel, runs: Sequence[Run], spec: ParamSpec, channels, o: OutputErrorOptions,
                     segment_s: float):
    """``(kernel, data, batch, info)`` of the multiple-shooting problem (continuity weight 1)."""
    batch = make_batch(model, runs, channels, o.flt)
    R, N = batch.ts.shape
    dts = np.concatenate([np.diff(batch.ts[i, : batch.lengths[i]]) for i in range(R)])
    dt = float(np.median(dts))
    L = max(2, int(round(segment_s / dt)))
    S = max(1, -(-(N - 1) // L))
    n_pad = S * L + 1 - N
    last_dt = batch.ts[:, -1:] - batch.ts[:, -2:-1]
    ts = np.concatenate([batch.ts, batch.ts[:, -1:] + last_dt * np.arange(1, n_pad + 1)], axis=1)
    us = np.concatenate([batch.us, np.repeat(batch.us[:, -1:], n_pad, axis=1)], axis=1)
    ys = np.concatenate([batch.ys, np.zeros((R, n_pad, batch.ys.shape[2]))], axis=1)
    mask = np.concatenate([batch.mask, np.zeros((R, n_pad), dtype=bool)], axis=1)
    idx = np.arange(S)[:, None] * L + np.arange(L + 1)[None, :]
    # a segment is active when it starts before the last sample of its run; every sample is counted
    # once: the last sample of a segment is the first of the next active one
    active = np.array([[j * L < batch.lengths[i] - 1 for j in range(S)] for i in range(R)], dtype=bool)
    counted = np.ones((R, S, L + 1), dtype=bool)
    counted[:, :-1, -1] = ~active[:, 1:]
    counted &= active[:, :, None]
    seg_mask = (mask[:, idx] & counted).reshape(R * S, L + 1)
    x_guess = _segment_starts(model, runs, batch.ts, batch.x0, L, S, o.flt)
    x0_idx = tuple(model.state_names.index(s) for s in o.x0_states(model, batch.channels))
    n_x = len(model.state_names)
    rows, cols = [], []
    for i in range(R):
        rows += [i * S] * len(x0_idx)
        cols += list(x0_idx)
        for j in range(1, S):
            if active[i, j]:
                rows += [i * S + j] * n_x
                cols += list(range(n_x))
    defect_mask = active[:, 1:].reshape(R, S - 1)
    state_scale = x0_scales(model, batch, model.state_names)
    kernel = ShootingKernel(
        spec=spec.structural(),
        out_idx=tuple(model.output_names.index(c) for c in batch.channels),
        angle=tuple(c in model.angle_outputs for c in batch.channels),
        x0_idx=x0_idx, integrator=o.integrator, n_seg=S,
    )
    base = kernel_data(model, _segments(ts, idx), _segments(us, idx), _segments(ys, idx), seg_mask,
                       x_guess.reshape(R * S, n_x), channel_spread(batch), x0_scale=state_scale)
    fields = {f.name: getattr(base, f.name) for f in dataclasses.fields(KernelData)}
    data = ShootingData(**fields, free_row=jnp.asarray(rows, dtype=jnp.int64),
                        free_col=jnp.asarray(cols, dtype=jnp.int64),
                        state_scale=jnp.asarray(state_scale), defect_mask=jnp.asarray(defect_mask),
                        weight=jnp.asarray(1.0))
    info = {"segment_samples": L, "segments_per_run": S, "segment_s": L * dt, "n_segment_unknowns": len(rows)}
    return kernel, data, batch, info


@dataclasses.dataclass(frozen=True)
class MultipleShooting(OnOutputError):
    """Output error by multiple shooting (module docstring): the settings of the estimator.

    Attributes:
        oe: the output-error settings it shares (integrator, filter, weights, LM tolerances,
            estimated initial states of each run's first segment, priors) and the polish's.
        shooting: segments, penalties, polish and stage limits (:class:`ShootingOptions`).
    """

    method = "multiple_shooting"

    oe: OutputErrorOptions = OutputErrorOptions()
    shooting: ShootingOptions = ShootingOptions()

    def describe(self) -> str:
        return "multiple shooting"

    def prepare(self, model, runs, spec, channels, priors, say) -> Problem:
        o, sh = self.oe, self.shooting
        if o.estimate_x0 != "auto":  # the rule's states are resolved on the batch's channels (shooting_problem)
            o = dataclasses.replace(o, estimate_x0=tuple(o.estimate_x0))
        unknown = [s_ for s_ in (o.estimate_x0 if o.estimate_x0 != "auto" else ()) if s_ not in model.state_names]
        if unknown:
            raise FitError(f"estimate_x0: {', '.join(unknown)} are not states of model {model.name} "
                           f"({', '.join(model.state_names)})")
        kernel, data, batch, info = shooting_problem(model, runs, spec, channels, o, sh.segment_s)
        if o.channel_scales:
            data = data.replace(scales=jnp.asarray([o.channel_scales[c] for c in batch.channels], dtype=jnp.float64))
        p_mean, p_w = prior_arrays(priors, spec)
        if np.any(p_w):
            data = data.replace(prior_mean=jnp.asarray(p_mean), prior_w=jnp.asarray(p_w))
        n_p, n_s = len(spec.free_names), info["n_segment_unknowns"]
        # Before a polish the stages only bring the parameters into the single-shooting basin: they stop
        # at the plain step/cost tests with a looser cost-stall test (``stage_ftol``). The Gauss–Newton-
        # step check (``gntol``) and the single-shooting tolerances are kept for the polish, and for every
        # stage when there is no polish (measured on one 300-s KVLCC2 zigzag, 31 segments: with them,
        # every stage ran its 100 steps, 0.9 s each on the shared 2-core machine).
        lm = dict(max_steps=sh.max_steps, rtol=o.rtol, atol=o.atol, gntol=float("inf") if sh.polish else float(o.gntol))
        if sh.polish:
            lm["ftol"] = float(sh.stage_ftol)
        say(f"multiple shooting: compiling ({n_p} parameters + {n_s} segment states, {info['segments_per_run']} "
            f"segments per run, {o.integrator.describe()})...")
        (res_fn, solve_fn), compile_s = kernel.compiled_many([("residuals", np.zeros(n_p + n_s), data, {}),
                                                               ("solve", np.zeros(n_p + n_s), data, lm)])
        messages = [f"multiple shooting: {info['segments_per_run']} segments of {info['segment_samples']} "
                    f"samples ({info['segment_s']:.3g} s) per run, {n_s} segment-state unknowns"]
        return Problem(model=model, spec=spec, runs=tuple(runs), channels=batch.channels, n_nuisance=n_s,
                       nuisance_names=tuple(f"segment state {i + 1}" for i in range(n_s)), priors=priors,
                       compile_seconds=compile_s,
                       state=dict(kernel=kernel, data=data, batch=batch, info=info, res_fn=res_fn, solve_fn=solve_fn,
                                  n_data=int(np.prod(data.ys.shape)), messages=messages, integrator=o.integrator,
                                  n_rows=batch.n_residuals, channels=channels))

    def start_cost(self, problem, z) -> float:
        st_ = problem.state
        r = np.asarray(st_["res_fn"](jnp.asarray(z), st_["data"]))
        c = 0.5 * float(np.sum(r * r))
        return c if math.isfinite(c) and not np.any(np.abs(r[:st_["n_data"]]) >= PENALTY) else math.inf

    def _stages(self, problem, z, say):
        """The increasing continuity penalty, one LM solve each (one compiled program)."""
        st_, sh, o = problem.state, self.shooting, self.oe
        data, batch, n_data = st_["data"], st_["batch"], st_["n_data"]
        # the channels are re-weighted by their residual RMS (now of a continuous trajectory) and the
        # last stage solved again (not before a polish: single shooting re-weights itself)
        schedule = list(sh.penalties)
        if o.weights == "noise" and not o.channel_scales and not sh.polish:
            schedule.append(None)
        spread = channel_spread(batch)
        seg_mask = np.asarray(data.mask)
        n_def = np.asarray(data.defect_mask).size * len(problem.model.state_names)
        stages, r = [], None
        for mu in schedule:
            if mu is None:
                sig = channel_rms(r[:n_data], seg_mask, np.asarray(data.scales))
                data = data.replace(scales=jnp.asarray(np.maximum(sig, 1e-6 * spread)))
                mu = sh.penalties[-1]
            data = data.replace(weight=jnp.asarray(mu))
            z, result, steps, r = st_["solve_fn"](jnp.asarray(z), data)
            r = np.asarray(r)
            defect = np.abs(r[n_data:n_data + n_def]) / mu
            stages.append({"penalty": mu, "steps": int(steps), "result": st.message(result), "code": result,
                           "max_defect": float(defect.max(initial=0.0)), "cost": 0.5 * float(r[:n_data] @ r[:n_data]),
                           "weights": "noise" if len(stages) == len(sh.penalties) else "initial"})
            say(f"multiple shooting: penalty {mu:g} ({stages[-1]['weights']} weights): {stages[-1]['result']} after "
                f"{int(steps)} steps, largest continuity defect {stages[-1]['max_defect']:.2g} state scales")
        return np.asarray(z), r, data, stages

    def first_solves(self, problem, zs, say):
        if self.oe.choose == "first":
            zs = zs[:1]
        out = []
        t0 = time.perf_counter()
        for z in zs:
            z, r, data, stages = self._stages(problem, z, say)
            c = 0.5 * float(r @ r)
            bad = not math.isfinite(c) or np.any(np.abs(r[:problem.state["n_data"]]) >= PENALTY)
            out.append((z, math.inf if bad else c, sum(s_["steps"] for s_ in stages)))
            problem.state.setdefault("runs_of_stages", []).append((z, r, data, stages))
        problem.state["ms_s"] = time.perf_counter() - t0
        return out

    def residuals(self, problem, z) -> np.ndarray:
        st_ = problem.state
        if "polish" in st_:
            oe, p2 = st_["polish"]
            return oe.residuals(p2, z)
        d = st_.get("final_data", st_["data"])
        return np.asarray(st_["res_fn"](jnp.asarray(z), d))[: st_["n_data"]]

    def finish(self, problem, z, steps, say) -> Solved:
        st_, sh = problem.state, self.shooting
        z, r, data, stages = next(t for t in st_["runs_of_stages"] if np.array_equal(t[0], z))
        st_["final_data"] = data
        spec, model = problem.spec, problem.model
        n_p = problem.n_params
        theta = np.asarray(spec.full_values(jnp.asarray(z[:n_p]), model.theta()))
        values = {n: float(theta[i]) for i, n in enumerate(model.param_names)}
        ms_info = {"segment_s": st_["info"]["segment_s"], "segments_per_run": st_["info"]["segments_per_run"],
                   "segment_unknowns": problem.n_nuisance, "stages": [{k: v for k, v in s_.items() if k != "code"}
                                                                      for s_ in stages],
                   "seconds": st_["ms_s"], "steps": steps, "polish": sh.polish,
                   "params": {n: model.canonical(values)[n] for n in spec.free_names}}
        pens = ", ".join(f"{p:g}" for p in sh.penalties)
        messages = list(st_["messages"]) + [f"multiple shooting: {steps} steps over penalties {pens}; "
                                            f"largest final continuity defect {stages[-1]['max_defect']:.2g} state scales"]
        if sh.polish:
            # the single-shooting fit from the multiple-shooting estimate: the result *is* its optimum
            say("multiple shooting: polishing by single shooting from the multiple-shooting estimate...")
            oe = dataclasses.replace(self.oe, warmup=0.0, choose="first")
            p2 = oe.prepare(model, problem.runs, spec, st_["channels"], problem.priors, say)
            out = oe.first_solves(p2, [p2.z_start(values)], say)
            s2 = oe.finish(p2, out[0][0], out[0][2], say)
            st_["polish"] = (oe, p2)
            return dataclasses.replace(
                s2, steps=s2.steps + steps, seconds=s2.seconds + st_["ms_s"], compile_seconds=s2.compile_seconds
                + p2.compile_seconds, messages=tuple(messages) + s2.messages, info={**s2.info, "shooting": ms_info})
        kernel, batch, n_data = st_["kernel"], st_["batch"], st_["n_data"]
        t0 = time.perf_counter()
        jac_fn, c = kernel.compiled("jacobian", z, data)
        J = np.asarray(jac_fn(jnp.asarray(z), data)) * per_scale_columns(spec, z, len(z))
        r_d, J_d, J_rest, r_rest = r[:n_data], J[:n_data], J[n_data:], r[n_data:]
        n_res = int(np.asarray(data.mask).sum()) * len(batch.channels)
        result = st.as_diffship(stages[-1]["code"])
        scales = np.asarray(data.scales)
        noise = channel_rms(r_d, np.asarray(data.mask), scales)
        x0 = np.asarray(kernel.initial_states(jnp.asarray(z), data)).reshape(len(batch.names), kernel.n_seg, -1)[:, 0]
        return Solved(
            z=z, r_data=r_d, J_data=J_d, J_extra=J_rest, r_extra=r_rest, result=result, steps=steps,
            seconds=st_["ms_s"] + time.perf_counter() - t0, compile_seconds=c, cost=0.5 * float(r_d @ r_d),
            channel_scales={ch: float(s_) for ch, s_ in zip(batch.channels, scales)},
            noise_std={ch: float(s_) for ch, s_ in zip(batch.channels, noise)}, initial_states=tuple(x0),
            run_names=batch.names, dof=max(n_res - n_p, 1), kind="white", messages=tuple(messages),
            info={"shooting": ms_info, "estimate_x0": self.oe.x0_states(problem.model, st_["batch"].channels), "weights": self.oe.weights,
                  "integrator": self.oe.integrator.describe()})


def fit_multiple_shooting(
    model: AbstractModel,
    runs: Sequence[Run],
    *,
    spec: ParamSpec | None = None,
    starts: Sequence[Mapping[str, float]] | Mapping[str, Mapping[str, float]] = (),
    channels: Sequence[str] | None = None,
    options: OutputErrorOptions = OutputErrorOptions(),
    shooting: ShootingOptions = ShootingOptions(),
    progress: Callable[[str], None] | None = None,
    n_starts: int | None = 1,
    throw: bool = True,
) -> FitResult:
    """Output error by multiple shooting: :func:`diffship.fit.fit` with :class:`MultipleShooting`.
    One start by default (the lowest initial multiple-shooting cost of the model's values and
    ``starts``): multiple shooting is itself the remedy for a poor start. Returns a
    :class:`~diffship.fit.FitResult` with ``info["shooting"]`` describing the stage."""
    return fit(model, runs, MultipleShooting(oe=options, shooting=shooting), spec=spec, starts=starts,
               n_starts=n_starts, channels=channels, progress=progress, throw=throw)
