r"""k-step-ahead prediction from the Kalman filter's state: what a model of a sea state can honestly do.

A disturbance that is a random process (waves with a random phase, gusts) cannot be simulated from the first
sample of a run, only filtered: a free simulation of a fit at sea misses by the sea state, however right the
dynamics. The honest test of such a model on held-out runs is prediction: filter up to sample :math:`k`
(:mod:`diffship.fit.ekf`, with the fitted noise levels), then simulate :math:`H` samples ahead with the measured
inputs and compare with :math:`y_{k+H}`,

.. math:: \hat y_{k+H|k} = h\big(\Phi_{k\to k+H}(\hat x_{k|k}),\ u_{k+H}\big),

where :math:`\Phi` is the filter's own model (the fit's integrator over every sample interval). **With the
disturbance** the augmented state :math:`(x, w)` is propagated — a wave resonator keeps oscillating at its period
and phase, an Ornstein–Uhlenbeck force decays; **without** it, the same filtered :math:`x` with :math:`w = 0`: the
dynamics alone. The difference is what the disturbance model predicts (Ljung 1999, §3.2; the innovations at
:math:`H = 1`).

Metrics are those of :mod:`diffship.metrics` (RMSE, NRMSE fit %) on the samples predicted (:math:`k + H` within
the run), returned as an :class:`~diffship.metrics.Evaluation` whose ``horizon`` says which prediction it is, so
the verdicts of :mod:`diffship.usability` apply to it unchanged.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from ..data import Run
from ..metrics import Evaluation, compare
from . import disturbance as dist
from .output_error import OutputErrorOptions
from .prediction_error import PredictionErrorOptions, pe_problem
from .result import FitResult

__all__ = ["ahead", "ahead_table", "choose_disturbance", "neg_log_likelihood"]


def _noise(result: FitResult) -> PredictionErrorOptions:
    """The fitted noise model, held (:class:`PredictionErrorOptions` with ``estimate_noise=False``)."""
    info = result.info
    kind = info.get("disturbance", "ou")
    hyper = {"tau": info["disturbance_tau"]} if kind == "ou" else {}
    if kind == "wave":
        hyper = {"wave_period": info["wave_period"], "wave_damping": info["wave_damping"]}
    return PredictionErrorOptions(process_states=tuple(info["process_states"]), estimate_noise=False,
                                  process_noise=dict(info["process_sd"]), measurement_noise=dict(info["measurement_sd"]),
                                  disturbance=kind, **hyper)


def _held_filter(result: FitResult, runs: Sequence[Run], keep: bool = False):
    """``(kernel, data, batch, filter pass)``: the fit's filter over ``runs``, its dynamics and noise model held."""
    model = result.model
    kernel, data, batch, _ = pe_problem(model, runs, model.spec().fix(model.param_names), result.channels,
                                        OutputErrorOptions(integrator=result.integrator), _noise(result))
    return kernel, data, batch, kernel.filter(jnp.zeros(0), data, keep=keep)


def ahead(result: FitResult, runs: Sequence[Run], seconds: float | None = 30.0,
          disturbance: bool = True) -> Evaluation:
    """The ``seconds``-ahead predictions (``None``: one sample ahead) of a prediction-error fit on ``runs``
    (module docstring), with or without the ``disturbance``'s own dynamics in the prediction."""
    if result.method != "prediction_error":
        raise ValueError(f"k-step-ahead prediction needs a prediction-error fit (its noise model), got {result.method}")
    return _ahead(result, runs, _held_filter(result, runs, keep=True), seconds, disturbance)


def _ahead(result: FitResult, runs: Sequence[Run], held, seconds: float | None, disturbance: bool) -> Evaluation:
    """:func:`ahead` from the fit's filter over ``runs`` (``held``: :func:`_held_filter`, states kept)."""
    model = result.model
    kernel, data, batch, fp = held
    f, h, *_ = kernel.system(jnp.zeros(0), data)
    dt = float(np.median(np.concatenate([np.diff(r.time) for r in runs])))
    H = 1 if seconds is None else max(1, int(round(seconds / dt)))
    n_x = len(model.state_names)

    def one(ts, us, xf):  # every k of one run: H intervals from the filtered state at k
        N = ts.shape[0]
        idx = jnp.minimum(jnp.arange(N)[:, None] + jnp.arange(H + 1)[None, :], N - 1)

        def roll(x, t_seq, u_seq):
            x = x if disturbance else x.at[n_x:].set(0.0)

            def body(x, i):
                return kernel.integrator.interval(f, t_seq[i], t_seq[i + 1], x, u_seq[i], u_seq[i + 1]), None
            x, _ = jax.lax.scan(body, x, jnp.arange(H))
            return h(x, u_seq[-1])
        return jax.vmap(roll)(xf, ts[idx], us[idx])

    pred = np.asarray(jax.jit(jax.vmap(one))(data.ts, data.us, fp.xf))  # (R, N, n_c): ŷ[k+H | k] at row k
    what = "one-sample" if seconds is None else f"{H * dt:g}-s"
    simulated, ok = {}, {}
    for i, run in enumerate(runs):  # ŷ[k] predicted from k − H; the first H samples have no prediction
        yh = np.full((run.n, len(batch.channels)), math.nan)
        yh[H:] = pred[i, : run.n - H]
        simulated[run.name] = {c: yh[:, j] for j, c in enumerate(batch.channels)}
        ok[run.name] = bool(np.all(np.isfinite(pred[i, : run.n - H])))
    return compare(runs, simulated, batch.channels, model.angle_outputs, ok, skip=H,
                   horizon=f"{what}-ahead prediction from the Kalman filter's state, "
                           f"{'with' if disturbance else 'without'} the disturbance")


