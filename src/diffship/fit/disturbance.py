r"""Stochastic disturbance processes that the prediction-error filter carries as extra states.

At sea the rates of the velocity states receive forces nobody measured: gusts, waves, a wandering current. Each
process below is a linear state-space model driven by white noise, added to the rate of every state in
``process_states`` (:mod:`diffship.fit.prediction_error`): :math:`\dot x_i = f_i(x, u) + w_i`. Its stationary
standard deviation :math:`q_i` [state unit/s] is one noise unknown per state; its time scales are shared by the
states and estimated with the noise levels (the *hyper-parameters*, :data:`HYPER`).

* ``"white"`` — no extra state; white process noise of intensity :math:`q_i^2` [unit²/s] on the state itself.
* ``"ou"`` — Ornstein–Uhlenbeck (wind gusts, slowly varying drift forces), time constant :math:`\tau`:

  .. math:: \dot w = -w/\tau + \sqrt{2/\tau}\,q\,\xi(t).

* ``"wave"`` — a narrow-band process, the wave-induced force at the encounter period :math:`T_w`: a
  second-order resonator of relative damping :math:`\zeta_w`, :math:`\omega_w = 2\pi/T_w`,

  .. math:: \ddot w + 2\zeta_w\omega_w\dot w + \omega_w^2 w = \sqrt{4\zeta_w\omega_w^3}\,q\,\xi(t),

  whose stationary variance is :math:`q^2` (Fossen 2011, §8.2.4: the linear wave-response model; Sørensen 2011).
  A sinusoid of fixed phase cannot carry a wave from one run to another (its phase is random per run); the
  resonator can, because the filter re-estimates its phase from the measurements as it goes.
* ``"walk"`` — a random walk (a current or drift force that wanders without returning), :math:`\dot w = q\,\xi(t)`,
  :math:`q` in [unit/s per √s]; it starts at zero with the variance it gathers in one second, :math:`q^2`·1 s.

Extra filter states are laid out as ``(w_1 … w_nq)`` then, for the wave, ``(ẇ_1 … ẇ_nq)``: ``w_i`` is always the
force added to state ``i``'s rate (:mod:`diffship.fit.smoother` reports it as ``w_<state>``).

Hyper-parameters are positive, parametrised as :math:`h = h_0 e^{\zeta}` with :math:`\zeta` clipped (:data:`CLIP`;
the wave damping to at most 10 times its start), starting at :math:`\zeta = 0`. Measured limitation: in an
open-loop run in a heavy sea (the wave's yaw acceleration six times the rudder's) the likelihood prefers a
"wave" of hundreds of seconds at critical damping beside a 0.7-s ship, even from the truth; a narrower period
range makes the Levenberg–Marquardt path stop on it (a clip has no gradient) and was not kept.
A fit whose hyper-parameter ends on a bound says so.

References:
    T. I. Fossen, *Handbook of Marine Craft Hydrodynamics and Motion Control*, Wiley 2011, §8.2.4.
    A. J. Sørensen, "A survey of dynamic positioning control systems", Annu. Rev. Control 35 (2011).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

__all__ = ["KINDS", "HYPER", "CLIP", "spectral_period", "hyper_starts", "LABEL", "describe", "bounds_text", "n_hyper", "n_extra", "hyper_values", "extra_rates", "extra_noise", "extra_p0"]

#: Disturbance kinds the filter carries.
KINDS = ("white", "ou", "wave", "walk")

#: Names of each kind's hyper-parameters (shared by the noisy states), in the unknowns' order.
HYPER = {"white": (), "ou": ("tau",), "wave": ("wave_period", "wave_damping"), "walk": ()}

CLIP = {"tau": (-10.0, 10.0), "wave_period": (-10.0, 10.0), "wave_damping": (-6.0, 2.3)}


def n_hyper(kind: str) -> int:
    """Number of hyper-parameters of ``kind``."""
    return len(HYPER[kind])


def n_extra(kind: str, n_q: int) -> int:
    """Extra filter states of ``kind`` for ``n_q`` noisy states."""
    return {"white": 0, "ou": n_q, "wave": 2 * n_q, "walk": n_q}[kind]


def hyper_values(kind: str, zeta: Float[Array, " n_h"], h0: Float[Array, " 2"]) -> Float[Array, " 2"]:
    """The hyper-parameters :math:`h_0 e^{\\zeta}` (padded with NaN to two entries)."""
    out = [h0[j] * jnp.exp(jnp.clip(zeta[j], *CLIP[name])) for j, name in enumerate(HYPER[kind])]
    return jnp.stack(out + [jnp.full((), jnp.nan)] * (2 - len(out)))


def extra_rates(kind: str, w: Float[Array, " n_w"], h: Float[Array, " 2"], n_q: int) -> Float[Array, " n_w"]:
    """Time derivative of the extra states (their deterministic part)."""
    if kind == "ou":
        return -w / h[0]
    if kind == "wave":
        om = 2.0 * jnp.pi / h[0]
        f, fd = w[:n_q], w[n_q:]
        return jnp.concatenate([fd, -2.0 * h[1] * om * fd - om ** 2 * f])
    return jnp.zeros_like(w)  # walk


def extra_noise(kind: str, q: Float[Array, " n_q"], h: Float[Array, " 2"]) -> Float[Array, " n_w"]:
    """Intensity (variance per second) of the white noise driving each extra state."""
    if kind == "ou":
        return 2.0 * q ** 2 / h[0]
    if kind == "wave":
        om = 2.0 * jnp.pi / h[0]
        return jnp.concatenate([jnp.zeros_like(q), 4.0 * h[1] * om ** 3 * q ** 2])
    return q ** 2  # walk


def extra_p0(kind: str, q: Float[Array, " n_q"], h: Float[Array, " 2"]) -> Float[Array, " n_w"]:
    """Initial variance of the extra states: the stationary one (a random phase per run); the walk: one second's."""
    if kind == "wave":
        om = 2.0 * jnp.pi / h[0]
        return jnp.concatenate([q ** 2, om ** 2 * q ** 2])
    return q ** 2


