r"""Fit metrics from whole-horizon simulation.

Every metric here comes from simulating each run over its **whole horizon** from its initial
state with the run's measured inputs — never from one-step-ahead predictions — so
equation-error and output-error fits are judged the same way.

* RMSE per channel (heading error wrapped to (−π, π]);
* NRMSE fit % :math:`= 100\,(1 - \lVert y - \hat y\rVert / \lVert y - \bar y\rVert)` (100 % is
  perfect, 0 % is no better than the mean, negative is worse).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

import numpy as np

from .data import Run
from .integrators import AbstractIntegrator, Diffrax
from .models import AbstractModel
from .preprocess import Filter
from .initial import estimate_starts
from .simulate import simulate_run

__all__ = ["Evaluation", "evaluate", "nrmse_fit", "rmse", "simulate_run", "start_channels", "start_state"]


def _err(c: str, y: np.ndarray, yh: np.ndarray, angles) -> np.ndarray:
    e = yh - y
    if c in angles:
        e = np.arctan2(np.sin(e), np.cos(e))
    return e


def rmse(e: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(e))))


def nrmse_fit(y: np.ndarray, e: np.ndarray) -> float:
    d = np.linalg.norm(y - np.mean(y))
    return float(100.0 * (1.0 - np.linalg.norm(e) / d)) if d > 0 else float("nan")


@dataclasses.dataclass(frozen=True, eq=False)
class Evaluation:
    """Simulated channels and metrics of one model on a set of runs.

    Attributes:
        channels: channels compared (model outputs present in the runs).
        rmse: ``{channel: RMSE}`` over all runs pooled.
        fit_percent: ``{channel: NRMSE fit %}`` pooled.
        per_run: ``{run: {"rmse": {...}, "fit_percent": {...}, "ok": bool}}``.
        simulated: ``{run: {channel: array}}`` for plots.
        ok: no simulation blew up.
    """

    channels: tuple[str, ...]
    rmse: dict[str, float]
    fit_percent: dict[str, float]
    per_run: dict[str, dict]
    simulated: dict[str, dict[str, np.ndarray]]
    ok: bool
    horizon: str = "whole-run simulation from the initial state"

    def errors(self, runs: Sequence[Run], channels: Sequence[str], angles: Sequence[str] = ()) -> dict:
        """``{run: {channel: simulated − measured}}`` (angles wrapped to (−π, π]) on the ``channels`` every run logs."""
        chans = [c for c in channels if all(r.has(c) and c in self.simulated[r.name] for r in runs)]
        return {r.name: {c: _err(c, np.asarray(r[c], dtype=float), np.asarray(self.simulated[r.name][c]), angles)
                         for c in chans} for r in runs}


#: Channels that are not part of the initial-state estimate unless a fit fitted them (positions).
NOT_ESTIMATED_BY_DEFAULT = ("x0", "y0")


def start_channels(model: AbstractModel, runs: Sequence[Run], fitted: Sequence[str] | None = None) -> tuple[str, ...]:
    """The channels a run's initial state is estimated on: the fit's channels where given (and in every
    run), else every output of the model the runs have except positions."""
    chans = tuple(c for c in (fitted or ()) if c in model.output_names and all(r.has(c) for r in runs))
    if chans:  # (an equation-error fit's channels are its equations: the default then)
        return chans
    return tuple(c for c in model.output_names if c not in NOT_ESTIMATED_BY_DEFAULT and all(r.has(c) for r in runs))


def start_state(model: AbstractModel, run: Run, flt: Filter = Filter(), *, integrator: AbstractIntegrator = Diffrax(),
                channels: Sequence[str] | None = None, scales: Mapping[str, float] | None = None) -> np.ndarray:
    r"""**The initial-state rule of every metric** (:mod:`diffship.initial`, the rule every fit uses): the run's
    initial state estimated over the whole run with the model held, each measured state within its sensor
    noise (a prior row centred on its first sample), states no channel measures free, the data's value for
    the rest; the output errors weighted by the fit's channel scales ``scales`` (``FitResult.channel_scales``;
    default: the residual RMS at the measured start times the square root of its correlation time).

    The first sample alone keeps all of its sensor noise, and a whole-horizon simulation carries that start
    error to the end (an error in r grows into a heading offset of about :math:`T\,\delta r`), so the true
    model would score above the sensor noise; estimated on the run, the start error shrinks with the run's
    effective sample count, and a structurally wrong model, whose residuals have few effective samples,
    cannot move its start away from the log. ``channels``: the fit's channels (default
    :func:`start_channels`)."""
    return _starts(model, [run], flt, integrator, channels, scales)[0]


def _starts(model, runs, flt, integrator, channels, scales) -> list[np.ndarray]:
    chans = start_channels(model, runs, channels)
    if scales is not None and not all(c in scales for c in chans):
        scales = None  # e.g. an equation-error fit's scales are its equations'
    return estimate_starts(model, runs, chans, scales, flt=flt, integrator=integrator)


def evaluate(
    model: AbstractModel,
    runs: Sequence[Run],
    x0: Sequence[np.ndarray] | None = None,
    *,
    channels: Sequence[str] | None = None,
    flt: Filter = Filter(),
    integrator: AbstractIntegrator = Diffrax(),
    fitted: Sequence[str] | None = None,
    scales: Mapping[str, float] | None = None,
) -> Evaluation:
    """Simulate ``model`` on every run (whole horizon) and compare with the measurements.

    ``x0``: initial states per run; by default :func:`start_state` — **the one initial-state rule** of every
    fit and metric diffship reports (:mod:`diffship.initial`), estimated on the fit's channels ``fitted``
    with the fit's channel scales ``scales`` (``FitResult.channels``, ``FitResult.channel_scales``):
    ``python -m diffship.fit`` judges training and ``--validate`` runs this way, and a training run
    scored so starts where the fit started it. ``integrator``: use the fit's (``fit.integrator``) so the
    model is judged as it was fitted.
    """

    simulated, ok = {}, {}
    starts = list(x0) if x0 is not None else _starts(model, runs, flt, integrator, fitted, scales)
    for i, run in enumerate(runs):
        sol = simulate_run(model, run, np.asarray(starts[i]), integrator)
        ok[run.name] = bool(sol.ok)
        ys = np.asarray(sol.ys)
        simulated[run.name] = {c: ys[:, model.output_names.index(c)] for c in model.output_names}
    wanted = channels or model.output_names
    return compare(runs, simulated, [c for c in model.output_names if c in wanted], model.angle_outputs, ok)


def compare(runs: Sequence[Run], simulated: Mapping[str, Mapping[str, np.ndarray]], channels: Sequence[str],
            angles: Sequence[str], ok: Mapping[str, bool], skip: int = 0,
            horizon: str = "whole-run simulation from the initial state") -> Evaluation:
    """Metrics of ``simulated`` (``{run: {channel: array}}``) against the runs' measurements on ``channels`` (those
    each run logs and ``simulated`` holds), from sample ``skip`` on; ``ok``: whether each run's model output is
    valid. :func:`evaluate` and the k-step-ahead predictions (:mod:`diffship.fit.ahead`) are scored by it."""
    pooled_e: dict[str, list] = {}
    pooled_y: dict[str, list] = {}
    per_run = {}
    for run in runs:
        chans = [c for c in channels if c in simulated[run.name] and run.has(c)]
        rr, ff = {}, {}
        for c in chans:
            y = np.asarray(run[c], dtype=float)[skip:]
            e = _err(c, y, np.asarray(simulated[run.name][c])[skip:], angles)
            yv = np.unwrap(y) if c in angles else y
            rr[c], ff[c] = rmse(e), nrmse_fit(yv, e)
            pooled_e.setdefault(c, []).append(e)
            pooled_y.setdefault(c, []).append(yv - np.mean(yv))
        per_run[run.name] = {"rmse": rr, "fit_percent": ff, "ok": bool(ok[run.name])}
    order = tuple(c for c in channels if c in pooled_e)
    r_all = {c: rmse(np.concatenate(pooled_e[c])) for c in order}
    f_all = {c: nrmse_fit(np.concatenate(pooled_y[c]), np.concatenate(pooled_e[c])) for c in order}
    return Evaluation(order, r_all, f_all, per_run, dict(simulated), all(ok[r.name] for r in runs), horizon=horizon)
