"""Synthetic benchmark cases with known truth (data generators and one extra truth model).

* :class:`NomotoCubic` — a nonlinear Nomoto truth, :math:`T\dot r + r + a r^3 = K(\delta+\delta_0)`,
  used to generate data that the *linear* Nomoto model is then fitted to (model-structure error).
* :func:`nomoto_case_runs` — zigzag-like rudder runs (training and validation manoeuvres differ),
  with an optional input time delay the fitted model does not know about: the truth is driven by
  :math:`\delta(t-\tau)` while the run records :math:`\delta(t)`.
* :func:`vmm_case_runs`, :func:`rov_case_runs` — excitation runs of the VMM ship and the 6-DOF ROV
  (the same recipes as the model tests' helpers).
"""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp
import numpy as np

from diffship.models._base import AbstractModel, scalar
from diffship.params import Param
from diffship.synthetic import rudder_sequence, simulate_run

DEG = np.pi / 180.0


class NomotoCubic(AbstractModel):
    r"""Nonlinear first-order Nomoto model (Norrbin-type cubic yaw damping).

    .. math:: \dot\psi = r,\qquad T\dot r + r + a r^3 = K(\delta + \delta_0)

    States ``(psi, r)``, input ``delta`` [rad]; ``a`` [s²]. With ``a = 0`` it is :class:`Nomoto1`.
    """

    name: ClassVar[str] = "nomoto_cubic"
    state_names: ClassVar[tuple[str, ...]] = ("psi", "r")
    output_names: ClassVar[tuple[str, ...]] = ("psi", "r")
    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("K", 0.2, scale=0.5, unit="1/s", description="rudder gain"),
        Param("T1", 8.0, lower=0.0, scale=5.0, unit="s", description="yaw time constant"),
        Param("a", 50.0, scale=50.0, unit="s2", description="cubic yaw damping"),
        Param("delta0", 0.0, scale=0.01, unit="rad", description="rudder offset"),
    )
    K: jnp.ndarray = scalar(0.2)
    T1: jnp.ndarray = scalar(8.0)
    a: jnp.ndarray = scalar(50.0)
    delta0: jnp.ndarray = scalar(0.0)

    @property
    def input_names(self) -> tuple[str, ...]:
        return ("delta",)

    def vector_field(self, t, x, u):
        r = x[1]
        return jnp.stack([r, (self.K * (u[0] + self.delta0) - r - self.a * r * r * r) / self.T1])


TRAIN_MANOEUVRES = ((10.0, 20.0), (-20.0, 30.0))  # (amplitude deg, period s)
VAL_MANOEUVRES = ((15.0, 25.0), (-25.0, 40.0))


def nomoto_case_runs(truth, *, which="train", duration=60.0, dt=0.1, noise="realistic", seed=0, delay=0.0):
    """Zigzag-like rudder runs of ``truth``; validation runs use different amplitudes/periods."""
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


def vmm_case_runs(model, n_runs=2, duration=300.0, dt=0.5, noise="realistic", seed=0, first=0):
    """Open-loop alternating-rudder runs (10°–25°, 2.3°/s) with ±20–30 % thrust steps."""
    from diffship.models.vmm import approach_thrust

    T0 = approach_thrust(float(model.X0), float(model.XT), float(model.U0), float(model.L), float(model.rho))
    out = []
    for j in range(n_runs):
        i = first + j
        t = np.arange(0.0, duration + dt / 2, dt)
        amp = [10, -20, 15, -25][i % 4] * DEG
        period = [60.0, 80.0, 70.0, 90.0][i % 4]
        delta = rudder_sequence(t, amp, period, rate=2.3 * DEG, start=5.0)
        thrust = T0 * (1 + [0.3, -0.3, 0.2, -0.2][i % 4] * ((t > 0.3 * duration) & (t < 0.75 * duration)))
        x0 = np.array([0.0, 0.0, 0.0, float(model.U0), 0.0, 0.0])
        out.append(simulate_run(model, t, {"delta": delta, "thrust": thrust}, x0, name=f"zigzag_{i}", noise=noise,
                                seed=100 * seed + i))
    return out, T0


ROV_NOISE = {"x0": 0.1, "y0": 0.1, "z0": 0.02, "phi": 0.3 * DEG, "theta": 0.3 * DEG, "psi": 0.3 * DEG,
             "u": 0.01, "v": 0.01, "w": 0.01, "p": 0.2 * DEG, "q": 0.2 * DEG, "r": 0.2 * DEG}
ROV_AMPLITUDE = (40.0, 40.0, 40.0, 2.0, 2.0, 3.0)


def rov_case_runs(model, n_runs=2, duration=30.0, dt=0.05, noise=ROV_NOISE, seed=0):
    """Independent smoothed random force/moment steps in all six DOF (held 2–4 s)."""
    names = ("tau_x", "tau_y", "tau_z", "tau_k", "tau_m", "tau_n")
    out = []
    for i in range(n_runs):
        rng = np.random.default_rng(1000 * seed + i)
        t = np.arange(0.0, duration + dt / 2, dt)
        inp = {}
        for n, amp in zip(names, ROV_AMPLITUDE):
            k = max(1, int(round(rng.uniform(2.0, 4.0) / dt)))
            sig = np.repeat(rng.uniform(-amp, amp, size=t.size // k + 2), k)[: t.size]
            w = max(1, int(round(0.5 / dt)))
            inp[n] = np.convolve(np.concatenate([np.full(w, sig[0]), sig]), np.ones(w) / w, mode="valid")[1 : t.size + 1]
        out.append(simulate_run(model, t, inp, np.zeros(12), name=f"rov_{i}", noise=noise, seed=7 + 100 * seed + i))
    return out
