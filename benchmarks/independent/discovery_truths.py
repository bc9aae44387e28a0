r"""Independent USV truths with extra hydrodynamic terms, for judging structure discovery (NumPy only).

Nothing here imports diffship: the vessel, its terms, the manoeuvres, the integrator and the noise are
written in this file from the textbook equations. The truth is Fossen's 3-DOF matrix form with force
inputs (body velocities ν = (u, v, r) over ground, η = (x, y, ψ) north-east, ψ clockwise),

.. math::
    \dot\eta = R(\psi)\nu, \qquad
    (M_{RB} + M_A)\dot\nu + C_{RB}(\nu)\nu + C_A(\nu)\nu + D(\nu)\nu = \tau + \Delta\tau(\nu),

with :math:`M_{RB} + M_A = \mathrm{diag}(m - X_{\dot u},\ m - Y_{\dot v},\ I_z - N_{\dot r})`, the
rigid-body and added-mass Coriolis/centripetal forces (CG at the origin, diagonal added mass)

.. math::
    C_{RB}(\nu)\nu = (-m v r,\ m u r,\ 0), \qquad
    C_A(\nu)\nu = (Y_{\dot v} v r,\ -X_{\dot u} u r,\ (X_{\dot u} - Y_{\dot v}) u v),

linear plus quadratic damping
:math:`D(\nu)\nu = -(X_u u + X_{|u|u}|u|u,\ Y_v v + Y_{|v|v}|v|v,\ N_v v + N_r r + N_{|r|r}|r|r)`,
and the extra terms :math:`\Delta\tau_j = \sum_k c_{j,k}\,\phi_k(u, v, r)` — the hydrodynamics a base
fossen3 lacks. A term is named ``EQ_F1[_F2[_F3]]`` (``"X_v_r"``: :math:`X_{vr}\,vr`;
``"N_r_r_r"``: :math:`N_{rrr}\,r^3`; ``"Y_v_ar"``: :math:`Y_{v|r|}\,v|r|`, ``a`` = modulus), the
names under which the discovery library reports them.

Inputs :math:`\tau = (\tau_x, \tau_y, \tau_z)` [N, N, N m] come from open-loop commands: a water
jet's thrust :math:`T` and nozzle angle :math:`\alpha`, :math:`\tau = T(\cos\alpha,\ \sin\alpha,\
-\ell\sin\alpha)` with :math:`\ell = 3.8` m, or a yaw moment from a heading-switched bang–bang
command. The logged inputs are sampled at 10 Hz and the truth sees them linearly interpolated
between samples. The state advances with classical RK4 at 0.01 s (10 steps per sample), each
record starting in the steady straight run of its first command. Sensor noise (white, every sample,
the first included) at the seed-002 USV levels: GNSS position 0.5 m and velocity 0.05 m/s, heading
0.5°, rate gyro 0.2°/s.

:func:`truths` gives five truths with two to four extra terms each — surge :math:`vr` (a term of
its own beside the mass-tied centripetal :math:`(m - Y_{\dot v})vr`), :math:`r^2`, sway
:math:`v^2 r`, :math:`ur`, :math:`v|r|`, yaw :math:`vr^2`, :math:`r^3`, :math:`uv` — and a null
truth without any. Each truth has four training runs (jet commands twice, a heading-switched
zigzag, sums of sines) and two held-out runs (a pull-out: a turn, then the moment released; and a
sway-exciting run of nozzle pulses at higher speed). Coefficient sizes were chosen so that removing
any one term changes the held-out heading by several times the heading noise
(:func:`term_effects` measures it; ``tests/benchmarks`` checks it).

Records have the form of :func:`benchmarks.independent.robust_truths.usv_runs`: ``{"name", "time",
"x0", "y0", "psi", "u", "v", "r", "tau_x", "tau_y", "tau_z", "truth"}`` (SI units, radians).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .integrate import rk4_interval
from .robust_truths import NOISE

__all__ = ["NOISE", "PARAMS", "FREE", "Truth", "truths", "simulate", "term_effects", "MANOEUVRES"]

DEG = math.pi / 180.0
#: The base hydrodynamics (SI units; mass and inertia known to a fit).
PARAMS = dict(m=4935.14, Iz=20928.0, Xudot=-350.0, Yvdot=-700.0, Nrdot=-7000.0, Xu=-65.0, Xuu=-300.0,
              Yv=-280.0, Yvv=-2600.0, Nv=1600.0, Nr=-1900.0, Nrr=-2600.0)
#: The base coefficients a fit estimates.
FREE = ("Xudot", "Yvdot", "Nrdot", "Xu", "Yv", "Nv", "Nr", "Xuu", "Yvv", "Nrr")
#: Training and held-out manoeuvres.
MANOEUVRES = {"train": ("jet_a", "jet_b", "zigzag", "sines"), "held_out": ("pullout", "sway_pulses")}
_ARM = 3.8  # nozzle lever arm [m]


@dataclasses.dataclass(frozen=True)
class Truth:
    """One truth: its extra terms ``{name: coefficient}`` and seed (excitation and noise)."""

    name: str
    terms: dict[str, float]
    seed: int


def truths() -> list[Truth]:
    """The five truths with extra terms and the null truth (module docstring)."""
    return [
        Truth("surge_vr_yaw_r3", {"X_v_r": -3000.0, "N_r_r_r": -8000.0}, 1),
        Truth("sway_v2r_yaw_vr2", {"Y_v_v_r": -8000.0, "N_v_r_r": 12000.0}, 2),
        Truth("surge_vr_sway_v2r_yaw_vr2", {"X_v_r": 6000.0, "Y_v_v_r": -8000.0, "N_v_r_r": 12000.0}, 3),
        Truth("coriolis_monomials", {"X_r_r": -20000.0, "Y_u_r": -400.0, "N_u_v": 150.0}, 4),
        Truth("mixed_four", {"X_v_r": -3000.0, "Y_v_ar": -1500.0, "N_u_v": -120.0, "N_r_r_r": -10000.0}, 5),
        Truth("null", {}, 6),
    ]


def _phi(name: str, u: float, v: float, r: float) -> float:
    vals = {"u": u, "v": v, "r": r, "au": abs(u), "av": abs(v), "ar": abs(r)}
    out = 1.0
    for f in name.split("_")[1:]:
        out *= vals[f]
    return out


def _rhs(p: dict, terms: dict, x: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """:math:`(\\dot x, \\dot y, \\dot\\psi, \\dot u, \\dot v, \\dot r)` (module docstring)."""
    psi, u, v, r = x[2], x[3], x[4], x[5]
    m = p["m"]
    crb = np.array([-m * v * r, m * u * r, 0.0])
    ca = np.array([p["Yvdot"] * v * r, -p["Xudot"] * u * r, (p["Xudot"] - p["Yvdot"]) * u * v])
    d = -np.array([p["Xu"] * u + p["Xuu"] * abs(u) * u, p["Yv"] * v + p["Yvv"] * abs(v) * v,
                   p["Nv"] * v + p["Nr"] * r + p["Nrr"] * abs(r) * r])
    extra = np.zeros(3)
    for name, c in terms.items():
        extra["XYN".index(name[0])] += c * _phi(name, u, v, r)
    mass = np.array([m - p["Xudot"], m - p["Yvdot"], p["Iz"] - p["Nrdot"]])
    nud = (tau + extra - crb - ca - d) / mass
    c, s = math.cos(psi), math.sin(psi)
    return np.array([c * u - s * v, s * u + c * v, r, *nud])


def _rk4(f, x: np.ndarray, tau0: np.ndarray, tau1: np.ndarray, dt: float, substeps: int) -> np.ndarray:
    """One sample interval: ``substeps`` classical RK4 steps (:func:`.integrate.rk4_interval`), the input linear
    from ``tau0`` to ``tau1``."""
    return rk4_interval(lambda t, xx: f(xx, tau0 + (tau1 - tau0) * (t / dt)), 0.0, dt, x, substeps)


def _jet(t: np.ndarray, rng: np.random.Generator, thrust: tuple[float, float], hold: tuple[float, float],
         max_nozzle: float) -> np.ndarray:
    """Water-jet commands: thrust levels held 30 s (2 s ramps), nozzle levels held ``hold`` s alternating
    sides, slewed at 15°/s; τ = T(cos α, sin α, −ℓ sin α)."""
    dt, n = float(t[1] - t[0]), t.size
    T = np.repeat(rng.uniform(*thrust, size=n // int(30.0 / dt) + 2), int(30.0 / dt))[:n]
    w = int(2.0 / dt)
    T = np.convolve(np.concatenate([np.full(w, T[0]), T]), np.ones(w) / w, "valid")[1:n + 1]
    order, k, side = np.zeros(n), int(5.0 / dt), rng.choice([-1.0, 1.0])
    while k < n:
        m = int(rng.uniform(*hold) / dt)
        order[k:k + m] = side * rng.uniform(0.3, 1.0) * max_nozzle
        side, k = -side, k + m
    alpha = np.zeros(n)
    for i in range(1, n):
        alpha[i] = alpha[i - 1] + np.clip(order[i] - alpha[i - 1], -15 * DEG * dt, 15 * DEG * dt)
    return np.stack([T * np.cos(alpha), T * np.sin(alpha), -_ARM * T * np.sin(alpha)], axis=1)


def _commands(kind: str, t: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, tuple | None]:
    """``(tau (n × 3), zigzag)`` of one manoeuvre; ``zigzag = (moment, heading switch)`` or None."""
    n = t.size
    if kind in ("jet_a", "jet_b"):
        return _jet(t, rng, (2500.0, 6500.0), (8.0, 14.0), 8 * DEG), None
    if kind == "sway_pulses":  # faster, short nozzle pulses: large sway velocities against yaw
        return _jet(t, rng, (6000.0, 8000.0), (4.0, 7.0), 9 * DEG), None
    tau = np.zeros((n, 3))
    tau[:, 0] = 4000.0 + 1500.0 * np.sign(np.sin(2 * np.pi * t / 60.0 + rng.uniform(0, 2 * np.pi)))
    if kind == "zigzag":
        return tau, (rng.uniform(1500.0, 2000.0), rng.uniform(15.0, 25.0) * DEG)
    if kind == "sines":
        ph = rng.uniform(0, 2 * np.pi, 3)
        tau[:, 2] = 1500.0 * np.sin(2 * np.pi * t / 28.0 + ph[0]) + 600.0 * np.sin(2 * np.pi * t / 9.0 + ph[1])
        tau[:, 1] = 500.0 * np.sin(2 * np.pi * t / 13.0 + ph[2])
        return tau, None
    if kind == "pullout":  # turn to starboard, release, turn to port, release
        tau[:, 0] = 5000.0
        tau[:, 2] = np.where((t > 10) & (t < 60), 2000.0, 0.0) - np.where((t > 130) & (t < 180), 2000.0, 0.0)
        return tau, None
    raise ValueError(f"unknown manoeuvre {kind!r}")


def simulate(kind: str, terms: dict[str, float], seed: int, duration: float = 240.0, dt: float = 0.1,
             substeps: int = 10, params: dict | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(time, clean states (n × 6) = (x, y, ψ, u, v, r), tau (n × 3))`` of one manoeuvre (the
    excitation drawn from ``seed``; the same seed gives the same commands whatever the terms, so runs
    with and without a term differ only by its force)."""
    p = {**PARAMS, **(params or {})}
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration + 0.5 * dt, dt)
    tau, zig = _commands(kind, t, rng)
    f = lambda x, ta: _rhs(p, terms, x, ta)  # noqa: E731
    # steady straight run of the first command: surge balance -(Xu + Xuu u) u = tau_x, by pre-roll
    x = np.array([0.0, 0.0, 0.0, 3.0, 0.0, 0.0])
    for _ in range(600):
        x = _rk4(f, x, tau[0], tau[0], 0.1, 2)
    x[:3] = 0.0
    xs = np.zeros((t.size, 6))
    sign = 1.0
    for k in range(t.size):
        xs[k] = x
        if k + 1 == t.size:
            break
        if zig is not None:  # the moment at t_{k+1} decided from the heading at t_k (one sample of delay)
            amp, sw = zig
            sign = -1.0 if (sign > 0 and x[2] > sw) else (1.0 if (sign < 0 and x[2] < -sw) else sign)
            tau[k + 1, 2] = sign * amp if t[k + 1] >= 5.0 else 0.0
        x = _rk4(f, x, tau[k], tau[k + 1], dt, substeps)
        if not np.all(np.isfinite(x)):
            raise RuntimeError(f"the truth simulation of {kind} blew up")
    return t, xs, tau


