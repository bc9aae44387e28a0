r"""Independent noisy truths for the robustness matrix and the coverage checks (NumPy only).

Nothing here imports diffship (``tests/diagnose/test_independent_generator.py`` checks every file of
this package): the truths are written from the textbooks with their own state realisations and the
package's own fixed-step RK4 (:mod:`.integrate`), and the noise is added to **every** sample, the first
one included (a fit that takes the first sample as the exact initial state is biased by it).

* :func:`nomoto2_runs` — a ship whose yaw obeys the second-order Nomoto transfer function
  :math:`r/\delta = K(1+T_3 s)/((1+T_1 s)(1+T_2 s))` with a rudder offset, realised in controllable
  canonical form (states ψ, q, q̇; :math:`T_1T_2\ddot q + (T_1+T_2)\dot q + q = \delta + \delta_0`,
  :math:`r = K(q + T_3\dot q)`), steered through zigzags by a helmsman reading the noisy compass, the
  rudder rate-limited by its steering gear (closed loop);
* :func:`nomoto1_runs` — the same ship with :math:`T_2 = T_3 = 0` (first order, :class:`.vessels.Ship`
  dynamics) — the same helmsman;
* :func:`usv_runs` — the 3-DOF water-jet USV of :class:`.vessels.USV` (Fossen's matrix form) driven by
  open-loop jet commands (:func:`.vessels.usv_commands`), started at rest in a steady run at 2 m/s;
* noise at the levels of the seed-002 USV sensors (:data:`NOISE`): GNSS position 0.5 m and velocity
  0.05 m/s, heading 0.5°, rate gyro 0.2°/s, white and independent per sample.

Each function returns a list of plain dicts ``{"name", "time", channels...}`` in SI units and radians
(NED, heading clockwise, starboard-positive rudder), with the truth's parameters in ``"truth"``.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .integrate import rk4_interval
from .vessels import USV, simulate, usv_commands

__all__ = ["NOISE", "NomotoShip", "nomoto1_runs", "nomoto2_runs", "usv_runs", "USV_FREE"]

DEG = np.pi / 180.0

#: One standard deviation of white sensor noise per channel (seed-002 USV sensors).
NOISE = {"x0": 0.5, "y0": 0.5, "psi": 0.5 * DEG, "u": 0.05, "v": 0.05, "r": 0.2 * DEG}

#: The USV's hydrodynamic coefficients a fit estimates (mass and inertia are known).
USV_FREE = ("Xudot", "Yvdot", "Nrdot", "Xu", "Yv", "Nv", "Nr", "Xuu", "Yvv", "Nrr")


@dataclasses.dataclass(frozen=True)
class NomotoShip:
    """Second-order Nomoto yaw dynamics with a rudder offset (module docstring); ``T2 = T3 = 0``: first order."""

    K: float = 0.12
    T1: float = 14.0
    T2: float = 1.6
    T3: float = 3.0
    delta0: float = 0.4 * DEG

    def rhs(self, x: np.ndarray, delta: float) -> np.ndarray:
        psi, q, qd = x
        d = delta + self.delta0
        if self.T2 == 0.0:  # first order: q is the yaw rate over K, qd unused
            return np.array([self.K * q, (d - q) / self.T1, 0.0])
        qdd = (d - q - (self.T1 + self.T2) * qd) / (self.T1 * self.T2)
        return np.array([self.K * (q + self.T3 * qd), qd, qdd])

    def yaw_rate(self, x: np.ndarray) -> float:
        return self.K * (x[1] + (self.T3 * x[2] if self.T2 else 0.0))

    def params(self) -> dict[str, float]:
        out = {"K": self.K, "T1": self.T1, "delta0": self.delta0}
        return out if self.T2 == 0.0 else {**out, "T2": self.T2, "T3": self.T3}


def _zigzag(ship: NomotoShip, amp: float, switch: float, side: int, duration: float, dt: float,
            rng: np.random.Generator, rate: float = 5.0 * DEG, t_exec: float = 5.0, substeps: int = 8) -> dict:
    """A zigzag flown by a helmsman reading the noisy compass (closed loop): rudder ``side·amp`` at
    ``t_exec``, reversed when the measured heading passes ``±switch`` from the initial one; the logged
    rudder is the steering gear's output (rate ``rate``), held linearly between samples."""
    t = np.arange(0.0, duration + 0.5 * dt, dt)
    n = t.size
    x = np.array([rng.uniform(-np.pi, np.pi), 0.0, 0.0])
    # the record starts on a steady course: rudder at zero, the offset's steady yaw rate
    x[1] = ship.delta0 if ship.T2 == 0.0 else ship.delta0
    psi_noise = NOISE["psi"] * rng.standard_normal(n)
    X, D = np.zeros((n, 3)), np.zeros(n)
    X[0] = x
    order, ref = 0.0, None
    for k in range(n - 1):
        psi_m = x[0] + psi_noise[k]
        ref = psi_m if ref is None else ref
        if t[k] >= t_exec and order == 0.0:
            order = side * amp
        dpsi = psi_m - ref
        if order > 0 and dpsi >= switch:
            order = -amp
        elif order < 0 and dpsi <= -switch:
            order = amp
        step = rate * dt
        D[k + 1] = D[k] + np.clip(order - D[k], -step, step)
        d0, d1 = D[k], D[k + 1]
        x = rk4_interval(lambda tt, xx: ship.rhs(xx, d0 + (d1 - d0) * (tt - t[k]) / dt), t[k], t[k + 1], x, substeps)
        X[k + 1] = x
    r = np.array([ship.yaw_rate(xx) for xx in X])
    return {"time": t, "psi": X[:, 0] + psi_noise, "r": r + NOISE["r"] * rng.standard_normal(n), "delta": D,
            "clean_psi": X[:, 0], "clean_r": r}


