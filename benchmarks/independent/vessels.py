r"""Truth vessels and the simulation loop (NumPy only).

**USV** (3-DOF, Fossen's matrix form, body-fixed velocities over ground ν = (u, v, r), earth-
fixed η = (x, y, ψ), x north, y east, ψ clockwise; force inputs τ = (τ_x, τ_y, τ_z)):

.. math::
    \dot\eta = R(\psi)\nu,\qquad
    M_{RB}\dot\nu + C_{RB}(\nu)\nu + M_A\dot\nu_r + C_A(\nu_r)\nu_r + D(\nu_r)\nu_r = \tau + \Delta\tau

with the velocity through the water :math:`\nu_r = \nu - (R^\top v_c, 0)` and
:math:`\dot\nu_r = \dot\nu - \tfrac{d}{dt}(R^\top v_c)`, :math:`\tfrac{d}{dt}(R^\top v_c) =
r(v^b_{c,y}, -v^b_{c,x}) + R^\top\dot v_c` (Fossen 2021, §10.3, eqs. 10.7–10.10: rigid-body terms
in the inertial velocity, hydrodynamic terms in the relative one). Diagonal added mass, CG at the
origin; :math:`C_{RB}(\nu)\nu = (-m v r,\ m u r,\ 0)`,
:math:`C_A(\nu)\nu = (Y_{\dot v} v r,\ -X_{\dot u} u r,\ (X_{\dot u} - Y_{\dot v}) u v)` (Fossen 2021
eq. 6.43 with diagonal added mass; the last entry is the Munk moment; C_RB and C_A are
skew-symmetric, so without damping and forcing the kinetic energy ½νᵀMν is conserved — the
generator's test checks this), :math:`D(\nu)\nu = -(X_u u + X_{|u|u}|u|u,\ Y_v v + Y_{|v|v}|v|v,\ N_v v + N_r r +
N_{|r|r}|r|r)`.

**Ship** (first-order Nomoto, states ψ, r; rudder δ [rad], starboard positive):
:math:`\dot\psi = r,\ T\dot r + r = K(\delta + \delta_0) + F` with F from force effects and
δ the rudder angle the hull sees (the logged one after the actuator effects). The truth ship has
**no built-in rudder offset** (δ0 = 0): a rudder offset is a hidden effect of its own
(:class:`~.effects.RudderOffset`, scenario label ``rudder_offset``). Until 2026-11-25 the base
ship carried δ0 = 0.004 rad (0.23°) in every scenario, nulls included; diffship's diagnosis holds
a Nomoto model's own δ0 at 0 in the base fit so that its ``rudder_offset`` candidate stands for
it, so those "null" data did hold a rudder offset and the diagnosis rightly named it — the label
was wrong, not the diagnosis.

The simulation (:func:`simulate`) advances sample by sample with :func:`~.integrate.rk4_interval`;
the logged command either is given (open loop) or comes from a :class:`Zigzag` helmsman that
reads the (biased, noise-free) compass at each sample and orders the rudder (closed loop). The
command seen inside an interval is the logged command interpolated linearly in time.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .effects import Effect
from .integrate import rk4_interval

__all__ = ["USV", "Ship", "Zigzag", "simulate", "usv_commands"]

DEG = np.pi / 180.0


@dataclasses.dataclass
class USV:
    """A 5 t water-jet USV. Mass and inertia are known (the fitted base model fixes them); the
    hydrodynamic coefficients are this generator's own truth (SI units)."""

    m: float = 4935.14
    Iz: float = 20928.0
    Xudot: float = -350.0
    Yvdot: float = -700.0
    Nrdot: float = -7000.0
    Xu: float = -65.0
    Yv: float = -280.0
    Nv: float = 1600.0
    Nr: float = -1900.0
    Xuu: float = -300.0
    Yvv: float = -2600.0
    Nrr: float = -2600.0

    states = ("x0", "y0", "psi", "u", "v", "r")
    inputs = ("tau_x", "tau_y", "tau_z")
    outputs = ("x0", "y0", "psi", "u", "v", "r")

    def rhs(self, t, x, tau, extra_force, current):
        psi, nu = x[2], x[3:6]
        c, s = np.cos(psi), np.sin(psi)
        vc, vcd = current(t)
        vcb = np.array([c * vc[0] + s * vc[1], -s * vc[0] + c * vc[1]])
        vcbd = np.array([c * vcd[0] + s * vcd[1], -s * vcd[0] + c * vcd[1]])
        u, v, r = nu
        ur, vr = u - vcb[0], v - vcb[1]
        dvcb = np.array([r * vcb[1] + vcbd[0], -r * vcb[0] + vcbd[1], 0.0])  # d/dt (R^T v_c, 0)
        MA = np.array([-self.Xudot, -self.Yvdot, -self.Nrdot])
        MRB = np.array([self.m, self.m, self.Iz])
        crb = np.array([-self.m * v * r, self.m * u * r, 0.0])
        ca = np.array([self.Yvdot * vr * r, -self.Xudot * ur * r, (self.Xudot - self.Yvdot) * ur * vr])
        d = -np.array([self.Xu * ur + self.Xuu * abs(ur) * ur,
                       self.Yv * vr + self.Yvv * abs(vr) * vr,
                       self.Nv * vr + self.Nr * r + self.Nrr * abs(r) * r])
        f = extra_force(t, psi, np.array([ur, vr, r]))
        # (M_RB + M_A) nu_dot = tau + f - C_RB nu - C_A nu_r - D nu_r + M_A d/dt(R^T v_c)
        nud = (tau + f - crb - ca - d + MA * dvcb) / (MRB + MA)
        return np.array([c * u - s * v, s * u + c * v, r, *nud])

    def rest_state(self, u0: float) -> np.ndarray:
        return np.array([0.0, 0.0, 0.0, u0, 0.0, 0.0])


