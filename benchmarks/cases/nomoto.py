r"""Cases ``nomoto`` and ``nomoto_cubic``: the first-order Nomoto model, every method on the same data.

What is measured:

* ``nomoto`` (``nomoto_linear`` in the CSV) — truth Nomoto 1 (K = 0.2 /s, T = 8 s, δ0 = 0.01 rad),
  zigzag-like rudder runs (2 training, 2 validation manoeuvres, 60 s at 10 Hz). For noise none /
  realistic / 3× realistic: parameter errors, validation NRMSE, 10/10 and 20/20 overshoot errors,
  wall/compile time and memory of diffship output error, diffship equation error, scipy
  ``least_squares`` over NumPy RK4 (the identical problem; ``cost_check_rel_diff`` proves it), NumPy
  OLS and STLSQ; a warm second output-error call; parameter errors over noise seeds (default noise
  weighting); sweeps of sample interval, run length and unmodelled rudder delay (quick: delay
  only); convergence from N random starts; vmapped batches (:mod:`.nomoto_batch`).
* ``nomoto_cubic`` (``nomoto_cubic_truth``) — truth :math:`T\dot r + r + a r^3 = K(\delta + \delta_0)`,
  a = 50 s², fitted with the *linear* model (model-structure error); STLSQ's library contains r³.

:func:`nomoto_methods` (fit the linear Nomoto model with every method, record everything) is
shared with :mod:`.sspa`.
"""

from __future__ import annotations

import math
import time
from typing import ClassVar

import jax.numpy as jnp
import numpy as np

from benchmarks.common import peers
from benchmarks.cases.nomoto_batch import batched, nomoto_derivatives
from benchmarks.common.fitapi import (FLT_NONE, batch_of, fit_ee, fit_numbers, fit_oe, fitted_model, fitted_params,
                               initial_states, spread_of)
from benchmarks.record import (EE_KEYS, METHODS, convergence, log_uniform_starts, record_common, record_fit,
                               record_zig, say, seed_summary, timed, traced_peak)
from diffship.models import Nomoto1
from diffship.models import AbstractModel, param
from diffship.synthetic import rudder_sequence, simulate_run

DEG = np.pi / 180.0
NOMOTO_TRUTH = dict(K=0.2, T1=8.0, delta0=0.01)
CUBIC_TRUTH = dict(K=0.2, T1=8.0, a=50.0, delta0=0.01)
STLSQ_THRESHOLD = 0.02  # relative, on unit-RMS columns; 0.05 already drops the r³ and δ0 terms of the truth
NAMES = ("K", "T1", "delta0")


# -- truth and data ---------------------------------------------------------------------------------------------
class NomotoCubic(AbstractModel):
    r"""Nonlinear first-order Nomoto model (Norrbin-type cubic yaw damping).

    .. math:: \dot\psi = r,\qquad T\dot r + r + a r^3 = K(\delta + \delta_0)

    States ``(psi, r)``, input ``delta`` [rad]; ``a`` [s²]. With ``a = 0`` it is :class:`Nomoto1`.
    """

    name: ClassVar[str] = "nomoto_cubic"
    state_names: ClassVar[tuple[str, ...]] = ("psi", "r")
    output_names: ClassVar[tuple[str, ...]] = ("psi", "r")
    K: jnp.ndarray = param(0.2, scale=0.5, unit="1/s", description="rudder gain")
    T1: jnp.ndarray = param(8.0, lower=0.0, scale=5.0, unit="s", description="yaw time constant")
    a: jnp.ndarray = param(50.0, scale=50.0, unit="s2", description="cubic yaw damping")
    delta0: jnp.ndarray = param(0.0, scale=0.01, unit="rad", description="rudder offset")

    @property
    def input_names(self) -> tuple[str, ...]:
        return ("delta",)

    def vector_field(self, t, x, u):
        r = x[1]
        return jnp.stack([r, (self.K * (u[0] + self.delta0) - r - self.a * r * r * r) / self.T1])


TRAIN_MANOEUVRES = ((10.0, 20.0), (-20.0, 30.0))  # (amplitude deg, period s)
VAL_MANOEUVRES = ((15.0, 25.0), (-25.0, 40.0))


