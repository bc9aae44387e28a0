"""Synthetic BlueROV2-like excitation runs for the 6-DOF tests (test helper)."""

import numpy as np

from diffship.synthetic import simulate_run

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


def rov_runs(model, n_runs=2, duration=60.0, dt=0.05, noise=ROV_NOISE, seed=0):
    out = []
    for i in range(n_runs):
        t, inp = rov_excitation(duration, dt, seed=1000 * seed + i)
        out.append(simulate_run(model, t, inp, np.zeros(12), name=f"rov_{i}", noise=noise, seed=7 + 100 * seed + i))
    return out