@dataclasses.dataclass
class Ship:
    """First-order Nomoto ship: K [1/s], T [s], built-in rudder offset δ0 [rad] (0: none; the
    scenarios inject an offset as the ``rudder_offset`` effect instead)."""

    K: float = 0.11
    T: float = 12.0
    delta0: float = 0.0

    states = ("psi", "r")
    inputs = ("delta",)
    outputs = ("psi", "r")

    def rhs(self, t, x, delta, extra_force, current):
        r = x[1]
        F = extra_force(t, x[0], np.array([0.0, 0.0, r]))[2]
        return np.array([r, (self.K * (delta[0] + self.delta0) - r + F) / self.T])

    def rest_state(self, u0: float = 0.0) -> np.ndarray:
        return np.array([0.0, self.K * self.delta0])


@dataclasses.dataclass
class Zigzag:
    """A helmsman's zigzag: rudder ``amp`` [rad] to ``side`` (+1 starboard) at ``t_start``, then
    reversed each time the compass heading passes ``±switch`` [rad] from the initial heading;
    the logged rudder moves towards the order at ``rate`` [rad/s] (the steering gear)."""

    amp: float
    switch: float
    side: int = 1
    rate: float = 8 * DEG
    t_start: float = 2.0

    def next_command(self, t, delta_now, psi_meas, psi_ref, state):
        if t >= self.t_start and "order" not in state:
            state["order"] = self.side * self.amp
        order = state.get("order", 0.0)
        dpsi = psi_meas - psi_ref
        if order > 0 and dpsi >= self.switch:
            order = -self.amp
        elif order < 0 and dpsi <= -self.switch:
            order = self.amp
        if "order" in state:
            state["order"] = order
        return order


def usv_commands(t: np.ndarray, rng: np.random.Generator, max_nozzle: float = 25 * DEG) -> np.ndarray:
    """Open-loop jet commands: thrust levels held 25 s in 2–6 kN, nozzle angle levels held
    8–14 s within ±max_nozzle, nozzle slewed at 15°/s; τ = T(cos α, sin α, −3.8 sin α)."""
    dt = float(t[1] - t[0])
    n = t.size
    thrust = np.empty(n)
    nozzle_order = np.empty(n)
    k = 0
    while k < n:
        m = int(25.0 / dt)
        thrust[k:k + m] = rng.uniform(2000.0, 6000.0)
        k += m
    k = int(3.0 / dt)
    nozzle_order[:k] = 0.0
    side = rng.choice([-1.0, 1.0])
    while k < n:
        m = int(rng.uniform(8.0, 14.0) / dt)
        nozzle_order[k:k + m] = side * rng.uniform(0.35, 1.0) * max_nozzle
        side = -side
        k += m
    alpha = np.zeros(n)
    for i in range(1, n):
        alpha[i] = alpha[i - 1] + np.clip(nozzle_order[i] - alpha[i - 1], -15 * DEG * dt, 15 * DEG * dt)
    # thrust changes over 2 s
    w = int(2.0 / dt)
    thrust = np.convolve(np.concatenate([np.full(w, thrust[0]), thrust]), np.ones(w) / w, "valid")[1:n + 1]
    return np.stack([thrust * np.cos(alpha), thrust * np.sin(alpha), -3.8 * thrust * np.sin(alpha)], axis=1)