def nomoto_case_runs(truth, *, which="train", duration=60.0, dt=0.1, noise="realistic", seed=0, delay=0.0):
    """Zigzag-like rudder runs of ``truth``; validation runs use different amplitudes/periods.

    With ``delay`` the truth is driven by δ(t − delay) while the run records δ(t) (an input delay
    the fitted model does not know about).
    """
    man = TRAIN_MANOEUVRES if which == "train" else VAL_MANOEUVRES
    out = []
    for i, (amp, period) in enumerate(man):
        t = np.arange(0.0, duration + 0.5 * dt, dt)
        delta = rudder_sequence(t, amp * DEG, period)
        drive = np.interp(t - delay, t, delta, left=0.0) if delay else delta
        run = simulate_run(truth, t, {"delta": drive}, np.zeros(2), name=f"{which}_{i}", noise=noise,
                           seed=1000 * seed + 10 * i + (0 if which == "train" else 5))
        out.append(run.with_channels(delta=delta) if delay else run)
    return out


def nomoto_zigzag_errors(truth_model):
    """Errors of the 10/10 and 20/20 zigzag overshoots of a model against the truth's [deg]."""
    from diffship.manoeuvres import zigzag, zigzag_metrics

    def metrics(m):
        out = {}
        for a in (10.0, 20.0):
            run = zigzag(m, {"psi": 0.0, "r": 0.0}, rudder_deg=a, duration=150.0, dt=0.2, rudder_rate_deg_s=5.0)
            zm = zigzag_metrics(run)
            out[a] = (zm.first_overshoot, zm.second_overshoot)
        return out

    ref = metrics(truth_model)

    def errors(m):
        try:
            got = metrics(m)
        except Exception:
            return {"zigzag_failed": math.nan}
        out = {}
        for a in ref:
            out[f"err_overshoot1_{a:g}_{a:g}"] = got[a][0] - ref[a][0]
            out[f"err_overshoot2_{a:g}_{a:g}"] = got[a][1] - ref[a][1]
        return out

    return errors


# -- every method on one data set ---------------------------------------------------------------------------
def nomoto_spec(start):
    return Nomoto1().spec().with_values(start)


def fit_nomoto_oe(spec, train, weights="spread"):
    """diffship output error on the scipy peer's problem (raw initial states, psi and r estimated per run, free:
    no prior holding them near the first samples, which the peer's least squares does not have)."""
    return fit_oe(Nomoto1(), train, spec=spec, estimate_x0=("psi", "r"), weights=weights, flt=FLT_NONE, x0_prior=False)


def nomoto_problem(spec, train):
    """The NumPy peer's problem and its start ``z0`` (scaled parameters, zero initial-state offsets)."""
    batch = batch_of(Nomoto1().with_params(spec.values()), train, ("psi", "r"), FLT_NONE)
    prob = peers.NomotoProblem(spec, batch, spread_of(batch))
    return prob, batch, np.concatenate([spec.to_z(), np.zeros(2 * len(train))])


