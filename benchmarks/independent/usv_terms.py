r"""A 3-DOF USV truth with extra hydrodynamic terms, for judging ``diffship.discover``.

Written apart from diffship (NumPy only, its own RK4): Fossen's matrix form with force inputs,

.. math::
    M\dot\nu + C(\nu)\nu + D(\nu)\nu = \tau + \Delta\tau(\nu), \qquad
    \dot\eta = R(\psi)\nu,

:math:`M = \mathrm{diag}(m - X_{\dot u}, m - Y_{\dot v}, I_z - N_{\dot r})`,
:math:`C(\nu)\nu = (-(m - Y_{\dot v}) v r,\ (m - X_{\dot u}) u r,\ (X_{\dot u} - Y_{\dot v}) u v)`,
:math:`D(\nu)\nu = -(X_u u + X_{|u|u}|u|u,\ Y_v v + Y_{|v|v}|v|v,\ N_v v + N_r r + N_{|r|r}|r|r)` — the
seed-002 USV standard model with added masses — and :math:`\Delta\tau` a sum of extra terms
:math:`c\,\phi(u, v, r)` given as ``{"N_v_ar": -3000.0, ...}`` (equation, then factors ``u, v, r`` or
``au, av, ar`` for moduli; the names diffship's term library uses, so a result can be compared by name).

Manoeuvres (open loop, force and moment inputs): steps, sines, chirp, zigzag (a bang–bang yaw moment
switching on heading), pull-out (a turn, then the moment released) and a fast run with sway-force
pulses.

**Inputs between samples.** A log holds the input's samples only; what it did between them is a
convention of the data. By default (``hold="linear"``) the truth is driven by the piecewise-linear
input through the logged samples (first-order hold), the convention under which a log of a
continuous force is read. ``hold="zero"`` holds each sample until the next (a digital command);
read back under the linear convention such a log leads the true input by half a sample, which at
10 Hz and these time constants leaves a heading error of about the heading noise (0.5°) in a model
with exactly the true structure and parameters — a structural error that a discovery method would
then, rightly, try to explain with extra terms. Measurements carry white noise at the levels of real logs (GNSS 0.5 m, 0.05 m/s; heading 0.5°;
gyro 0.2°/s).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["TRUTH", "EXTRA", "NOISE", "manoeuvre", "simulate", "run_table"]

TRUTH = dict(m=4935.14, Iz=20928.0, Xudot=-400.0, Yvdot=-400.0, Nrdot=-3000.0, Xu=-50.0, Xuu=-243.0,
             Yv=-200.0, Yvv=-2000.0, Nv=1281.0, Nr=-1281.0, Nrr=-3594.38)
#: The withheld terms of the judged scenario.
EXTRA = {"Y_r_ar": -3000.0, "N_v_ar": 3000.0, "N_r_r_r": -8000.0}
_DEG = math.pi / 180.0
NOISE = {"x0": 0.5, "y0": 0.5, "psi": 0.5 * _DEG, "u": 0.05, "v": 0.05, "r": 0.2 * _DEG}


def _phi(name: str, u, v, r):
    vals = {"u": u, "v": v, "r": r, "au": abs(u), "av": abs(v), "ar": abs(r)}
    out = 1.0
    for f in name.split("_")[1:]:
        out = out * vals[f]
    return out


def _rhs(p, extra, x, tau):
    psi, u, v, r = x[2], x[3], x[4], x[5]
    mu, mv, mr = p["m"] - p["Xudot"], p["m"] - p["Yvdot"], p["Iz"] - p["Nrdot"]
    cor = np.array([-mv * v * r, mu * u * r, (p["Xudot"] - p["Yvdot"]) * u * v])
    dmp = -np.array([p["Xu"] * u + p["Xuu"] * abs(u) * u, p["Yv"] * v + p["Yvv"] * abs(v) * v,
                     p["Nv"] * v + p["Nr"] * r + p["Nrr"] * abs(r) * r])
    add = np.zeros(3)
    for name, c in extra.items():
        add["XYN".index(name[0])] += c * _phi(name, u, v, r)
    acc = (tau - cor - dmp + add) / np.array([mu, mv, mr])
    c, s = math.cos(psi), math.sin(psi)
    return np.array([c * u - s * v, s * u + c * v, r, *acc])


def simulate(time: np.ndarray, tau: np.ndarray, x0, extra=None, params=None, substeps: int = 4,
             zigzag: tuple[float, float] | None = None, hold: str = "linear") -> np.ndarray:
    """States ``(n, 6)`` = (x0, y0, ψ, u, v, r) under ``tau`` ``(n, 3)`` (RK4 with ``substeps`` steps per
    sample), linear between samples (``hold="linear"``) or held over each interval (``"zero"``; module
    docstring). ``zigzag = (N_amp, ψ_switch)`` overrides the yaw moment by a bang–bang moment switched
    on heading (and writes it into ``tau``): the sample at ``t_{k+1}`` is decided from the state at
    ``t_k`` (one sample of controller delay, so that the linear input over each interval is known at its
    start)."""
    if hold not in ("linear", "zero"):
        raise ValueError(f"hold {hold!r}: linear or zero")
    p = {**TRUTH, **(params or {})}
    extra = EXTRA if extra is None else extra
    xs = np.zeros((time.size, 6))
    x = np.asarray(x0, dtype=float)
    sign = 1.0
    if zigzag is not None:
        tau[0, 2] = 0.0
    for k in range(time.size):
        xs[k] = x
        if k + 1 == time.size:
            break
        if zigzag is not None:
            amp, sw = zigzag
            if sign > 0 and x[2] > sw:
                sign = -1.0
            elif sign < 0 and x[2] < -sw:
                sign = 1.0
            tau[k + 1, 2] = sign * amp if time[k + 1] >= 2.0 else 0.0
        dt = time[k + 1] - time[k]
        h = dt / substeps
        slope = (tau[k + 1] - tau[k]) / dt if hold == "linear" else np.zeros(3)
        for j in range(substeps):
            ta, tb, tc = (tau[k] + slope * (j * h + c * h) for c in (0.0, 0.5, 1.0))
            k1 = _rhs(p, extra, x, ta)
            k2 = _rhs(p, extra, x + 0.5 * h * k1, tb)
            k3 = _rhs(p, extra, x + 0.5 * h * k2, tb)
            k4 = _rhs(p, extra, x + h * k3, tc)
            x = x + h * (k1 + 2 * k2 + 2 * k3 + k4) / 6.0
    return xs


def manoeuvre(kind: str, duration: float = 120.0, dt: float = 0.1, seed: int = 0):
    """``(time, tau, x0, zigzag)`` of one open-loop manoeuvre: ``steps``, ``sines``, ``chirp``,
    ``zigzag``, ``pullout`` or ``fast_pulses``."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration + 0.5 * dt, dt)
    n = t.size
    tau = np.zeros((n, 3))
    u0, zig = 4.0, None
    tau[:, 0] = 4100.0
    if kind == "steps":
        levels = rng.uniform(-2500, 2500, size=int(duration // 15) + 1)
        tau[:, 2] = levels[(t // 15).astype(int)]
        tau[:, 0] = 4100.0 + 1500.0 * np.sign(np.sin(2 * np.pi * t / 40.0))
    elif kind == "sines":
        tau[:, 2] = 1800.0 * np.sin(2 * np.pi * t / 25.0) + 700.0 * np.sin(2 * np.pi * t / 9.0)
        tau[:, 1] = 300.0 * np.sin(2 * np.pi * t / 13.0)
    elif kind == "chirp":
        f = 0.01 + (0.25 - 0.01) * t / duration
        tau[:, 2] = 2000.0 * np.sin(2 * np.pi * np.cumsum(f) * dt)
    elif kind == "zigzag":
        zig = (2200.0, 20 * _DEG)
    elif kind == "pullout":
        tau[:, 2] = np.where((t > 5.0) & (t < 45.0), 2600.0, 0.0)
    elif kind == "fast_pulses":
        u0 = 6.0
        tau[:, 0] = 50.0 * 6 + 243.0 * 36
        tau[:, 2] = 1200.0 * np.sin(2 * np.pi * t / 30.0)
        tau[:, 1] = np.where((t % 20.0 > 5.0) & (t % 20.0 < 9.0), 1500.0 * np.sign(np.sin(np.pi * t / 20.0)), 0.0)
    else:
        raise ValueError(kind)
    return t, tau, np.array([0.0, 0.0, 0.0, u0, 0.0, 0.0]), zig


def run_table(kind: str, duration: float = 120.0, dt: float = 0.1, seed: int = 0, extra=None, noise=True,
              params=None, hold: str = "linear") -> dict[str, np.ndarray]:
    """Columns of a CSV run (``time``, ``x0, y0, psi, u, v, r`` measured, ``tau_x, tau_y, tau_z``; SI, rad)."""
    t, tau, x0, zig = manoeuvre(kind, duration, dt, seed)
    xs = simulate(t, tau, x0, extra=extra, params=params, zigzag=zig, hold=hold)
    rng = np.random.default_rng(1000 + seed)
    cols = {"time": t}
    for i, c in enumerate(("x0", "y0", "psi", "u", "v", "r")):
        cols[c] = xs[:, i] + (rng.normal(0.0, NOISE[c], t.size) if noise else 0.0)
    for i, c in enumerate(("tau_x", "tau_y", "tau_z")):
        cols[c] = tau[:, i]
    return cols
