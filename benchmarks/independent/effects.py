r"""Hidden effects, implemented at the physics level (independently of diffship's effect code).

Every effect acts where the physics puts it, through one of four hooks that
:mod:`.vessels` calls:

* **actuator** (:class:`Lag`, :class:`Delay`, :class:`RateLimit`, :class:`RudderOffset`): between the *logged*
  command (what the data file holds) and the *actual* actuator output that drives the hull.
  ``actual(t, z, cmd)`` returns the actual actuator vector from the effect's own states ``z``
  and the command history ``cmd(t)``; ``dz`` their derivatives.

  - first-order lag :math:`T_a(t)\,\dot a = c - a` (constant :math:`T_a`, or a
    time-varying one for the out-of-family case);
  - pure delay :math:`a(t) = c(t - \tau)`, the logged command history interpolated linearly
    (no rational approximation);
  - rate limit :math:`\dot a = \mathrm{clip}((c - a)/\varepsilon, \pm\dot a_{max})`, a stiff
    servo (ε = 0.05 s) whose slew rate saturates;
  - rudder offset :math:`a = c + \delta_{off}`: the hull sees the logged rudder angle plus a
    constant offset (an indicator zero error, or the neutral helm of an asymmetric hull/propeller).
* **force** (:class:`ConstantForce`, :class:`Damping`, :class:`Wave`): an added generalised
  force on the hull [N, N, N·m] for the USV, or an added term in the Nomoto yaw equation
  :math:`T\dot r + r = K\delta + F` [rad/s]. Hydrodynamic terms see the velocity
  through the water :math:`\nu_r` that the vessel passes in.
* **current** (:class:`Current`): the water velocity :math:`v_c(t)` in NED and its rate;
  the vessel applies it in the relative-velocity form.
* **measurement** (:class:`SensorBias`): added to the measured channel (a compass
  misalignment reads :math:`\psi + b`).

Each effect carries ``label`` (the library effect a correct diagnosis names, or the family for
out-of-family truths) and ``params`` (the true values, for the report).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

__all__ = ["ConstantForce", "Current", "Damping", "Delay", "Effect", "Lag", "RateLimit", "RudderOffset", "SensorBias", "Wave"]


@dataclasses.dataclass
class Effect:
    """Base: no states, no force, no current, no measurement change."""

    hook: str = dataclasses.field(init=False, default="none")

    @property
    def params(self) -> dict[str, float]:
        return {k: v for k, v in dataclasses.asdict(self).items()
                if k != "hook" and isinstance(v, (int, float))}

    def n_states(self, n_act: int) -> int:
        return 0


# -- actuator effects ---------------------------------------------------------------------------
@dataclasses.dataclass
class Lag(Effect):
    r"""First-order lag :math:`T_a\dot a = c - a` on the actuator channels ``channels``.

    ``T_end`` > 0 makes the time constant drift linearly from ``T`` at t = 0 to ``T_end`` at
    ``t_end`` (out of family: a servo that heats up or loses pressure).
    """

    T: float = 1.0
    T_end: float = 0.0
    t_end: float = 60.0
    channels: tuple[int, ...] = (1, 2)

    def __post_init__(self):
        self.hook = "actuator"

    def n_states(self, n_act):
        return len(self.channels)

    def time_constant(self, t: float) -> float:
        if self.T_end > 0:
            return self.T + (self.T_end - self.T) * min(max(t / self.t_end, 0.0), 1.0)
        return self.T

    def init(self, c0: np.ndarray) -> np.ndarray:
        return np.array([c0[i] for i in self.channels], dtype=float)

    def actual(self, t, z, cmd: Callable[[float], np.ndarray]):
        c = cmd(t)
        a = c.copy()
        a[list(self.channels)] = z
        dz = (c[list(self.channels)] - z) / self.time_constant(t)
        return a, dz


@dataclasses.dataclass
class Delay(Effect):
    r"""Pure transport delay :math:`a(t) = c(t - \tau)` on ``channels`` (command history held
    at its first value before the run starts)."""

    tau: float = 1.0
    channels: tuple[int, ...] = (1, 2)

    def __post_init__(self):
        self.hook = "actuator"

    def init(self, c0):
        return np.zeros(0)

    def actual(self, t, z, cmd):
        c = cmd(t)
        a = c.copy()
        a[list(self.channels)] = cmd(t - self.tau)[list(self.channels)]
        return a, np.zeros(0)


@dataclasses.dataclass
class RateLimit(Effect):
    r"""Slew-rate-limited servo :math:`\dot a = \mathrm{clip}((c - a)/\varepsilon, \pm\,\mathrm{rate})`
    on ``channels`` (rate in actuator units per second)."""

    rate: float = 0.05
    eps: float = 0.05
    channels: tuple[int, ...] = (0,)

    def __post_init__(self):
        self.hook = "actuator"

    def n_states(self, n_act):
        return len(self.channels)

    def init(self, c0):
        return np.array([c0[i] for i in self.channels], dtype=float)

    def actual(self, t, z, cmd):
        c = cmd(t)
        a = c.copy()
        a[list(self.channels)] = z
        dz = np.clip((c[list(self.channels)] - z) / self.eps, -self.rate, self.rate)
        return a, dz


@dataclasses.dataclass
class RudderOffset(Effect):
    r"""Constant rudder-angle offset: the hull sees :math:`a = c + \delta_{off}` on ``channels``
    (``delta_off`` in rad; the logged rudder angle is the command :math:`c`).

    This is what the ship's "rudder offset" means in this generator (and in the library's
    ``rudder_offset`` effect for a Nomoto model): a zero error between the logged rudder angle and
    the angle the flow sees, so that the rudder which holds a straight course reads
    :math:`-\delta_{off}`. The truth ship itself has none (``Ship.delta0 = 0``), so a null
    scenario carries no offset.
    """

    delta_off: float = 0.0
    channels: tuple[int, ...] = (0,)

    def __post_init__(self):
        self.hook = "actuator"

    def init(self, c0):
        return np.zeros(0)

    def actual(self, t, z, cmd):
        a = cmd(t).copy()
        a[list(self.channels)] = a[list(self.channels)] + self.delta_off
        return a, np.zeros(0)


# -- forces ------------------------------------------------------------------------------------
@dataclasses.dataclass
class ConstantForce(Effect):
    """Constant body-fixed environmental force/moment ``(X0, Y0, N0)`` [N, N, N·m] (USV), or a
    constant term ``N0`` [rad/s] in the Nomoto yaw equation."""

    X0: float = 0.0
    Y0: float = 0.0
    N0: float = 0.0

    def __post_init__(self):
        self.hook = "force"

    def force(self, t, psi, nu_r):
        return np.array([self.X0, self.Y0, self.N0])


@dataclasses.dataclass
class Damping(Effect):
    r"""Missing hydrodynamic damping forces on the velocity through the water
    :math:`\nu_r = (u, v, r)`, each a separate coefficient (0 = absent):

    :math:`\Delta Y = Y_{|v|r}|v|r + Y_{|r|r}|r|r + Y_{vvv}v^3`,
    :math:`\Delta N = N_{|v|v}|v|v + N_{|v|r}|v|r + N_{rrr}r^3`.
    For the Nomoto ship only ``Nrr`` and ``Nrrr`` apply, as the added term
    :math:`F = N_{rr}|r|r + N_{rrr}r^3` in :math:`T\dot r + r = K(\delta+\delta_0) + F`
    (negative coefficients damp; units s and s², since F is in rad/s).
    """

    Yvr: float = 0.0
    Yrr: float = 0.0
    Yvvv: float = 0.0
    Nvv: float = 0.0
    Nvr: float = 0.0
    Nrrr: float = 0.0
    Nrr: float = 0.0

    def __post_init__(self):
        self.hook = "force"

    def force(self, t, psi, nu_r):
        _, v, r = nu_r
        Y = self.Yvr * abs(v) * r + self.Yrr * abs(r) * r + self.Yvvv * v ** 3
        N = self.Nvv * abs(v) * v + self.Nvr * abs(v) * r + self.Nrrr * r ** 3 + self.Nrr * abs(r) * r
        return np.array([0.0, Y, N])


@dataclasses.dataclass
class Wave(Effect):
    r"""Wave-like disturbance: a mean drift force ``F_mean`` [N] towards NED direction ``beta``
    plus a first-order oscillation at encounter period ``period`` [s] of amplitudes ``F_osc``
    (sway, N) and ``N_osc`` (yaw, N·m):

    :math:`\Delta\tau = R(\psi)^\top F_{mean}(\cos\beta, \sin\beta) + (0, F_{osc}, N_{osc})\sin(2\pi t/T_e)`.
    """

    F_mean: float = 0.0
    beta: float = 0.0
    F_osc: float = 0.0
    N_osc: float = 0.0
    period: float = 7.0

    def __post_init__(self):
        self.hook = "force"

    def force(self, t, psi, nu_r):
        c, s = np.cos(psi), np.sin(psi)
        fx, fy = self.F_mean * np.cos(self.beta), self.F_mean * np.sin(self.beta)
        w = np.sin(2 * np.pi * t / self.period)
        return np.array([c * fx + s * fy, -s * fx + c * fy + self.F_osc * w, self.N_osc * w])


# -- current -----------------------------------------------------------------------------------
@dataclasses.dataclass
class Current(Effect):
    r"""Water velocity in NED: speed ``V`` [m/s] towards direction ``beta`` [rad].

    ``omega`` ≠ 0 rotates the direction at ``omega`` rad/s; ``ramp`` > 0 grows the speed linearly
    from 0 to ``V`` over ``ramp`` seconds (both out of family: the library's current is constant).
    Returns :math:`v_c(t)` and :math:`\dot v_c(t)`.
    """

    V: float = 0.0
    beta: float = 0.0
    omega: float = 0.0
    ramp: float = 0.0

    def __post_init__(self):
        self.hook = "current"

    def velocity(self, t):
        b = self.beta + self.omega * t
        if self.ramp > 0 and t < self.ramp:
            V, dV = self.V * t / self.ramp, self.V / self.ramp
        else:
            V, dV = self.V, 0.0
        vc = np.array([V * np.cos(b), V * np.sin(b)])
        vcd = np.array([dV * np.cos(b) - V * self.omega * np.sin(b), dV * np.sin(b) + V * self.omega * np.cos(b)])
        return vc, vcd


# -- measurement -------------------------------------------------------------------------------
@dataclasses.dataclass
class SensorBias(Effect):
    """Constant bias ``b`` added to the measured channel ``channel`` (e.g. compass ψ + b)."""

    b: float = 0.0
    channel: str = "psi"

    def __post_init__(self):
        self.hook = "measurement"

    def measure(self, y: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        out = dict(y)
        out[self.channel] = out[self.channel] + self.b
        return out