def nomoto_methods(rec, case, variant, train, val, truth, truth_model, *, start, methods=METHODS, guard=60.0,
                   zig=None, memory=False, oe_weights="spread"):
    """Fit the linear Nomoto model to ``train`` with every method; record everything."""
    spec = nomoto_spec(start)
    out = {}
    # diffship output error (same problem as the scipy peer: spread weights, raw initial states)
    oe, wall = timed(fit_nomoto_oe, spec, train, oe_weights)
    out["diffship_oe"] = oe
    oe_cost = fit_numbers(oe)["cost"]
    record_fit(rec, case, variant, "diffship_oe", oe, wall)
    record_common(rec, case, variant, "diffship_oe", fitted_model(oe), val, truth, NAMES, zig)
    # diffship equation error
    if "diffship_ee" in methods:
        ee, wall = timed(fit_ee, Nomoto1(), train, spec=spec)
        out["diffship_ee"] = ee
        record_fit(rec, case, variant, "diffship_ee", ee, wall, EE_KEYS)
        record_common(rec, case, variant, "diffship_ee", fitted_model(ee), val, truth, NAMES, zig)
    # scipy least_squares over a NumPy RK4 simulation
    if "scipy_lm_numpy_rk4" in methods:
        prob, batch, z0 = nomoto_problem(spec, train)
        sp = peers.scipy_fit(prob.residuals, z0, guard_s=guard, target_cost=oe_cost)
        pv = prob.params(sp["z"])
        out["scipy_lm_numpy_rk4"] = (sp, pv)
        # consistency: NumPy residual at diffship's solution reproduces diffship's cost
        z_ds = np.concatenate([spec.to_z({n: fitted_params(oe)[n] for n in NAMES}),
                               ((initial_states(oe) - batch.x0) / prob.x0_scale).reshape(-1)])
        c_chk = 0.5 * float(np.sum(prob.residuals(z_ds) ** 2))
        rec.add(case, variant, "scipy_lm_numpy_rk4", "cost_check_rel_diff", abs(c_chk - oe_cost) / max(oe_cost, 1e-300),
                note="NumPy residual at diffship's OE solution vs diffship's cost")
        for k, v, u in (("wall_s", sp["wall"], "s"), ("compile_s", 0.0, "s"), ("fit_s", sp["wall"], "s"),
                        ("cost", sp["cost"], ""), ("f_evals", sp["calls"], ""), ("converged", sp["finished"], ""),
                        ("time_to_oe_cost_s", sp["t_target"] if sp["t_target"] is not None else math.nan, "s")):
            rec.add(case, variant, "scipy_lm_numpy_rk4", k, v, u)
        if memory:
            with traced_peak() as mem:
                peers.scipy_fit(prob.residuals, z0, guard_s=guard, max_nfev=1)
            rec.add(case, variant, "scipy_lm_numpy_rk4", "tracemalloc_peak_mb", mem["mb"],
                    "MB", "tracemalloc, one LM iteration (one FD Jacobian): the peak working set")
        record_common(rec, case, variant, "scipy_lm_numpy_rk4", Nomoto1().with_params(pv), val, truth, NAMES, zig)
    # NumPy OLS and STLSQ on the same filtered derivatives as diffship's equation error
    if "numpy_ols" in methods or "stlsq_sindy" in methods:
        t = time.perf_counter()
        R, RD, D = (np.concatenate(a) for a in nomoto_derivatives(train))
        t_deriv = time.perf_counter() - t
        if "numpy_ols" in methods:
            with traced_peak() as mem:
                pv, wall = timed(peers.nomoto_ols, R, RD, D)
            rec.add(case, variant, "numpy_ols", "tracemalloc_peak_mb", mem["mb"], "MB", "tracemalloc around the regression")
            out["numpy_ols"] = pv
            rec.add(case, variant, "numpy_ols", "wall_s", wall + t_deriv, "s", "includes filtering/differentiation")
            rec.add(case, variant, "numpy_ols", "compile_s", 0.0, "s")
            if pv["T1"] > 0:
                record_common(rec, case, variant, "numpy_ols", Nomoto1().with_params(pv), val, truth, NAMES, zig)
        if "stlsq_sindy" in methods:
            t = time.perf_counter()
            lib = np.stack([R, R**3, D, np.ones_like(R)], 1)
            xi = peers.stlsq(lib, RD, threshold=STLSQ_THRESHOLD)
            wall = time.perf_counter() - t + t_deriv
            a1, a3, b, c = xi
            rec.add(case, variant, "stlsq_sindy", "wall_s", wall, "s", "includes filtering/differentiation")
            rec.add(case, variant, "stlsq_sindy", "compile_s", 0.0, "s")
            rec.add(case, variant, "stlsq_sindy", "cubic_term_kept", a3 != 0.0, "",
                    f"library r, r^3, delta, 1; threshold {STLSQ_THRESHOLD}")
            if a1 < 0 and b != 0:
                T = -1.0 / a1
                pv = {"K": b * T, "T1": T, "a": -a3 * T, "delta0": c / b}
                out["stlsq_sindy"] = pv
                mdl = NomotoCubic(**pv)
                record_common(rec, case, variant, "stlsq_sindy", mdl, val, truth, NAMES, None)
                if zig is not None:
                    record_zig(rec, case, variant, "stlsq_sindy", zig(mdl))
    return out


