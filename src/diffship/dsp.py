r"""The signal processing every fit runs, in NumPy: the zero-phase Butterworth low-pass and Welch's spectrum.

Every fit reads each run's initial state through a zero-phase low-pass filter (:func:`diffship.simulate.initial_state`,
:func:`diffship.preprocess.smooth_and_derivative`), and the equation-error fit chooses its cut-off from the spectrum
(:func:`diffship.preprocess.auto_cutoff`). ``scipy.signal`` computes both, but importing it costs 1.4 s of every
process (it imports ``scipy.stats`` and parses the docstrings of its array-API wrappers), a quarter of the bundled
example's whole fit command. This module gives the numbers of ``scipy.signal.butter``, ``filtfilt`` (odd extension),
``detrend`` and ``welch`` (Hann window, half overlap, density scaling), to rounding.

**Design** (:func:`butter_lowpass`, as ``scipy.signal.butter``; Oppenheim & Schafer, *Discrete-Time Signal
Processing*, 3rd ed., §7.1): the analogue prototype's poles :math:`p_k = -e^{i\pi m/(2N)}`,
:math:`m = -N+1, -N+3, \dots, N-1`, scaled to the pre-warped cut-off :math:`\omega = 4\tan(\pi W_n/2)`, mapped by
the bilinear transform :math:`z = (4 + p)/(4 - p)` with :math:`N` zeros at :math:`z = -1`, kept as second-order
sections (a conjugate pole pair each).

**Filtering** (:func:`lfilter`): the transposed direct form II recurrence as a state space,

.. math::
    s_{k+1} = A s_k + B x_k,\qquad y_k = s_{k,0} + b_0 x_k,

run in blocks of :data:`BLOCK` samples: within a block the output is the free response of the block's start state
plus the convolution with the impulse response (a lower-triangular Toeplitz matrix), so the loop in Python is over
blocks, not samples.

**Zero phase** (:func:`filtfilt`, as ``scipy.signal.filtfilt`` with its default odd extension,
Gustafsson's initial conditions left out as SciPy's default does): the signal is extended at each end by its odd
reflection, filtered forwards from the steady state of its first value (:func:`sosfilt_zi`), then backwards.
"""

from __future__ import annotations

import functools
import math

import numpy as np

__all__ = ["BLOCK", "butter_lowpass", "lfilter", "sosfilt_zi", "filtfilt", "detrend_linear", "welch"]

#: Samples per block of :func:`lfilter` (the Toeplitz matrix is BLOCK × BLOCK).
BLOCK = 128


def butter_lowpass(order: int, wn: float) -> np.ndarray:
    """Second-order sections ``sos`` (``n_sections × 6``: ``b0 b1 b2 1 a1 a2``) of the digital Butterworth low-pass of
    ``order`` and normalised cut-off ``wn`` (a fraction of the Nyquist frequency, 0 < wn < 1): the filter of
    ``scipy.signal.butter(order, wn)``, its conjugate pole pairs as sections (the product of the sections is that
    ``(b, a)``; as sections it stays accurate at low cut-offs, where the polynomial form loses digits)."""
    n = int(order)
    if n < 1 or not 0.0 < float(wn) < 1.0:
        raise ValueError(f"Butterworth order {order} and cut-off {wn}: need order ≥ 1 and 0 < cut-off < 1")
    m = np.arange(-n + 1, n, 2)
    warped = 4.0 * math.tan(math.pi * float(wn) / 2.0)
    p = -warped * np.exp(1j * math.pi * m / (2 * n))
    pz = (4.0 + p) / (4.0 - p)
    gain = warped ** n * np.real(1.0 / np.prod(4.0 - p))
    sections = []
    for z in pz[np.imag(pz) > 0]:  # a conjugate pair and two zeros at z = -1
        sections.append([1.0, 2.0, 1.0, 1.0, -2.0 * z.real, abs(z) ** 2])
    if n % 2:  # the real pole and one zero at z = -1
        sections.append([1.0, 1.0, 0.0, 1.0, -float(np.real(pz[np.argmin(np.abs(np.imag(pz)))])), 0.0])
    sos = np.asarray(sections)
    sos[0, :3] *= gain
    return sos


def _state_space(b, a) -> tuple[np.ndarray, np.ndarray]:
    """``(A, B)`` of the transposed direct form II states (``b``, ``a`` of one length, ``a[0] = 1``)."""
    n = a.size - 1
    A = np.eye(n, k=1) - np.outer(a[1:], np.eye(n)[0])
    return A, b[1:] - a[1:] * b[0]


def _section(row) -> tuple[np.ndarray, np.ndarray]:
    b, a = np.asarray(row[:3], dtype=np.float64), np.asarray(row[3:], dtype=np.float64)
    return b / a[0], a / a[0]


def sosfilt_zi(sos: np.ndarray) -> np.ndarray:
    """Each section's state (``n_sections × 2``) in the steady state of the cascade for a unit step at its input:
    ``scipy.signal.sosfilt_zi``."""
    out, level = [], 1.0
    for row in np.atleast_2d(sos):
        b, a = _section(row)
        A, B = _state_space(b, a)
        out.append(level * np.linalg.solve(np.eye(2) - A, B))
        level *= b.sum() / a.sum()  # the section's gain at zero frequency
    return np.asarray(out)


