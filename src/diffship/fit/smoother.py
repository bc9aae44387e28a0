r"""EKF + Rauch–Tung–Striebel smoothing of measured runs: states and accelerations with uncertainty.

The equation-error baseline needs velocities and accelerations; the filters used so far
(:class:`diffship.preprocess.Filter`: zero-phase Butterworth, Savitzky–Golay) know nothing of
the ship. The VMM/wPCC practice of seed 000 runs an extended Kalman filter over a model of the
ship and smooths backwards (RTS) before the regression: every state, measured or not, comes
with a standard deviation, and the measured channels are smoothed consistently with the
dynamics and the sensor noise.

Forward pass: the prediction-error method's filter (:func:`diffship.fit.prediction_error.ekf`,
Ornstein–Uhlenbeck disturbance states by default) at the model's parameter values. Backward pass
(Särkkä 2013, §8.2), for :math:`k = N-2, \dots, 0`:

.. math::
    C_k = P_{k|k} A_k^\top P_{k+1|k}^{-1},\quad
    \hat x_{k|N} = \hat x_{k|k} + C_k(\hat x_{k+1|N} - \hat x_{k+1|k}),\quad
    P_{k|N} = P_{k|k} + C_k(P_{k+1|N} - P_{k+1|k})C_k^\top .

The noise levels are given, or estimated first by the prediction-error likelihood with every
model parameter held (the one kernel's LM over the noise unknowns only). The smoothed runs carry
the model's output channels at the smoothed state (``psi``, ``r``, ``u``, ``v``, …), their
standard deviations (``sd_<channel>``) and the smoothed disturbance; the equation-error
baseline then differentiates them with central differences (:class:`KalmanSmoother` is the
``Filter``-like choice: ``flt=KalmanSmoother()`` where the equation-error code takes it, or
``runs, _ = KalmanSmoother().apply(model, runs)`` and ``flt=Filter("none")``).

The smoother's model is the one being identified, at its starting values: where those are far
off, the disturbance states absorb the difference (they are estimated, not assumed zero), and
the smoothed signals stay close to the measurements; the equation-error regression is then
run on the smoothed signals.

Reference: S. Särkkä, *Bayesian Filtering and Smoothing*, Cambridge 2013, §8.2 (extended RTS).
H. E. Rauch, F. Tung, C. T. Striebel, AIAA Journal 3(8), 1965.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ..data import Run
from ..models import AbstractModel
from .output_error import OutputErrorOptions
from .prediction_error import FilterPass, PredictionErrorOptions, pe_problem

__all__ = ["KalmanSmoother", "rts"]


def rts(fp: FilterPass) -> tuple[Float[Array, "N n"], Float[Array, "N n n"]]:
    """Rauch–Tung–Striebel backward pass over one run's filter pass (``ekf(..., keep=True)``)."""

    def back(carry, inp):
        xs, Ps = carry
        xf, Pf, xp, Pp, A = inp
        C = jax.scipy.linalg.solve(Pp, A @ Pf, assume_a="pos").T
        x = xf + C @ (xs - xp)
        P = Pf + C @ (Ps - Pp) @ C.T
        P = 0.5 * (P + P.T)
        return (x, P), (x, P)

    last = (fp.xf[-1], fp.Pf[-1])
    _, (xs, Ps) = jax.lax.scan(back, last, (fp.xf[:-1], fp.Pf[:-1], fp.xp[:-1], fp.Pp[:-1], fp.A[:-1]), reverse=True)
    return jnp.concatenate([xs, last[0][None]]), jnp.concatenate([Ps, last[1][None]])


@dataclasses.dataclass(frozen=True)
class KalmanSmoother:
    """EKF + RTS smoothing as a preprocessing choice (module docstring).

    Attributes:
        channels: channels the filter measures (default: the model's outputs present in every
            run except absolute positions).
        noise: the noise model (given levels are used as they are when
            ``noise.estimate_noise`` is false; otherwise estimated first).
        options: integrator and initial-state filter (as for output error).
        max_steps: Levenberg–Marquardt steps for the noise levels (they need not be precise:
            the smoothed signals change little once the levels are right within tens of percent).
    """

    channels: tuple[str, ...] | None = None
    noise: PredictionErrorOptions = PredictionErrorOptions()
    options: OutputErrorOptions = OutputErrorOptions()
    max_steps: int = 30
    kind: str = "kalman"

    def describe(self, dt: float) -> str:
        d = "Ornstein–Uhlenbeck disturbance" if self.noise.disturbance == "ou" else "white process noise"
        return f"extended Kalman filter + RTS smoother over the model ({d}), central differences"

    def apply(self, model: AbstractModel, runs: Sequence[Run]) -> tuple[list[Run], dict]:
        """Smoothed copies of ``runs`` (channels at the smoothed state, plus ``sd_<channel>``) and
        what was estimated (``measurement_sd``, ``process_sd``, ``disturbance_tau``)."""
        spec = model.spec().fix(model.spec().free_names)
        kernel, data, batch, pstates = pe_problem(model, runs, spec, self.channels, self.options, self.noise)
        z = np.ones(kernel.n_noise)
        if kernel.n_noise:
            # loose on purpose (class docstring): the plain step/cost tests, no Gauss–Newton-step check
            z, _, _, _ = kernel.call("solve", z, data, max_steps=self.max_steps, rtol=1e-3, atol=1e-3,
                                     gntol=float("inf"))
        fp = kernel.filter(jnp.asarray(z), data, keep=True)
        xs, Ps = jax.vmap(rts)(fp)
        q, r, tau = (np.asarray(a) for a in kernel.noise(jnp.asarray(z), data))
        n_x = len(model.state_names)
        out = []
        for i, run in enumerate(runs):
            n = run.n
            x, P = np.asarray(xs[i, :n]), np.asarray(Ps[i, :n])
            us = np.asarray(data.us[i, :n])
            ys = np.asarray(jax.vmap(model.observe)(jnp.asarray(x[:, :n_x]), jnp.asarray(us)))
            H = np.asarray(jax.vmap(jax.jacfwd(model.observe))(jnp.asarray(x[:, :n_x]), jnp.asarray(us)))
            var = np.einsum("kcx,kxy,kcy->kc", H, P[:, :n_x, :n_x], H)
            chans = {}
            for j, c in enumerate(model.output_names):
                if run.has(c) or c in batch.channels:
                    chans[c] = ys[:, j]
                    chans[f"sd_{c}"] = np.sqrt(np.maximum(var[:, j], 0.0))
            for j, s in enumerate(pstates):
                if kernel.coloured:
                    chans[f"w_{s}"] = x[:, n_x + j]
            out.append(run.with_channels(**chans))
        info = {"measurement_sd": dict(zip(batch.channels, np.sqrt(r).tolist())),
                "process_sd": dict(zip(pstates, q.tolist())), "disturbance_tau": float(tau[0]),
                "method": self.describe(runs[0].dt)}
        return out, info
