"""Synthetic BlueROV2-like excitation runs for the 6-DOF tests (test helper)."""

import jax
import jax.numpy as jnp
import numpy as np

from diffship.data import Run
from diffship.integrators import RK4
from diffship.simulate import simulate

#: ROV sensor noise (1σ): USBL position 0.1 m, depth 0.02 m, attitude 0.3°, DVL 0.01 m/s, gyro 0.2°/s.
ROV_NOISE = {"x0": 0.1, "y0": 0.1, "z0": 0.02, "phi": 0.3 * np.pi / 180, "theta": 0.3 * np.pi / 180,
             "psi": 0.3 * np.pi / 180, "u": 0.01, "v": 0.01, "w": 0.01,
             "p": 0.2 * np.pi / 180, "q": 0.2 * np.pi / 180, "r": 0.2 * np.pi / 180}
AMPLITUDE = (40.0, 40.0, 40.0, 2.0, 2.0, 3.0)  # N, N, N, N m, N m, N m


def _levels(rng, t, hold, amp):
    k = max(1, int(round(hold / (t[1] - t[0]))))
    vals = rng.uniform(-amp, amp, size=t.size // k + 2)
    sig = np.repeat(vals, k)[: t.size]
    w = max(1, int(round(0.5 / (t[1] - t[0]))))
    return np.convolve(np.concatenate([np.full(w, sig[0]), sig]), np.ones(w) / w, mode="valid")[1 : t.size + 1]


def rov_excitation(duration=60.0, dt=0.05, seed=0):
    """Independent smoothed random force/moment steps in all six DOF (held 2–4 s)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration + dt / 2, dt)
    names = ("tau_x", "tau_y", "tau_z", "tau_k", "tau_m", "tau_n")
    return t, {n: _levels(rng, t, rng.uniform(2.0, 4.0), a) for n, a in zip(names, AMPLITUDE)}


_SIM = jax.jit(jax.vmap(lambda m, t, u, x: simulate(m, t, u, x, RK4(substeps=2)), in_axes=(None, None, 0, 0)))


def rov_runs(model, n_runs=2, duration=60.0, dt=0.05, noise=ROV_NOISE, seed=0):
    """Runs of ``model`` from rest under :func:`rov_excitation`, all simulated in one compiled call."""
    excs = [rov_excitation(duration, dt, seed=1000 * seed + i) for i in range(n_runs)]
    t = excs[0][0]
    us = np.stack([np.stack([e[1][n] for n in model.input_names], 1) for e in excs])
    sol = _SIM(model, jnp.asarray(t), jnp.asarray(us), jnp.zeros((n_runs, 12)))
    assert bool(np.all(np.asarray(sol.valid))), "reference ROV simulation blew up"
    noise = {} if noise == "none" else noise
    out = []
    for i in range(n_runs):
        rng = np.random.default_rng(7 + 100 * seed + i)
        ch = {c: np.asarray(sol.ys[i])[:, j] + (rng.normal(0.0, noise[c], t.size) if c in noise else 0.0)
              for j, c in enumerate(model.output_names)}
        ch.update({n: us[i][:, k] for k, n in enumerate(model.input_names)})
        out.append(Run(f"rov_{i}", t, ch, {"source": "tests/_rov_data", "truth": model.param_values()}))
    return out
