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
from collections.abc import Sequence

import numpy as np

from .data import Run
from .integrators import AbstractIntegrator, Diffrax
from .models import AbstractModel
from .preprocess import Filter
from .simulate import initial_state, simulate_run

__all__ = ["Evaluation", "evaluate", "simulate_run", "rmse", "nrmse_fit"]


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


def evaluate(
    model: AbstractModel,
    runs: Sequence[Run],
    x0: Sequence[np.ndarray] | None = None,
    *,
    channels: Sequence[str] | None = None,
    flt: Filter = Filter(),
    integrator: AbstractIntegrator = Diffrax(),
) -> Evaluation:
    """Simulate ``model`` on every run (whole horizon) and compare with the measurements.

    ``x0``: initial states per run; by default from the filtered measurements at the first sample
    (:func:`diffship.simulate.initial_state`) — **the one initial-state rule** of every metric
    diffship reports: ``python -m diffship.fit`` judges training and ``--validate`` runs this way,
    so a file fitted and then validated gives the same fit % (pass a fit's ``initial_states`` to
    see the fit's own estimated starts instead). ``integrator``: use the fit's
    (``fit.integrator``) so the model is judged as it was fitted.
    """

    pooled_e: dict[str, list] = {}
    pooled_y: dict[str, list] = {}
    per_run, simulated = {}, {}
    all_ok = True
    chans_all = set()
    for i, run in enumerate(runs):
        xi = np.asarray(x0[i]) if x0 is not None else initial_state(model, run, flt)
        sol = simulate_run(model, run, xi, integrator)
        ok = bool(sol.ok)
        all_ok &= ok
        ys = np.asarray(sol.ys)
        chans = [c for c in (channels or model.output_names) if c in model.output_names and run.has(c)]
        chans_all.update(chans)
        simulated[run.name] = {c: ys[:, model.output_names.index(c)] for c in model.output_names}
        rr, ff = {}, {}
        for c in chans:
            y = np.asarray(run[c])
            yh = simulated[run.name][c]
            e = _err(c, y, yh, model.angle_outputs)
            yv = np.unwrap(y) if c in model.angle_outputs else y
            rr[c], ff[c] = rmse(e), nrmse_fit(yv, e)
            pooled_e.setdefault(c, []).append(e)
            pooled_y.setdefault(c, []).append(yv - np.mean(yv))
        per_run[run.name] = {"rmse": rr, "fit_percent": ff, "ok": ok}
    order = tuple(c for c in model.output_names if c in chans_all)
    r_all = {c: rmse(np.concatenate(pooled_e[c])) for c in order}
    f_all = {c: nrmse_fit(np.concatenate(pooled_y[c]), np.concatenate(pooled_e[c])) for c in order}
    return Evaluation(order, r_all, f_all, per_run, simulated, all_ok)