def _record(name: str, t, xs, tau, rng: np.random.Generator, truth: dict) -> dict:
    chans = ("x0", "y0", "psi", "u", "v", "r")
    return {"name": name, "time": t,
            **{c: xs[:, i] + NOISE[c] * rng.standard_normal(t.size) for i, c in enumerate(chans)},
            **{c: tau[:, i].copy() for i, c in enumerate(("tau_x", "tau_y", "tau_z"))}, "truth": truth}


def runs(truth: Truth, duration: float = 240.0, dt: float = 0.1) -> dict[str, list[dict]]:
    """``{"train": [4 records], "held_out": [2 records]}`` of one truth (module docstring)."""
    out: dict[str, list[dict]] = {}
    info = {**PARAMS, "terms": dict(truth.terms)}
    for part, kinds in MANOEUVRES.items():
        out[part] = []
        for i, kind in enumerate(kinds):
            s = 100 * truth.seed + i + (10 if part == "held_out" else 0)
            t, xs, tau = simulate(kind, truth.terms, s, duration, dt)
            out[part].append(_record(f"{kind}_{truth.name}", t, xs, tau, np.random.default_rng(50_000 + s), info))
    return out


def term_effects(truth: Truth, duration: float = 240.0, dt: float = 0.1) -> dict[str, dict[str, float]]:
    """``{term: {held-out manoeuvre: RMS heading change [rad]}}`` when that one term is removed from the
    truth (noise-free): how visible each term is on the held-out runs, to compare with ``NOISE["psi"]``."""
    out: dict[str, dict[str, float]] = {}
    for name in truth.terms:
        rest = {k: c for k, c in truth.terms.items() if k != name}
        out[name] = {}
        for i, kind in enumerate(MANOEUVRES["held_out"]):
            s = 100 * truth.seed + i + 10
            a = simulate(kind, truth.terms, s, duration, dt)[1][:, 2]
            b = simulate(kind, rest, s, duration, dt)[1][:, 2]
            out[name][kind] = float(np.sqrt(np.mean((a - b) ** 2)))
    return out
