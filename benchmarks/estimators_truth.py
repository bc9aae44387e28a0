"""The NumPy truths of the estimators benchmark (:mod:`benchmarks.estimators`): written apart from the fitter.

Plain NumPy models and integrator — nothing from ``diffship.models``, ``diffship.simulate`` or
``diffship.synthetic``: the Fossen 3-DOF USV (the water-jet USV hull with the test USV's added masses
and damping) and the MMG KVLCC2 L7 model (Yasukawa & Yoshimura 2015), RK4 with 10 substeps per
sample, inputs linear within a sample, Ornstein–Uhlenbeck disturbance forces/moments advanced
exactly per substep, then white sensor noise (GNSS velocity 0.05 m/s, heading 0.5°, gyro 0.2°/s).
Only :func:`to_run` touches diffship: it wraps the arrays into a :class:`diffship.data.Run`.
"""

from __future__ import annotations

import math

import numpy as np

from diffship.data import Run

DEG = math.pi / 180
SENSOR = {"x0": 0.5, "y0": 0.5, "psi": 0.5 * DEG, "u": 0.05, "v": 0.05, "r": 0.2 * DEG}

# -- truth 1: Fossen 3-DOF USV (NumPy) ----------------------------------------------------------
USV = dict(m=4935.14, Iz=20928.0, Xudot=-400.0, Yvdot=-600.0, Nrdot=-8000.0, Xu=-70.0, Yv=-300.0,
           Nv=1700.0, Nr=-1800.0, Xuu=-320.0, Yvv=-2800.0, Nrr=-2400.0)


def usv_rhs(x, tau, p=USV):
    """ẋ of (x0, y0, psi, u, v, r) for generalised forces tau (3,) [N, N, N m]; x_g = 0."""
    psi, u, v, r = x[2], x[3], x[4], x[5]
    a, b, e = p["m"] - p["Xudot"], p["m"] - p["Yvdot"], p["Iz"] - p["Nrdot"]
    cx, cy = (p["m"] - p["Yvdot"]) * v, (p["m"] - p["Xudot"]) * u
    coriolis = np.array([-cx * r, cy * r, cx * u - cy * v])
    damping = -np.array([(p["Xu"] + p["Xuu"] * abs(u)) * u, (p["Yv"] + p["Yvv"] * abs(v)) * v,
                         p["Nv"] * v + (p["Nr"] + p["Nrr"] * abs(r)) * r])
    acc = (tau - coriolis - damping) / np.array([a, b, e])
    return np.array([u * math.cos(psi) - v * math.sin(psi), u * math.sin(psi) + v * math.cos(psi), r, *acc])


#: Surge-thrust design: (lowest, highest level [N], hold [s]). "base": the design of the first benchmark;
#: "rich": down to 150 N (about 0.6 m/s) with 20 s holds, so that the linear surge damping X_u, a few
#: per cent of the force at 2–4 m/s, is seen at low speed where it is a third of it (experiment design).
THRUST = {"base": (1500.0, 6000.0, 40.0), "rich": (150.0, 6000.0, 20.0), "fast": (150.0, 6000.0, 8.0)}