def neg_log_likelihood(result: FitResult, runs: Sequence[Run]) -> float:
    r"""The Gaussian negative log-likelihood of ``runs`` per sample under a prediction-error fit's filter, with its
    dynamics and noise model held,

    .. math:: \bar\ell = \frac{1}{N}\sum_k \tfrac12\big(\varepsilon_k^\top\varepsilon_k + \log\det S_k
              + n_c \log 2\pi\big),

    over the ``N`` measured samples (:mod:`diffship.fit.ekf`: the normalised innovations :math:`\varepsilon_k` and
    their covariances :math:`S_k`). On the training runs it is what the fit minimises (up to its constant); on
    held-out runs it judges a noise model as the one-sample prediction does, with the filter's own stated
    uncertainty: two fits of different noise models compare by it, not by ``FitResult.cost`` (which holds only the
    :math:`\varepsilon` part, about ``N/2`` for any consistent noise level)."""
    if result.method != "prediction_error":
        raise ValueError(f"the filter's likelihood needs a prediction-error fit (its noise model), got {result.method}")
    return _nll(_held_filter(result, runs))


def choose_disturbance(fits: Mapping[str, FitResult], runs: Sequence[Run]) -> FitResult:
    r"""Of prediction-error fits of one model with different disturbance processes (``{"ou": fit, "wave": fit}``),
    the one of lowest Akaike criterion on the training ``runs``,

    .. math:: \mathrm{AIC} = 2N\bar\ell + 2k,

    with :math:`N\bar\ell` the filter's negative log-likelihood (:func:`neg_log_likelihood`, log-determinants
    included: the fits' ``cost`` cannot compare noise models) and :math:`k` the free coefficients plus the noise
    parameters (a level per channel and per disturbed state, and the process's own: τ for ``ou``; period and
    damping for ``wave``). A fit that is not usable is chosen only where none is. The chosen fit says in its
    messages and ``info["disturbance_choice"]`` what it was chosen against and by how much (Akaike 1974)."""
    if not fits:
        raise ValueError("choose_disturbance needs at least one fit")
    score = {}
    for kind, res in fits.items():
        if res.method != "prediction_error":
            raise ValueError(f"choosing a disturbance needs prediction-error fits, got {res.method} for {kind}")
        held = _held_filter(res, runs)  # one filter pass: the sample count and the likelihood
        n, nll = int(np.sum(np.asarray(held[2].mask, dtype=bool))), _nll(held)
        info = res.info
        k = len(res.free) + len(info.get("measurement_sd", {})) + len(info.get("process_sd", {})) + dist.n_hyper(kind)
        score[kind] = (not res.usable, 2 * n * nll + 2 * k, nll)
    best = min(score, key=lambda kd: score[kd][:2])
    others = "; ".join(f"{kd} {score[kd][1] - score[best][1]:+.1f} (−log L {score[kd][2]:.4f} per sample"
                       + (", not usable" if score[kd][0] else "") + ")" for kd in score if kd != best)
    line = (f"disturbance: {best}, chosen by the Akaike criterion of the filter's likelihood on the training runs "
            f"(−log L {score[best][2]:.4f} per sample; against it: {others})")
    res = fits[best]
    return dataclasses.replace(res, messages=(*res.messages, line), info={
        **res.info, "disturbance_choice": {kd: {"aic": v[1], "neg_log_likelihood_per_sample": v[2], "usable": not v[0]}
                                           for kd, v in score.items()}})


def _nll(held) -> float:
    """:func:`neg_log_likelihood` from the fit's filter over the runs (``held``: :func:`_held_filter`)."""
    _, _, batch, fp = held
    mask = np.asarray(batch.mask, dtype=bool)
    eps, logdet = np.asarray(fp.eps)[mask], np.asarray(fp.logdet)[mask]
    n_c = eps.shape[-1]
    return float(0.5 * np.mean(np.sum(eps ** 2, axis=-1) + logdet + n_c * math.log(2 * math.pi)))


def ahead_table(result: FitResult, train: Sequence[Run], val: Sequence[Run] = (),
                seconds: float = 30.0) -> tuple[str, dict, dict[str, Evaluation]]:
    """The one-sample and ``seconds``-ahead predictions with and without the disturbance, on the training and the
    held-out runs: ``(text, json, evaluations)`` (``evaluations["val"]``/``["train"]``: the ``seconds``-ahead ones
    with the disturbance, the verdict's)."""
    if result.method != "prediction_error":
        raise ValueError(f"k-step-ahead prediction needs a prediction-error fit (its noise model), got {result.method}")
    rows, doc, evs, nll = [], {}, {}, {}
    for label, runs in (("held-out", val), ("training", train)):
        if not runs:
            continue
        held = _held_filter(result, runs, keep=True)  # one filter pass per set of runs, shared by every row
        nll[label] = _nll(held)
        for s in (None, seconds):
            for d in (True, False):
                ev = _ahead(result, runs, held, s, d)
                key = f"{label} {'1 sample' if s is None else f'{s:g} s'} {'with' if d else 'without'} disturbance"
                doc[key] = {"rmse": ev.rmse, "fit_percent": ev.fit_percent}
                rows.append(f"  {key:<44}" + "".join(f"{c} {ev.rmse[c]:.4g} ({ev.fit_percent[c]:.0f} %)  "
                                                      for c in ev.channels))
                if s is not None and d:
                    evs["val" if label == "held-out" else "train"] = ev
    doc["neg_log_likelihood_per_sample"] = nll
    rows.append("  negative log-likelihood per sample (the filter's innovations): "
                + ", ".join(f"{label} {v:.4g}" for label, v in nll.items()))
    text = ("prediction from the Kalman filter's state (RMSE, fit %; a sea state is predicted, not simulated):\n"
            + "\n".join(rows))
    return text, doc, evs
