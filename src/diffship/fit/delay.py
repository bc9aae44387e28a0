r"""Input time delay: shift an input channel, and estimate the delay between input and response.

Two estimators (:func:`estimate_input_delay`): the lag that maximises the cross-correlation of
the differenced input and output (cheap, a bound), or the delay whose refitted model explains the
data best (a grid of refits, equation error or output error).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..errors import DataError
from ..preprocess import Filter, smooth
from .equation_error import fit_equation_error
from .output_error import OutputErrorOptions, fit_output_error

__all__ = ["DelayEstimate", "delay_input", "estimate_input_delay"]


@dataclasses.dataclass(frozen=True)
class DelayEstimate:
    """Result of :func:`estimate_input_delay`.

    Attributes:
        delay: the estimated delay [s] (the input acts on the craft ``delay`` seconds after it
            is logged).
        delays: the candidate delays searched [s].
        scores: the criterion at each candidate (lower is better for ``"refit"``: the fit's
            normalised residual mean square; higher is better for ``"xcorr"``: |correlation|).
        method: ``"refit"`` or ``"xcorr"``.
    """

    delay: float
    delays: np.ndarray
    scores: np.ndarray
    method: str


def delay_input(run, name: str, delay: float):
    """A copy of ``run`` whose input ``name`` is delayed by ``delay`` [s]: u_new(t) = u(t − delay).

    Samples before ``t0 + delay`` hold the first value (linear interpolation in between).
    """
    t = np.asarray(run.time, dtype=np.float64)
    u = np.asarray(run[name], dtype=np.float64)
    return run.with_channels(**{name: np.interp(t - delay, t, u, left=u[0], right=u[-1])})


def estimate_input_delay(runs, input: str, output: str | None = None, *, model=None, max_delay: float = 2.0,
                         step: float | None = None, method: str | None = None, fit: str = "equation_error",
                         flt: Filter = Filter()) -> DelayEstimate:
    """Estimate a pure time delay between a logged input and the motion it causes.

    Two methods (``method`` defaults to ``"refit"`` when a model is given, else ``"xcorr"``):

    * ``"refit"`` (the brute-force search of seed 002, §5.3.4): for each candidate delay d in
      ``[0, max_delay]`` the input is delayed by d, the model is refitted (equation error by
      default — one linear least-squares solve per candidate; ``fit="output_error"`` for the
      slower simulation fit), and the delay with the smallest residual mean square wins. The
      residuals of all equations/channels are normalised by their values at d = 0 so that
      every candidate is scored on the same scale.
    * ``"xcorr"``: the lag in ``[0, max_delay]`` maximising the cross-correlation between the
      input's increments and the derivative of ``output`` (both filtered). This measures the
      delay *plus* the fastest part of the dynamics' lag, so it is an upper bound on the dead
      time; it needs no model.

    Args:
        runs: a :class:`~diffship.data.Run` or a list of runs (uniformly sampled).
        input: input channel, e.g. ``"delta"``.
        output: output channel for ``"xcorr"`` (e.g. ``"r"``).
        model: model for ``"refit"``.
        max_delay: largest delay searched [s].
        step: grid step [s] (default: the sample interval).
    """
    runs = [runs] if not isinstance(runs, (list, tuple)) else list(runs)
    if not runs:
        raise DataError("estimate_input_delay: no runs given")
    dt = float(np.median(np.diff(np.asarray(runs[0].time))))
    step = step or dt
    delays = np.arange(0.0, max_delay + 0.5 * step, step)
    method = method or ("refit" if model is not None else "xcorr")
    for r in runs:
        r.require((input,), "the input time-delay search")
    if flt.kind == "butter" and flt.cutoff is None:
        # a fixed cut-off (10 % of Nyquist) for every shifted refit: a data-chosen one
        # would change with the shift and move the shallow minimum
        flt = Filter("butter", cutoff=0.05 / float(np.median([r.dt for r in runs])))
    if method == "xcorr":
        if output is None:
            raise DataError("estimate_input_delay(method='xcorr') needs the output channel, e.g. output='r'")
        scores = np.zeros(delays.size)
        for r in runs:
            r.require((output,), "the input time-delay search")
            t = np.asarray(r.time)
            du = np.diff(smooth(t, np.asarray(r[input]), flt, f"run {r.name}, column {input}"))
            y = np.asarray(r[output])
            dy = np.diff(smooth(t, np.unwrap(y) if output == "psi" else y, flt, f"run {r.name}, column {output}"))
            du, dy = du - du.mean(), dy - dy.mean()
            for i, d in enumerate(delays):
                k = int(round(d / dt))
                a, b = du[: du.size - k], dy[k:]
                den = float(np.linalg.norm(a) * np.linalg.norm(b))
                scores[i] += abs(float(a @ b)) / den if den > 0 else 0.0
        return DelayEstimate(float(delays[int(np.argmax(scores))]), delays, scores / len(runs), "xcorr")
    if method != "refit":
        raise DataError(f"unknown delay method {method!r}: use 'refit' or 'xcorr'")
    if model is None:
        raise DataError("estimate_input_delay(method='refit') needs a model")
    ms = []
    for d in delays:
        shifted = [delay_input(r, input, float(d)) for r in runs]
        if fit == "equation_error":
            res = fit_equation_error(model, shifted, flt=flt)
        elif fit == "output_error":
            # a profile over the delay: one start (the model's values), as every point of a scan
            res = fit_output_error(model, shifted, options=OutputErrorOptions(flt=flt, weights="spread", ee_start=False),
                                   n_starts=1)
        else:
            raise DataError(f"unknown fit {fit!r}: use 'equation_error' or 'output_error'")
        ms.append(np.array([res.noise_std[c] ** 2 for c in res.channels]))
    ms = np.asarray(ms)
    scores = np.mean(ms / np.maximum(ms[0], 1e-300), axis=1)
    return DelayEstimate(float(delays[int(np.argmin(scores))]), delays, scores, "refit")