def simulate(vessel, effects: list[Effect], t: np.ndarray, *, commands: np.ndarray | None = None,
             pilot: Zigzag | None = None, u0: float = 2.0, preroll: float = 30.0, substeps: int = 10) -> dict:
    """Simulate ``vessel`` with ``effects`` on the sample times ``t``.

    Open loop: ``commands`` (n × inputs), the logged actuator commands. Closed loop: ``pilot``
    decides the logged rudder sample by sample. Before ``t[0]`` the vessel runs ``preroll``
    seconds with the first command held (so the record starts in a steady state, effects
    included). Returns ``{"time", "commands", "clean", "actual"}``: logged commands, noise-free
    measurements (sensor biases included) and the actual actuator output.
    """
    acts = [e for e in effects if e.hook == "actuator"]
    acts.sort(key=lambda e: 0 if type(e).__name__ == "Delay" else 1)  # a delay acts on the raw command
    forces = [e for e in effects if e.hook == "force"]
    currents = [e for e in effects if e.hook == "current"]
    meas = [e for e in effects if e.hook == "measurement"]
    n, ni = t.size, len(vessel.inputs)
    cmd = np.zeros((n, ni)) if commands is None else np.asarray(commands, dtype=float)
    known = [n if commands is not None else 1]  # samples of the logged command known so far

    def cmd_fn(tt):
        k = known[0]
        if tt <= t[0]:
            return cmd[0].copy()
        return np.array([np.interp(tt, t[:k], cmd[:k, j]) for j in range(ni)])

    def extra_force(tt, psi, nu_r):
        f = np.zeros(3)
        for e in forces:
            f = f + e.force(tt, psi, nu_r)
        return f

    def current(tt):
        if not currents:
            return np.zeros(2), np.zeros(2)
        return currents[0].velocity(max(tt, 0.0))

    ns = len(vessel.states)
    sizes = [e.n_states(ni) for e in acts]

    def held(a):
        return lambda _t: a

    def actual(tt, z):
        fn, off, dz = cmd_fn, 0, []
        a = fn(tt)
        for e, k in zip(acts, sizes):
            a, d = e.actual(tt, z[off:off + k], fn)
            dz.append(d)
            off += k
            fn = held(a)  # the next actuator effect acts on this one's output (at the same time)
        return a, (np.concatenate(dz) if dz else np.zeros(0))

    def f(tt, xz):
        a, dz = actual(tt, xz[ns:])
        return np.concatenate([vessel.rhs(tt, xz[:ns], a, extra_force, current), dz])

    x0 = vessel.rest_state(u0)
    if "v" in vessel.states:  # start moving with the water: through-water velocity (u0, 0, 0) at ψ = 0
        iu = vessel.states.index("u")
        x0[iu:iu + 2] += current(0.0)[0]
    x = np.concatenate([x0] + [e.init(cmd[0]) for e in acts])
    # pre-roll with the first command held, current at its t=0 value
    if preroll > 0:
        x = rk4_interval(lambda tt, xz: f(0.0, xz), -preroll, 0.0, x, substeps=int(preroll * 10))
        for name in ("x0", "y0", "psi"):  # the record starts at the origin, heading north
            if name in vessel.states:
                x[vessel.states.index(name)] = 0.0
    X = np.zeros((n, x.size))
    A = np.zeros((n, ni))
    X[0] = x
    A[0] = actual(t[0], x[ns:])[0]
    state, psi_ref = {}, None
    for k in range(n - 1):
        if pilot is not None:
            psi_m = x[vessel.states.index("psi")] + sum(e.b for e in meas if e.channel == "psi")
            psi_ref = psi_m if psi_ref is None else psi_ref
            order = pilot.next_command(t[k], cmd[k, 0], psi_m, psi_ref, state)
            step = pilot.rate * (t[k + 1] - t[k])
            cmd[k + 1, 0] = cmd[k, 0] + np.clip(order - cmd[k, 0], -step, step)
            known[0] = k + 2
        x = rk4_interval(f, t[k], t[k + 1], x, substeps)
        X[k + 1] = x
        A[k + 1] = actual(t[k + 1], x[ns:])[0]
        if not np.all(np.isfinite(x)):
            raise RuntimeError("the truth simulation blew up")
    clean = {c: X[:, vessel.states.index(c)] for c in vessel.outputs}
    for e in meas:
        clean = e.measure(clean)
    return {"time": t, "commands": cmd, "clean": clean, "actual": A}
