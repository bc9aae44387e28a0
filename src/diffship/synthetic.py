"""Synthetic runs from diffship's own reference models, with realistic sensor noise.

Used by the tests, the benchmarks and the bundled fossen3 example: data whose truth is known.

Noise levels (``NOISE["realistic"]``, one standard deviation, white):
GNSS position 0.5 m, GNSS velocity 0.05 m/s, heading 0.5°, rate gyro 0.2°/s.
"""

from __future__ import annotations

from collections.abc import Mapping

import jax.numpy as jnp
import numpy as np

from .data import Run
from .integrators import RK4
from .models import AbstractModel, Fossen3, Nomoto1, usv_standard
from .simulate import simulate

__all__ = ["NOISE", "simulate_run", "USV_TRUTH", "usv_truth", "usv_excitation", "usv_runs", "rudder_sequence", "nomoto_runs"]

_DEG = np.pi / 180.0

NOISE: dict[str, dict[str, float]] = {
    "none": {},
    "realistic": {"x0": 0.5, "y0": 0.5, "psi": 0.5 * _DEG, "u": 0.05, "v": 0.05, "r": 0.2 * _DEG},
}
NOISE["high"] = {k: 3 * v for k, v in NOISE["realistic"].items()}


def simulate_run(
    model: AbstractModel,
    time: np.ndarray,
    inputs: Mapping[str, np.ndarray],
    x0: np.ndarray,
    *,
    name: str = "synthetic",
    noise: Mapping[str, float] | str = "none",
    seed: int = 0,
    substeps: int = 2,
) -> Run:
    """Simulate ``model`` and return a :class:`Run` of its outputs (plus noise) and inputs."""
    noise = NOISE[noise] if isinstance(noise, str) else dict(noise)
    us = np.stack([np.asarray(inputs[n], dtype=np.float64) for n in model.input_names], axis=1)
    # the hand-written RK4 with sub-steps: not the integrator the fits use (diffrax, one step per sample)
    sol = simulate(model, jnp.asarray(time), jnp.asarray(us), jnp.asarray(x0), RK4(substeps))
    if not bool(sol.ok):
        raise RuntimeError(f"synthetic run {name}: the reference simulation blew up")
    ys = np.asarray(sol.ys)
    rng = np.random.default_rng(seed)
    channels = {}
    for j, c in enumerate(model.output_names):
        y = ys[:, j]
        if noise.get(c):
            y = y + rng.normal(0.0, noise[c], size=y.shape)
        channels[c] = y
    for n in model.input_names:
        channels[n] = np.asarray(inputs[n], dtype=np.float64)
    return Run(name, np.asarray(time, dtype=np.float64), channels,
               {"source": "diffship.synthetic", "truth": model.param_values(), "noise": noise, "seed": seed})


#: The test USV (:func:`usv_truth`): the seed-002 hull and mass (:data:`~diffship.models.USV_STANDARD`)
#: with its own added masses and damping, every free parameter 30–50 % (or, for the added
#: masses, entirely) away from the :class:`~diffship.models.Fossen3` defaults, so that a fit
#: started "from the defaults" does not start at the answer.
USV_TRUTH: dict[str, float] = dict(
    Xudot=-400.0, Yvdot=-600.0, Nrdot=-8000.0,  # defaults: 0
    Xu=-70.0, Yv=-300.0, Nv=1700.0, Nr=-1800.0,  # defaults: -50, -200, 1281, -1281 (+40, +50, +33, +41 %)
    Xuu=-320.0, Yvv=-2800.0, Nrr=-2400.0,  # defaults: -243, -2000, -3594.38 (+32, +40, -33 %)
)