def usv_inputs(rng, t, design="base"):
    """Surge thrust levels and nozzle angles (12 s), 2 s moving-average ramps; τ_z = −3.82 τ_y."""
    lo, hi, hold = THRUST[design]
    def levels(hold, lo, hi):
        k = int(round(hold / (t[1] - t[0])))
        sig = np.repeat(rng.uniform(lo, hi, t.size // k + 2), k)[: t.size]
        w = int(round(2.0 / (t[1] - t[0])))
        return np.convolve(np.concatenate([np.full(w, sig[0]), sig]), np.ones(w) / w, "valid")[1: t.size + 1]

    thrust, nozzle = levels(hold, lo, hi), levels(12.0, -20 * DEG, 20 * DEG)
    tx, ty = thrust * np.cos(nozzle), thrust * np.sin(nozzle)
    return np.stack([tx, ty, -3.82 * ty], 1)


def simulate_truth(rhs, x0, t, inputs, rng, dist_sd, dist_tau, substeps=10, law=None):
    """RK4 with ``substeps`` per sample; OU disturbance (exact per substep) added to ``rhs``'s forces.

    ``inputs``: (N, n_u) sample values (linear in between), or ``law(x, u_prev, h) -> u`` (closed loop).
    Returns states (N, n_x) and the inputs actually applied (N, n_u)."""
    n = t.size
    xs = np.zeros((n, len(x0)))
    x = np.array(x0, dtype=float)
    d = np.zeros(len(dist_sd)) if dist_sd is not None else None
    us = np.zeros((n, inputs.shape[1])) if law is None else np.zeros((n, law.n_u))
    u_now = inputs[0] if law is None else law.start()
    for k in range(n):
        xs[k] = x
        us[k] = u_now
        if k + 1 == n:
            break
        h = (t[k + 1] - t[k]) / substeps
        for j in range(substeps):
            if law is None:
                ua = inputs[k] + (inputs[k + 1] - inputs[k]) * j / substeps
                ub = inputs[k] + (inputs[k + 1] - inputs[k]) * (j + 0.5) / substeps
                uc = inputs[k] + (inputs[k + 1] - inputs[k]) * (j + 1) / substeps
            else:
                ua = ub = uc = u_now = law(x, u_now, h)
            if d is not None:
                a = math.exp(-h / dist_tau)
                d = a * d + np.asarray(dist_sd) * math.sqrt(1 - a * a) * rng.normal(size=d.size)
            f = (lambda xx, uu: rhs(xx, uu, d)) if d is not None else (lambda xx, uu: rhs(xx, uu, None))
            k1 = f(x, ua)
            k2 = f(x + 0.5 * h * k1, ub)
            k3 = f(x + 0.5 * h * k2, ub)
            k4 = f(x + h * k3, uc)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        if law is not None:
            us[k + 1] = u_now
    return xs, us


def to_run(name, t, xs, inputs, input_names, rng, noise=True):
    ch = {c: xs[:, i] + (rng.normal(0, SENSOR[c], t.size) if noise else 0.0)
          for i, c in enumerate(("x0", "y0", "psi", "u", "v", "r"))}
    ch.update({n: inputs[:, j] for j, n in enumerate(input_names)})
    return Run(name, t, ch)


def usv_case(duration, dist_scale, seed, design="base", n_runs=2):
    """``n_runs`` disturbed training runs and one clean held-out run (with its true initial state)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration + 0.05, 0.1)
    sd = np.array([30.0, 12.0, 40.0]) * dist_scale

    def rhs(x, tau, d):
        return usv_rhs(x, tau if d is None else tau + d)

    train = []
    for i in range(n_runs):
        tau = usv_inputs(rng, t, design)
        xs, _ = simulate_truth(rhs, [0, 0, 0, 2.0, 0, 0], t, tau, rng, sd if dist_scale else None, 8.0)
        train.append(to_run(f"usv_{i}", t, xs, tau, ("tau_x", "tau_y", "tau_z"), rng))
    th = np.arange(0.0, 120.05, 0.1)
    tau = usv_inputs(rng, th, design)
    xs, _ = simulate_truth(rhs, [0, 0, 0, 2.0, 0, 0], th, tau, rng, None, 8.0)
    held = to_run("held_out", th, xs, tau, ("tau_x", "tau_y", "tau_z"), rng, noise=False)
    return train, held, xs[0]


# -- truth 2: MMG KVLCC2 L7 (NumPy) ------------------------------------------------------------
K2 = dict(R0=0.022, Xvv=-0.040, Xvr=0.002, Xrr=0.011, Xvvvv=0.771, Yv=-0.315, Yr=0.083, Yvvv=-1.607,
          Yvvr=0.379, Yvrr=-0.391, Yrrr=0.008, Nv=-0.137, Nr=-0.049, Nvvv=-0.030, Nvvr=-0.294, Nvrr=0.055,
          Nrrr=-0.013, mx=0.022, my=0.223, Jz=0.011, tP=0.220, wP0=0.40, xP=-0.48, C1=2.0, C2p=1.6, C2m=1.1,
          k0=0.2931, k1=-0.2753, k2=-0.1385, tR=0.387, aH=0.312, xH=-0.464, xR=-0.5, eps=1.09, kappa=0.50,
          lR=-0.710, gRm=0.395, gRp=0.640, fa=2.747, L=7.0, d=0.46, DP=0.216, HR=0.345, AR=0.0539,
          m=3272.0, xG=0.0348 * 7.0, kzz=0.2486, rho=1000.0)


def mmg_rhs(x, inp, dist, p=K2):
    """ẋ of (x0, y0, psi, u, v, r) at midship; inp = (delta [rad, starboard +], n [rps])."""
    psi, u, v, r = x[2], x[3], x[4], x[5]
    delta, n = inp
    L, d, rho = p["L"], p["d"], p["rho"]
    U = math.sqrt(u * u + v * v + 1e-12)
    vp, rp = v / U, r * L / U
    q = 0.5 * rho * L * d * U * U
    XH = q * (-p["R0"] + p["Xvv"] * vp**2 + p["Xvr"] * vp * rp + p["Xrr"] * rp**2 + p["Xvvvv"] * vp**4)
    YH = q * (p["Yv"] * vp + p["Yr"] * rp + p["Yvvv"] * vp**3 + p["Yvvr"] * vp**2 * rp + p["Yvrr"] * vp * rp**2
              + p["Yrrr"] * rp**3)
    NH = q * L * (p["Nv"] * vp + p["Nr"] * rp + p["Nvvv"] * vp**3 + p["Nvvr"] * vp**2 * rp
                  + p["Nvrr"] * vp * rp**2 + p["Nrrr"] * rp**3)
    beta = math.atan2(-v, u)
    bp = beta - p["xP"] * rp
    c2 = p["C2p"] if bp > 0 else p["C2m"]
    wfac = (1 - p["wP0"]) * (1 + (1 - math.exp(-p["C1"] * abs(bp))) * (c2 - 1))
    up = u * wfac
    J = up / (n * p["DP"])
    KT = p["k0"] + p["k1"] * J + p["k2"] * J * J
    XP = (1 - p["tP"]) * rho * n * n * p["DP"] ** 4 * KT
    eta = p["DP"] / p["HR"]
    slip = math.sqrt(max(up * up + 8 * KT * (n * p["DP"]) ** 2 / math.pi, 1e-12))
    uR = p["eps"] * math.sqrt(eta * (up + p["kappa"] * (slip - up)) ** 2 + (1 - eta) * up * up + 1e-12)
    bR = beta - p["lR"] * rp
    vR = U * (p["gRm"] if bR < 0 else p["gRp"]) * bR
    FN = 0.5 * rho * p["AR"] * (uR * uR + vR * vR) * p["fa"] * math.sin(delta - math.atan2(vR, uR))
    X = XH + XP - (1 - p["tR"]) * FN * math.sin(delta)
    Y = YH - (1 + p["aH"]) * FN * math.cos(delta)
    N = NH - (p["xR"] + p["aH"] * p["xH"]) * L * FN * math.cos(delta)
    if dist is not None:
        X, Y, N = X + dist[0], Y + dist[1], N + dist[2]
    half = 0.5 * rho * L * L * d
    a, b, c = p["m"] + half * p["mx"], p["m"] + half * p["my"], p["xG"] * p["m"]
    e = p["m"] * (p["kzz"] * L) ** 2 + p["xG"] ** 2 * p["m"] + half * L * L * p["Jz"]
    f1, f2, f3 = X + b * v * r + c * r * r, Y - a * u * r, N - c * u * r
    det = b * e - c * c
    acc = (f1 / a, (e * f2 - c * f3) / det, (b * f3 - c * f2) / det)
    return np.array([u * math.cos(psi) - v * math.sin(psi), u * math.sin(psi) + v * math.cos(psi), r, *acc])


class Zigzag:
    """Closed-loop zigzag: rudder to ±amp at 15.8°/s, switched when the heading passes ∓switch."""

    n_u = 2

    def __init__(self, amp_deg, switch_deg, rps=10.23):
        self.amp, self.sw, self.rps, self.target = amp_deg * DEG, switch_deg * DEG, rps, amp_deg * DEG

    def start(self):
        return np.array([0.0, self.rps])

    def __call__(self, x, u_prev, h):
        if x[2] >= self.sw:
            self.target = -self.amp
        elif x[2] <= -self.sw:
            self.target = self.amp
        step = 15.8 * DEG * h
        return np.array([u_prev[0] + np.clip(self.target - u_prev[0], -step, step), self.rps])


#: MMG parameter names (diffship) → keys of :data:`K2` where they differ.
K2_NAMES = {"f_alpha": "fa", "gammaR_minus": "gRm", "gammaR_plus": "gRp", "C2_plus": "C2p", "C2_minus": "C2m"}
#: KVLCC2 free sets: the MMG model's 10 defaults, or the KVLCC2 study's 33 (every hydrodynamic and
#: interaction coefficient, the manoeuvring wake C1, C2± and δ0: ``diffship.studies.kvlcc2.DEFAULT_FREE``,
#: copied here so that the benchmark does not load the study's pandas dependencies).
K2_FREE = {"ten": None,
           "study": ("R0", "Xvv", "Xvr", "Xrr", "Xvvvv", "Yv", "Yr", "Yvvv", "Yvvr", "Yvrr", "Yrrr", "Nv", "Nr",
                     "Nvvv", "Nvvr", "Nvrr", "Nrrr", "mx", "my", "Jz", "tR", "aH", "xH", "eps", "kappa", "lR",
                     "gammaR_minus", "gammaR_plus", "f_alpha", "delta0", "C1", "C2_plus", "C2_minus")}


#: KVLCC2 L7 disturbance at level 1: Ornstein–Uhlenbeck X, Y, N [N, N, N m] standard deviations (τ 8 s),
#: sized like the USV's (about 1 % of the resistance R'_0·q ≈ 49 N at 1.18 m/s in X, 1 N in Y, a lever
#: of 0.4 L in N).
K2_DIST = (0.5, 1.0, 3.0)


def kvlcc2_runs(seed, duration=90.0, amps=(10.0, 20.0), dt=0.1, dist_level=0.0):
    """Closed-loop zigzags of the NumPy truth at 10 Hz with sensor noise; ``dt`` > 0.1 keeps every
    ``dt / 0.1``-th sample (the truth is always integrated at 10 Hz with 10 RK4 substeps);
    ``dist_level`` > 0 adds the OU disturbance :data:`K2_DIST` × level (τ 8 s)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration + 0.05, 0.1)
    keep = round(dt / 0.1)
    sd = np.asarray(K2_DIST) * dist_level if dist_level else None
    runs = []
    for amp in amps:
        xs, us = simulate_truth(mmg_rhs, [0, 0, 0, 1.179, 0, 0], t, np.zeros((1, 2)), rng, sd, 8.0,
                                law=Zigzag(amp, amp))
        run = to_run(f"zigzag_{amp:g}", t, xs, us, ("delta", "n"), rng)
        if keep > 1:
            run = Run(run.name, t[::keep], {c: np.asarray(v)[::keep] for c, v in run.channels.items()})
        runs.append(run)
    return runs