def spectral_period(ys: list, dt: float, lo: float = 2.0) -> float:
    """The period [s] of the largest peak of the averaged periodogram of the first differences of every run's
    channels (``ys``: one ``(n, n_c)`` array per run; each channel's periodogram normalised to unit sum), between
    ``lo`` and a third of the shortest run: the wave resonator's start. Differencing takes out the slow steering
    response, so the narrow-band wave stands out."""
    n = min(len(y) for y in ys)
    if n < 16:
        return 8.0
    p = np.zeros(n // 2)
    for y in ys:
        y = np.asarray(y, dtype=float).reshape(len(y), -1)
        for c in range(y.shape[1]):
            d = np.diff(y[:n, c])
            d = (d - d.mean()) * np.hanning(d.size)
            pc = (np.abs(np.fft.rfft(d)) ** 2)[1:][: p.size]
            p[: pc.size] += pc / max(float(pc.sum()), 1e-300)
    f = np.arange(1, p.size + 1) / ((n - 1) * dt)
    ok = (1.0 / f >= lo) & (1.0 / f <= n * dt / 3.0)
    return float(1.0 / f[ok][np.argmax(p[ok])]) if np.any(ok) else 8.0


def hyper_starts(kind: str, tau: float, wave_period: float | None, wave_damping: float, batch) -> np.ndarray:
    """Starts of ``kind``'s hyper-parameters (NaN-padded to two); the wave's period, when not given, from
    :func:`spectral_period` of the batch's fitted channels."""
    if kind == "ou":
        return np.array([tau, np.nan])
    if kind == "wave":
        n = batch.ys.shape[0]
        period = wave_period or spectral_period([batch.ys[i, : batch.lengths[i]] for i in range(n)],
                                                float(np.median(np.diff(batch.ts[0, : batch.lengths[0]]))))
        return np.array([period, wave_damping])
    return np.array([np.nan, np.nan])


#: Readable names of the hyper-parameters (the fit's nuisance unknowns).
LABEL = {"tau": "disturbance time constant", "wave_period": "wave period", "wave_damping": "wave damping"}


def describe(kind: str, hyp) -> str:
    """One phrase for the fitted disturbance (``hyp``: :func:`hyper_values`)."""
    if kind == "wave":
        return f"narrow-band wave, period {float(hyp[0]):.3g} s, relative damping {float(hyp[1]):.3g}"
    return f"Ornstein–Uhlenbeck, time constant {float(hyp[0]):.3g} s" if kind == "ou" else "random walk"


def bounds_text(kind: str, h0) -> str:
    """The hyper-parameters' ranges (:data:`CLIP` around their starts ``h0``), as words."""
    h0 = np.asarray(h0, dtype=float)
    return ", ".join(f"{LABEL[n]} {h0[j] * np.exp(CLIP[n][0]):.3g}–{h0[j] * np.exp(CLIP[n][1]):.3g}"
                     for j, n in enumerate(HYPER[kind]))