def usv_truth() -> Fossen3:
    """Test truth: the seed-002 USV with the added masses and damping of :data:`USV_TRUTH`.

    The sway added mass is kept small (600 kg, 12 % of m): the Munk moment ``(Xudot − Yvdot)uv``
    grows with it and can make the model directionally unstable at speed (a positive real
    eigenvalue of the sway–yaw dynamics), which no open-loop output-error fit over minutes of
    data can follow; the yaw–sway coupling ``Nv`` is raised for the same reason. With these
    values all eigenvalues have negative real parts (≤ −0.05 1/s) for 0.5–7 m/s; the top
    speed at the largest excitation thrust (6 kN) is about 4.2 m/s.
    """
    return usv_standard(**USV_TRUTH)


def _levels(rng, n, dt, hold, lo, hi):
    """Piecewise-constant random levels held for ``hold`` seconds, smoothed by a 2 s ramp."""
    k = max(1, int(round(hold / dt)))
    vals = rng.uniform(lo, hi, size=n // k + 2)
    sig = np.repeat(vals, k)[:n]
    w = max(1, int(round(2.0 / dt)))
    return np.convolve(np.concatenate([np.full(w, sig[0]), sig]), np.ones(w) / w, mode="valid")[1 : n + 1]


def usv_excitation(duration: float = 300.0, dt: float = 0.1, seed: int = 0) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Times and jet-like force inputs: surge steps, nozzle zigzags (τ_z = −3.82 τ_y)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration + 0.5 * dt, dt)
    n = t.size
    thrust = _levels(rng, n, dt, 40.0, 1500.0, 6000.0)
    nozzle = _levels(rng, n, dt, 12.0, -20 * _DEG, 20 * _DEG)
    tau_x = thrust * np.cos(nozzle)
    tau_y = thrust * np.sin(nozzle)
    return t, {"tau_x": tau_x, "tau_y": tau_y, "tau_z": -3.82 * tau_y}


def usv_runs(
    n_runs: int = 3, duration: float = 300.0, dt: float = 0.1, noise: str | Mapping[str, float] = "realistic",
    seed: int = 0, model: Fossen3 | None = None,
) -> list[Run]:
    """``n_runs`` excitation runs of the USV truth (or ``model``), starting at 2 m/s."""
    model = model or usv_truth()
    runs = []
    for i in range(n_runs):
        t, inp = usv_excitation(duration, dt, seed=1000 * seed + i)
        x0 = np.array([0.0, 0.0, 0.0, 2.0, 0.0, 0.0])
        runs.append(simulate_run(model, t, inp, x0, name=f"usv_{i}", noise=noise, seed=10_000 + 100 * seed + i))
    return runs


def rudder_sequence(t: np.ndarray, amplitude: float, period: float, rate: float = 5 * _DEG, start: float = 1.0) -> np.ndarray:
    """Open-loop alternating rudder (zigzag-like) with a rate limit [rad/s]."""
    target = np.where(t < start, 0.0, amplitude * np.sign(np.sin(np.pi * (t - start) / (period / 2) + 1e-9)))
    out = np.zeros_like(t)
    for k in range(1, t.size):
        step = rate * (t[k] - t[k - 1])
        out[k] = out[k - 1] + np.clip(target[k] - out[k - 1], -step, step)
    return out


def nomoto_runs(model: AbstractModel | None = None, n_runs: int = 2, duration: float = 60.0, dt: float = 0.1,
                noise: str | Mapping[str, float] = "realistic", seed: int = 0) -> list[Run]:
    """Zigzag-like rudder runs of a Nomoto model (amplitudes 10°/20°, periods 20 s/30 s)."""
    model = model or Nomoto1(K=0.2, T1=8.0, delta0=0.01)
    runs = []
    for i in range(n_runs):
        t = np.arange(0.0, duration + 0.5 * dt, dt)
        amp, period = (10 * _DEG, 20.0) if i % 2 == 0 else (-20 * _DEG, 30.0)
        delta = rudder_sequence(t, amp, period)
        x0 = np.zeros(len(model.state_names))
        runs.append(simulate_run(model, t, {"delta": delta}, x0, name=f"zigzag_{i}", noise=noise, seed=100 * seed + i))
    return runs
