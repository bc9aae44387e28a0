r"""Filtering and numerical differentiation of measured channels.

The equation-error baseline needs time derivatives of measured velocities; this is where
noise is amplified (a derivative multiplies noise at frequency f by 2πf). Filters, all
zero-phase so that they add no lag:

* ``"butter"`` (default): 4th-order Butterworth low-pass applied forwards and backwards
  (``scipy.signal.filtfilt``), cut-off ``cutoff`` [Hz]; default 10 % of the Nyquist
  frequency (0.5 Hz at 10 Hz sampling, 2.5 Hz at 50 Hz). Derivative by central differences
  of the filtered signal.
* ``"savgol"``: Savitzky–Golay local cubic fit over ``window`` [s] (default 1 s), which
  differentiates the fitted polynomial analytically.
* ``"none"``: raw central differences (``numpy.gradient``).

Heading is unwrapped before filtering. Runs must be uniformly sampled for ``butter`` and
``savgol`` (resample first: :meth:`diffship.data.Run.resample`).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy import signal

from .errors import DataError

__all__ = ["Filter", "smooth", "derivative", "smooth_and_derivative"]


@dataclasses.dataclass(frozen=True)
class Filter:
    """A zero-phase smoothing/differentiation choice.

    Attributes:
        kind: ``"butter"``, ``"savgol"`` or ``"none"``.
        cutoff: Butterworth cut-off frequency [Hz]; ``None`` = 10 % of Nyquist.
        order: Butterworth order.
        window: Savitzky–Golay window [s].
    """

    kind: str = "butter"
    cutoff: float | None = None
    order: int = 4
    window: float = 1.0

    def __post_init__(self):
        if self.kind not in ("butter", "savgol", "none"):
            raise DataError(f"unknown filter {self.kind!r}: use 'butter', 'savgol' or 'none'")

    @classmethod
    def parse(cls, text: str) -> Filter:
        """``"butter"``, ``"butter:0.5"`` (cut-off Hz), ``"savgol:1.5"`` (window s) or ``"none"``."""
        kind, _, arg = text.partition(":")
        if not arg:
            return cls(kind)
        try:
            value = float(arg)
        except ValueError:
            raise DataError(f"filter {text!r}: {arg!r} is not a number") from None
        return cls(kind, cutoff=value) if kind == "butter" else cls(kind, window=value)

    def describe(self, dt: float) -> str:
        if self.kind == "butter":
            fc = self.cutoff if self.cutoff is not None else 0.1 * 0.5 / dt
            return f"zero-phase Butterworth order {self.order}, cut-off {fc:.3g} Hz, central differences"
        if self.kind == "savgol":
            return f"Savitzky–Golay cubic, window {self.window:.3g} s"
        return "no filter, central differences"


def _uniform_dt(t: np.ndarray, what: str) -> float:
    dts = np.diff(t)
    dt = float(np.median(dts))
    if np.max(np.abs(dts - dt)) > 1e-3 * dt + 1e-9:
        raise DataError(f"{what}: samples are not uniformly spaced; resample the run first (Run.resample(dt))")
    return dt


def smooth_and_derivative(t: np.ndarray, y: np.ndarray, flt: Filter = Filter(), what: str = "signal"):
    """Smoothed signal and its time derivative (NumPy arrays, same length as ``t``)."""
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if flt.kind == "none":
        return y.copy(), np.gradient(y, t)
    dt = _uniform_dt(t, what)
    n = y.size
    if flt.kind == "butter":
        nyq = 0.5 / dt
        fc = flt.cutoff if flt.cutoff is not None else 0.1 * nyq
        if not 0 < fc < nyq:
            raise DataError(f"{what}: Butterworth cut-off {fc} Hz must lie between 0 and the Nyquist frequency {nyq:g} Hz")
        b, a = signal.butter(flt.order, fc / nyq)
        padlen = min(3 * max(len(a), len(b)), n - 1)
        ys = signal.filtfilt(b, a, y, padlen=padlen)
        return ys, np.gradient(ys, t)
    win = int(round(flt.window / dt)) | 1
    win = max(5, min(win, (n - 1) | 1 if n % 2 == 0 else n))
    if win > n:
        win = n if n % 2 else n - 1
    ys = signal.savgol_filter(y, win, 3, mode="interp")
    yd = signal.savgol_filter(y, win, 3, deriv=1, delta=dt, mode="interp")
    return ys, yd


def smooth(t, y, flt: Filter = Filter(), what: str = "signal") -> np.ndarray:
    return smooth_and_derivative(t, y, flt, what)[0]


def derivative(t, y, flt: Filter = Filter(), what: str = "signal") -> np.ndarray:
    return smooth_and_derivative(t, y, flt, what)[1]


# -- input time delay (seed 002 §5.3.4) ----------------------------------------------------------


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
    from .fit import fit_equation_error, fit_output_error

    ms = []
    for d in delays:
        shifted = [delay_input(r, input, float(d)) for r in runs]
        if fit == "equation_error":
            res = fit_equation_error(model, shifted, flt=flt)
        elif fit == "output_error":
            res = fit_output_error(model, shifted, flt=flt, weights="spread")
        else:
            raise DataError(f"unknown fit {fit!r}: use 'equation_error' or 'output_error'")
        ms.append(np.array([res.noise_std[c] ** 2 for c in res.channels]))
    ms = np.asarray(ms)
    scores = np.mean(ms / np.maximum(ms[0], 1e-300), axis=1)
    return DelayEstimate(float(delays[int(np.argmin(scores))]), delays, scores, "refit")
