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

__all__ = ["WaveShip", "autopilot_runs", "NOISE", "WaveUSV", "usv_autopilot_runs", "USV_NOISE"]

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


@dataclasses.dataclass(frozen=True)
class WaveUSV:
    """The 3-DOF water-jet USV of :class:`.vessels.USV` under a PD heading autopilot on its yaw moment, in a wave
    of narrow-band sway and yaw accelerations (independent resonators of one period and damping)."""

    wave_period: float = 6.0
    wave_damping: float = 0.08
    wave_sd_v: float = 0.03   # m/s², stationary sd of the sway acceleration
    wave_sd_r: float = 0.01   # rad/s², of the yaw acceleration
    Kp: float = 2800.0        # N m per rad of heading error
    Kd: float = 10000.0       # N m per rad/s of yaw rate
    max_moment: float = 1500.0  # N m
    moment_rate: float = 1000.0  # N m/s, the jets' slew
    thrust: float = 1330.0    # N (2 m/s steady)


#: Sensor noise of the USV runs (GNSS position and velocity, compass, rate gyro).
USV_NOISE = {"x0": 0.5, "y0": 0.5, "psi": 0.2 * DEG, "u": 0.05, "v": 0.05, "r": 0.1 * DEG}


def usv_autopilot_runs(seed: int = 0, n_runs: int = 4, duration: float = 300.0, dt: float = 0.2, substeps: int = 4,
                       waves: bool = True, cfg: WaveUSV | None = None) -> list[dict]:
    """``n_runs`` autopilot runs of the USV (course changes of ±20–30° every 60–120 s) logged every ``dt`` s, with
    ``USV_NOISE`` on every sample; channels x0, y0, psi, u, v, r and the inputs tau_x, tau_y, tau_z."""
    from .vessels import USV

    cfg, usv = cfg or WaveUSV(), USV()
    rng = np.random.default_rng(9300 + seed)
    w = 2.0 * np.pi / cfg.wave_period
    sds = np.array([cfg.wave_sd_v, cfg.wave_sd_r]) if waves else np.zeros(2)
    gain = np.sqrt(4.0 * cfg.wave_damping * w ** 3) * sds
    no_force = lambda t, psi, nu: np.zeros(3)  # noqa: E731
    still = lambda t: (np.zeros(2), np.zeros(2))  # noqa: E731
    out = []
    for i in range(n_runs):
        n = int(round(duration / dt)) + 1
        t = np.arange(n) * dt
        x = np.array([0.0, 0.0, rng.uniform(-np.pi, np.pi), 2.0, 0.0, 0.0])
        d = np.concatenate([sds * rng.standard_normal(2), w * sds * rng.standard_normal(2)])  # (d_v, d_r, ḋ_v, ḋ_r)
        ref, nxt, tz = x[2], rng.uniform(30.0, 60.0), 0.0
        noise = {c: s * rng.standard_normal(n) for c, s in USV_NOISE.items()}
        X, TZ = np.zeros((n, 6)), np.zeros(n)
        h = dt / substeps
        for k in range(n):
            X[k], TZ[k] = x, tz
            if k == n - 1:
                break
            if t[k] >= nxt:
                ref += rng.choice([-1.0, 1.0]) * rng.uniform(20.0, 30.0) * DEG
                nxt += rng.uniform(60.0, 120.0)
            err = np.angle(np.exp(1j * (x[2] + noise["psi"][k] - ref)))
            order = float(np.clip(-cfg.Kp * err - cfg.Kd * (x[5] + noise["r"][k]), -cfg.max_moment, cfg.max_moment))
            tz1 = tz + float(np.clip(order - tz, -cfg.moment_rate * dt, cfg.moment_rate * dt))

            def f(s, xx, dd):
                tau = np.array([cfg.thrust, 0.0, tz + (tz1 - tz) * s / dt])
                rate = usv.rhs(t[k] + s, xx, tau, no_force, still)
                rate[4:6] += dd[:2]
                return rate, np.concatenate([dd[2:], -2.0 * cfg.wave_damping * w * dd[2:] - w * w * dd[:2]])
            s = 0.0
            for _ in range(substeps):  # RK4 on the ship and the resonators, Euler–Maruyama on the white forcing
                k1 = f(s, x, d)
                k2 = f(s + h / 2, x + h / 2 * k1[0], d + h / 2 * k1[1])
                k3 = f(s + h / 2, x + h / 2 * k2[0], d + h / 2 * k2[1])
                k4 = f(s + h, x + h * k3[0], d + h * k3[1])
                x = x + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
                d = d + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
                d[2:] += gain * np.sqrt(h) * rng.standard_normal(2)
                s += h
            tz = tz1
        names = ("x0", "y0", "psi", "u", "v", "r")
        chans = {c: X[:, j] + noise[c] for j, c in enumerate(names)}
        chans.update(tau_x=np.full(n, cfg.thrust), tau_y=np.zeros(n), tau_z=TZ)
        out.append({"name": f"usv_{'waves' if waves else 'calm'}_autopilot_{i}_s{seed}", "time": t, "channels": chans,
                    "clean": {c: X[:, j] for j, c in enumerate(names)},
                    "truth": {**{k: float(getattr(usv, k)) for k in ("m", "Iz", "Xudot", "Yvdot", "Nrdot", "Xu", "Yv",
                                                                     "Nv", "Nr", "Xuu", "Yvv", "Nrr")},
                              "wave_period": cfg.wave_period, "wave_sd_v": cfg.wave_sd_v, "wave_sd_r": cfg.wave_sd_r}})
    return out