def nomoto2_runs(seed: int = 0, duration: float = 120.0, dt: float = 0.1, ship: NomotoShip | None = None) -> list[dict]:
    """Two closed-loop zigzags (10°/10° to starboard, 20°/20° to port) of the second-order truth."""
    ship = ship or NomotoShip()
    rng = np.random.default_rng(7000 + seed)
    out = []
    for name, amp, sw, side in (("zigzag_10_10", 10.0, 10.0, 1), ("zigzag_20_20", 20.0, 20.0, -1)):
        rec = _zigzag(ship, amp * DEG, sw * DEG, side, duration, dt, rng)
        out.append({"name": f"{name}_s{seed}", **rec, "truth": ship.params()})
    return out


def nomoto1_runs(seed: int = 0, duration: float = 120.0, dt: float = 0.1) -> list[dict]:
    """:func:`nomoto2_runs` of the first-order truth (K 0.12 1/s, T 14 s, δ0 0.4°)."""
    return nomoto2_runs(seed, duration, dt, NomotoShip(T2=0.0, T3=0.0))


def usv_runs(seed: int = 0, n_runs: int = 2, duration: float = 300.0, dt: float = 0.1, truth: USV | None = None,
             substeps: int = 4) -> list[dict]:
    """``n_runs`` open-loop jet-command runs of the USV truth with sensor noise on every sample."""
    truth = truth or USV()
    out = []
    for i in range(n_runs):
        rng = np.random.default_rng(1000 * seed + i)
        t = np.arange(0.0, duration + 0.5 * dt, dt)
        cmd = usv_commands(t, rng)
        sim = simulate(truth, [], t, commands=cmd, u0=2.0, substeps=substeps)
        rec = {"name": f"usv_{i}_s{seed}", "time": t,
               **{c: sim["clean"][c] + NOISE[c] * rng.standard_normal(t.size) for c in truth.outputs},
               **{k: cmd[:, j] for j, k in enumerate(truth.inputs)},
               "truth": {k: float(getattr(truth, k)) for k in (*USV_FREE, "m", "Iz")}}
        out.append(rec)
    return out