# -- the cases ------------------------------------------------------------------------------------------------
def run(rec, quick, figs=None):
    """Case ``nomoto``: linear Nomoto truth (CSV case ``nomoto_linear``)."""
    case = "nomoto_linear"
    truth_model = Nomoto1(**NOMOTO_TRUTH)
    zig = nomoto_zigzag_errors(truth_model)
    start = {"K": 0.5 * NOMOTO_TRUTH["K"], "T1": 1.5 * NOMOTO_TRUTH["T1"], "delta0": 0.0}
    dur = 60.0
    # noise sweep (first variant also pays the compilation)
    for noise in ("none", "realistic", "high"):
        say(f"{case}: noise {noise}")
        tr = nomoto_case_runs(truth_model, which="train", duration=dur, noise=noise, seed=1)
        va = nomoto_case_runs(truth_model, which="val", duration=dur, noise=noise, seed=1)
        nomoto_methods(rec, case, f"noise={noise}", tr, va, NOMOTO_TRUTH, truth_model, start=start, zig=zig,
                       memory=(noise == "realistic"))
        if noise == "none":  # warm repeat: compiled already
            _, wall = timed(fit_nomoto_oe, nomoto_spec(start), tr, "spread")
            rec.add(case, "noise=none", "diffship_oe", "warm_wall_s", wall, "s", "2nd call")
    # parameter error over several noise seeds (the single-seed numbers above are one draw)
    seeds = range(10, 13) if quick else range(10, 18)
    say(f"{case}: realistic noise, {len(seeds)} seeds")
    for sd in seeds:
        tr = nomoto_case_runs(truth_model, which="train", duration=dur, noise="realistic", seed=sd)
        nomoto_methods(rec, case, f"seed={sd}", tr, [], NOMOTO_TRUTH, truth_model, start=start,
                       methods=("diffship_oe", "diffship_ee"), oe_weights="noise")
    seed_summary(rec, case, [f"seed={sd}" for sd in seeds], ("diffship_oe", "diffship_ee"))
    # sweeps (every new sample interval or run length is a new shape: diffship recompiles; quick: delay only)
    sweeps = {
        "dt": [] if quick else [0.05, 0.1, 0.5],
        "duration": [] if quick else [30.0, 60.0, 180.0],
        "delay": [0.0, 0.5] if quick else [0.0, 0.25, 0.5, 1.0],
    }
    for kind, values in sweeps.items():
        for v in values:
            kw = dict(duration=dur, dt=0.1, delay=0.0)
            kw[kind] = v
            say(f"{case}: {kind}={v:g}")
            tr = nomoto_case_runs(truth_model, which="train", noise="realistic", seed=2, **kw)
            va = nomoto_case_runs(truth_model, which="val", noise="realistic", seed=2,
                                  **{**kw, "duration": 60.0, "dt": kw["dt"]})
            nomoto_methods(rec, case, f"{kind}={v:g}", tr, va, NOMOTO_TRUTH, truth_model, start=start,
                           zig=zig if kind == "delay" else None)
    # convergence from N random starts (OE loop of warm fits vs scipy)
    n = 4 if quick else 16
    say(f"{case}: convergence from {n} random starts")
    tr = nomoto_case_runs(truth_model, which="train", duration=dur, noise="realistic", seed=1)
    starts = log_uniform_starts(NOMOTO_TRUTH, NAMES, n, seed=3)
    fits = {"diffship_oe": [], "scipy_lm_numpy_rk4": []}
    batch = batch_of(Nomoto1(), tr, ("psi", "r"), FLT_NONE)
    for s in starts:
        spec = nomoto_spec(s)
        t = time.perf_counter()
        try:
            r = fit_nomoto_oe(spec, tr)
            fits["diffship_oe"].append((fit_numbers(r)["cost"], time.perf_counter() - t))
        except Exception:
            fits["diffship_oe"].append((math.inf, time.perf_counter() - t))
        prob = peers.NomotoProblem(spec, batch, spread_of(batch))
        z0 = np.concatenate([spec.to_z(), np.zeros(2 * len(tr))])
        sp = peers.scipy_fit(prob.residuals, z0, guard_s=60.0)
        fits["scipy_lm_numpy_rk4"].append((sp["cost"], sp["wall"]))
    convergence(rec, case, "noise=realistic", fits)
    batched(rec, case, tr, starts, fits["diffship_oe"], quick)


def run_cubic(rec, quick, figs=None):
    """Case ``nomoto_cubic``: cubic Nomoto truth fitted with the linear model (CSV case ``nomoto_cubic_truth``)."""
    case = "nomoto_cubic_truth"
    truth_model = NomotoCubic(**CUBIC_TRUTH)
    zig = nomoto_zigzag_errors(truth_model)
    start = {"K": 0.5 * CUBIC_TRUTH["K"], "T1": 1.5 * CUBIC_TRUTH["T1"], "delta0": 0.0}
    for noise in ("none", "realistic") if quick else ("none", "realistic", "high"):
        say(f"{case}: noise {noise}")
        tr = nomoto_case_runs(truth_model, which="train", duration=60.0, noise=noise, seed=4)
        va = nomoto_case_runs(truth_model, which="val", duration=60.0, noise=noise, seed=4)
        out = nomoto_methods(rec, case, f"noise={noise}", tr, va, CUBIC_TRUTH, truth_model, start=start, zig=zig)
        if "stlsq_sindy" in out:
            rec.add(case, f"noise={noise}", "stlsq_sindy", "rel_err_a", abs(out["stlsq_sindy"]["a"] - 50.0) / 50.0)


CASES = {"nomoto": run, "nomoto_cubic": run_cubic}