@functools.lru_cache(maxsize=64)
def _blocks(coeffs: tuple[float, ...], L: int) -> tuple[np.ndarray, ...]:
    """``(P, T, G, A^L)`` of the filter ``coeffs = (*b, *a)`` for blocks of ``L`` samples: the free-response rows
    :math:`C A^j` (:math:`C = e_0^\\top`), the Toeplitz matrix of the impulse response :math:`h_0 = b_0`,
    :math:`h_j = C A^{j-1} B`, and the block-end maps. Built once per filter: a zero-phase pass runs every section
    twice, and every run's channels share one filter."""
    b, a = np.asarray(coeffs[:len(coeffs) // 2]), np.asarray(coeffs[len(coeffs) // 2:])
    n = a.size - 1
    A, B = _state_space(b, a)
    P, h, G = np.zeros((L, n)), np.zeros(L), np.zeros((n, L))
    Aj = np.eye(n)
    h[0] = b[0]
    for j in range(L):
        P[j] = Aj[0]
        if j + 1 < L:
            h[j + 1] = Aj[0] @ B
        G[:, L - 1 - j] = Aj @ B
        Aj = A @ Aj
    idx = np.arange(L)
    T = np.where(idx[:, None] >= idx[None, :], h[np.clip(idx[:, None] - idx[None, :], 0, L - 1)], 0.0)
    return P, T, G, Aj


def lfilter(b, a, x: np.ndarray, zi: np.ndarray | None = None) -> np.ndarray:
    """``y`` of the IIR filter ``(b, a)`` (of one length, ``a[0] = 1``) on ``x`` from state ``zi`` (default zero):
    ``scipy.signal.lfilter(b, a, x, zi=zi)[0]`` (module docstring: blocks of :data:`BLOCK` samples)."""
    b, a = np.asarray(b, dtype=np.float64), np.asarray(a, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    n = a.size - 1
    L = min(BLOCK, max(x.size, 1))
    P, T, G, AL = _blocks(tuple(map(float, b)) + tuple(map(float, a)), L)
    nb = -(-x.size // L)
    X = np.zeros(nb * L)
    X[:x.size] = x
    X = X.reshape(nb, L)
    GX = X @ G.T  # each block's input contribution to the next block's start state
    Z = np.zeros((nb, n))
    z = np.zeros(n) if zi is None else np.asarray(zi, dtype=np.float64)
    for i in range(nb):
        Z[i] = z
        z = AL @ z + GX[i]
    Y = Z @ P.T + X @ T.T
    return Y.reshape(-1)[:x.size]


def _cascade(sos: np.ndarray, x: np.ndarray, zi: np.ndarray) -> np.ndarray:
    for row, z in zip(np.atleast_2d(sos), zi):
        x = lfilter(*_section(row), x, z)
    return x


def filtfilt(sos: np.ndarray, x: np.ndarray, padlen: int) -> np.ndarray:
    """Zero-phase filtering of ``x`` by the sections ``sos`` forwards and backwards, ``x`` extended by its odd
    reflection of ``padlen`` samples at each end, each pass from the steady state of its first value:
    ``scipy.signal.filtfilt(b, a, x, padlen=padlen)`` of the sections' product ``(b, a)``."""
    x = np.asarray(x, dtype=np.float64)
    edge = int(padlen)
    if not 0 <= edge < x.size:
        raise ValueError(f"filtfilt: a pad of {edge} samples needs a signal longer than it (got {x.size})")
    ext = np.concatenate([2 * x[0] - x[edge:0:-1], x, 2 * x[-1] - x[-2:-(edge + 2):-1]]) if edge else x
    zi = sosfilt_zi(sos)
    y = _cascade(sos, ext, zi * ext[0])
    y = _cascade(sos, y[::-1], zi * y[-1])[::-1]
    return y[edge:-edge] if edge else y


def detrend_linear(y: np.ndarray) -> np.ndarray:
    """``y`` less its least-squares straight line over the sample index: ``scipy.signal.detrend(y)``."""
    y = np.asarray(y, dtype=np.float64)
    k = np.arange(y.size, dtype=np.float64)
    A = np.stack([k, np.ones_like(k)], axis=1)
    return y - A @ np.linalg.lstsq(A, y, rcond=None)[0]


def welch(y: np.ndarray, fs: float, nperseg: int) -> tuple[np.ndarray, np.ndarray]:
    r"""``(f, P)``: Welch's power spectral density of ``y`` sampled at ``fs`` [Hz]: the mean over segments of
    ``nperseg`` samples (at most ``y``'s length), overlapping by half, each less its mean and windowed by the
    periodic Hann window :math:`w_k`, of :math:`|\mathrm{DFT}|^2 / (f_s \sum_k w_k^2)`, one-sided:
    ``scipy.signal.welch(y, fs=fs, nperseg=nperseg)`` (Welch, IEEE Trans. Audio Electroacoust. 15, 1967)."""
    y = np.asarray(y, dtype=np.float64)
    m = min(int(nperseg), y.size)
    step = m - m // 2
    w = 0.5 - 0.5 * np.cos(2.0 * math.pi * np.arange(m) / m)
    count = (y.size - m // 2) // step
    segs = np.stack([y[i * step:i * step + m] for i in range(count)])
    segs = segs - segs.mean(axis=1, keepdims=True)
    P = np.abs(np.fft.rfft(segs * w, n=m, axis=1)) ** 2 / (fs * float(np.sum(w * w)))
    P[:, 1:-1 if m % 2 == 0 else None] *= 2.0
    return np.fft.rfftfreq(m, 1.0 / fs), P.mean(axis=0)
