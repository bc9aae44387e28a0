r"""Filtering and numerical differentiation of measured channels.

The equation-error baseline needs time derivatives of measured velocities; this is where
noise is amplified (a derivative multiplies noise at frequency f by 2πf). Filters, all
zero-phase so that they add no lag:

* ``"butter"`` (default): 4th-order Butterworth low-pass applied forwards and backwards
  (:func:`diffship.dsp.filtfilt`, the numbers of ``scipy.signal.filtfilt``), cut-off ``cutoff``
  [Hz]: a number, ``"auto"`` — chosen **from
  the data, per channel** (:func:`auto_cutoff`: where the signal's spectrum meets its noise
  floor), so that fast degrees of freedom (roll and pitch of a small ROV) are not filtered away
  and slow ones not left noisy; what the equation-error fit uses unless told otherwise — or
  ``None``, 10 % of the Nyquist frequency (heavy smoothing, for initial states taken from the
  data). Derivative by central differences of the filtered signal.
* ``"savgol"``: Savitzky–Golay local cubic fit over ``window`` [s] (default 1 s), which
  differentiates the fitted polynomial analytically.
* ``"none"``: raw central differences (``numpy.gradient``).

Heading is unwrapped before filtering. Runs must be uniformly sampled for ``butter`` and
``savgol`` (resample first: :meth:`diffship.data.Run.resample`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .errors import DataError
from .dsp import butter_lowpass, detrend_linear, filtfilt, welch

__all__ = ["Filter", "smooth", "derivative", "smooth_and_derivative", "auto_cutoff"]


@dataclasses.dataclass(frozen=True)
class Filter:
    """A zero-phase smoothing/differentiation choice.

    Attributes:
        kind: ``"butter"``, ``"savgol"`` or ``"none"``.
        cutoff: Butterworth cut-off frequency [Hz]; ``"auto"`` = chosen per channel from the data
            (:func:`auto_cutoff`); ``None`` = 10 % of Nyquist (the equation-error fit reads
            ``None`` as ``"auto"``).
        order: Butterworth order.
        window: Savitzky–Golay window [s].
    """

    kind: str = "butter"
    cutoff: float | str | None = None
    order: int = 4
    window: float = 1.0

    def __post_init__(self):
        if self.kind not in ("butter", "savgol", "none"):
            raise DataError(f"unknown filter {self.kind!r}: use 'butter', 'savgol' or 'none'")
        if isinstance(self.cutoff, str) and self.cutoff != "auto":
            raise DataError(f"filter cut-off {self.cutoff!r}: give a frequency in Hz or 'auto'")

    @classmethod
    def parse(cls, text: str) -> Filter:
        """``"butter"``, ``"butter:0.5"`` (cut-off Hz), ``"butter:auto"``, ``"savgol:1.5"`` (window s) or ``"none"``."""
        kind, _, arg = text.partition(":")
        if not arg:
            return cls(kind)
        if kind == "butter" and arg == "auto":
            return cls(kind, cutoff="auto")
        try:
            value = float(arg)
        except ValueError:
            raise DataError(f"filter {text!r}: {arg!r} is not a number") from None
        return cls(kind, cutoff=value) if kind == "butter" else cls(kind, window=value)

    def describe(self, dt: float) -> str:
        if self.kind == "butter":
            fc = ("chosen per channel from the noise floor" if self.cutoff == "auto"
                  else f"{self.cutoff if self.cutoff is not None else 0.1 * 0.5 / dt:.3g} Hz")
            return f"zero-phase Butterworth order {self.order}, cut-off {fc}, central differences"
        if self.kind == "savgol":
            return f"Savitzky–Golay cubic, window {self.window:.3g} s"
        return "no filter, central differences"


def _uniform_dt(t: np.ndarray, what: str) -> float:
    dts = np.diff(t)
    dt = float(np.median(dts))
    if np.max(np.abs(dts - dt)) > 1e-3 * dt + 1e-9:
        raise DataError(f"{what}: samples are not uniformly spaced; resample the run first (Run.resample(dt))")
    return dt


def auto_cutoff(y: np.ndarray, dt: float, *, snr: float = 100.0, lo: float = 0.02, hi: float = 0.6) -> float:
    r"""Butterworth cut-off [Hz] where the signal's spectrum meets its noise floor.

    Welch power spectrum of the linearly detrended signal (segments of 256 samples at most);
    the noise floor :math:`P_0` is the median power above 60 % of the Nyquist frequency
    :math:`f_N` (white sensor noise is flat there); the cut-off is the lowest frequency above
    which the spectrum stays below ``snr``·:math:`P_0`, clipped to ``[lo, hi]``·:math:`f_N`. A
    noise-free signal has only the window's leakage as its floor and gets a high cut-off.

    ``snr = 100`` (20 dB): differentiation multiplies the noise at f by (2πf)², so the
    derivative near the cut-off is clean only where the signal stands well above the floor.
    Measured on the 6-DOF ROV at 10 Hz (equation error, 18 parameters, 3 noise seeds): 10 dB
    left the added inertias 4–6 standard errors off; 20 dB put all 18 within 3.
    """
    y = np.asarray(y, dtype=np.float64)
    n = y.size
    nyq = 0.5 / dt
    if n < 32 or not np.any(y != y[0]):
        return hi * nyq
    f, P = welch(detrend_linear(y), 1.0 / dt, min(256, n))
    tail = f > 0.6 * nyq
    floor = float(np.median(P[tail])) if np.any(tail) else 0.0
    if floor <= 0 or not np.isfinite(floor):
        return hi * nyq
    above = np.flatnonzero(P > snr * floor)
    fc = f[above[-1] + 1] if above.size and above[-1] + 1 < f.size else hi * nyq
    return float(np.clip(fc, lo * nyq, hi * nyq))


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
        fc = auto_cutoff(y, dt) if flt.cutoff == "auto" else flt.cutoff if flt.cutoff is not None else 0.1 * nyq
        if not 0 < fc < nyq:
            raise DataError(f"{what}: Butterworth cut-off {fc} Hz must lie between 0 and the Nyquist frequency {nyq:g} Hz")
        # in NumPy (diffship.dsp): every fit reads its initial states through this filter, and importing
        # scipy.signal cost 1.4 s of every process
        ys = filtfilt(butter_lowpass(flt.order, fc / nyq), y, padlen=min(3 * (flt.order + 1), n - 1))
        return ys, np.gradient(ys, t)
    from scipy import signal  # imported here (Savitzky–Golay only): scipy.signal costs 1.4 s of a process's start
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
