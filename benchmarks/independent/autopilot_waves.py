r"""Independent truths at sea: a ship steered by an autopilot in a narrow-band wave yaw disturbance (NumPy only).

Nothing here imports diffship. The ship's yaw obeys first-order Nomoto dynamics with an additive wave-induced
yaw acceleration :math:`d(t)`,

.. math::
    \dot\psi = r, \qquad \dot r = \frac{K(\delta + \delta_0) - r}{T} + d(t),

and :math:`d` is a narrow-band process: a second-order resonator driven by white noise,

.. math::
    \ddot d + 2\zeta_w\omega_w\dot d + \omega_w^2 d = \sqrt{4\zeta_w\omega_w^3}\,\sigma_d\,\xi(t),

whose stationary standard deviation is :math:`\sigma_d` [rad/s²] and whose spectrum peaks at the wave
encounter period :math:`2\pi/\omega_w`. Every run starts the resonator from its stationary distribution, so the
wave's phase is random per run. The noise is integrated by Euler–Maruyama on a fine grid (``substeps`` per
sample), the ship by RK4 on the same grid.

The rudder order is a digital PD autopilot on the **measured** heading and yaw rate (closed loop: the rudder
reacts to the wave-induced yaw), :math:`\delta_c = \mathrm{sat}_{35°}(-K_p(\psi_m - \psi_{ref}) - K_d r_m)`, held
between samples, with course changes of ±10–20° every 100–200 s so that the steering excites the yaw; the steering
gear moves the rudder towards the order at up to 5°/s, and the logged rudder is the gear's output. Sensor noise:
heading 0.2°, yaw rate 0.05°/s, rudder 0.1° (white, every sample). ``waves=False`` gives the same runs in calm
water (:math:`\sigma_d = 0`); ``open_loop=True`` replays a pre-drawn rudder sequence (no feedback).

Each run is ``{"name", "time", "channels": {"psi", "r", "delta"}, "clean": {...}, "truth": {...}}``, SI units,
radians, heading clockwise, starboard-positive rudder.
"""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ["WaveShip", "autopilot_runs", "NOISE"]

DEG = np.pi / 180.0

#: Sensor noise (one standard deviation, white per sample).
NOISE = {"psi": 0.2 * DEG, "r": 0.05 * DEG, "delta": 0.1 * DEG}


@dataclasses.dataclass(frozen=True)
class WaveShip:
    """Nomoto ship, wave and autopilot of the module docstring."""

    K: float = 0.08          # 1/s
    T: float = 20.0          # s
    delta0: float = 0.5 * DEG
    wave_period: float = 8.0  # s (encounter)
    wave_damping: float = 0.08
    wave_sd: float = 0.004   # rad/s², stationary sd of the wave yaw acceleration
    Kp: float = 1.0          # rad rudder per rad heading error
    Kd: float = 10.0         # rad rudder per rad/s yaw rate
    max_rudder: float = 35.0 * DEG
    rudder_rate: float = 5.0 * DEG  # rad/s, steering gear

    def params(self) -> dict[str, float]:
        return {"K": self.K, "T1": self.T, "delta0": self.delta0, "wave_period": self.wave_period,
                "wave_damping": self.wave_damping, "wave_sd": self.wave_sd}


def _rhs(ship: WaveShip, x: np.ndarray, order: float) -> np.ndarray:
    """Deterministic part of (ψ, r, d, ḋ, δ): the gear drives δ to the order at its rate limit (smoothed over
    0.05° so that RK4 sees a Lipschitz right-hand side)."""
    w = 2.0 * np.pi / ship.wave_period
    psi, r, d, dd, delta = x
    return np.array([r, (ship.K * (delta + ship.delta0) - r) / ship.T + d, dd,
                     -2.0 * ship.wave_damping * w * dd - w * w * d,
                     ship.rudder_rate * np.tanh((order - delta) / (0.05 * DEG))])


def _run(ship: WaveShip, rng: np.random.Generator, duration: float, dt: float, substeps: int, waves: bool,
         open_loop: np.ndarray | None) -> dict:
    n = int(round(duration / dt)) + 1
    t = np.arange(n) * dt
    w = 2.0 * np.pi / ship.wave_period
    sd = ship.wave_sd if waves else 0.0
    # the resonator from its stationary distribution: d ~ N(0, σ²), ḋ ~ N(0, ω²σ²) (random phase)
    x = np.array([rng.uniform(-np.pi, np.pi), 0.0, sd * rng.standard_normal(), w * sd * rng.standard_normal(),
                  -ship.delta0])
    ref = x[0]
    next_change = rng.uniform(60.0, 120.0)
    noise = {c: s * rng.standard_normal(n) for c, s in NOISE.items()}
    X = np.zeros((n, 5))
    h = dt / substeps
    gain = np.sqrt(4.0 * ship.wave_damping * w ** 3) * sd
    for k in range(n):
        X[k] = x
        if open_loop is not None:
            order = float(open_loop[k])
        else:
            if t[k] >= next_change:
                ref += rng.choice([-1.0, 1.0]) * rng.uniform(10.0, 20.0) * DEG
                next_change += rng.uniform(100.0, 200.0)
            err = np.angle(np.exp(1j * (x[0] + noise["psi"][k] - ref)))
            order = float(np.clip(-ship.Kp * err - ship.Kd * (x[1] + noise["r"][k]) - ship.delta0,
                                  -ship.max_rudder, ship.max_rudder))
        if k == n - 1:
            break
        for _ in range(substeps):  # RK4 on the drift, Euler–Maruyama on the resonator's white-noise forcing
            k1 = _rhs(ship, x, order)
            k2 = _rhs(ship, x + 0.5 * h * k1, order)
            k3 = _rhs(ship, x + 0.5 * h * k2, order)
            k4 = _rhs(ship, x + h * k3, order)
            x = x + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)
            x[3] += gain * np.sqrt(h) * rng.standard_normal()
    clean = {"psi": X[:, 0], "r": X[:, 1], "delta": X[:, 4]}
    chans = {c: clean[c] + noise[c] for c in ("psi", "r", "delta")}
    return {"time": t, "channels": chans, "clean": {**clean, "wave": X[:, 2]}}


def autopilot_runs(seed: int = 0, n_runs: int = 3, duration: float = 600.0, dt: float = 0.5, substeps: int = 10,
                   waves: bool = True, open_loop: bool = False, ship: WaveShip | None = None) -> list[dict]:
    """``n_runs`` autopilot runs of ``duration`` s logged every ``dt`` s (module docstring). With ``open_loop`` the
    rudder is a pre-drawn sequence of holds (±5–15°, 20–60 s each) instead of the autopilot's."""
    ship = ship or WaveShip()
    rng = np.random.default_rng(9100 + seed)
    out = []
    for i in range(n_runs):
        seq = None
        if open_loop:
            n = int(round(duration / dt)) + 1
            seq, k = np.zeros(n), 0
            while k < n:
                m = int(rng.uniform(20.0, 60.0) / dt)
                seq[k:k + m] = rng.choice([-1.0, 1.0]) * rng.uniform(5.0, 15.0) * DEG - ship.delta0
                k += m
        rec = _run(ship, rng, duration, dt, substeps, waves, seq)
        kind = ("waves" if waves else "calm") + ("_open" if open_loop else "_autopilot")
        out.append({"name": f"{kind}_{i}_s{seed}", **rec, "truth": ship.params()})
    return out
