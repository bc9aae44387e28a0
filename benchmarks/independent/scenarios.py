r"""The scenario grid and :func:`generate` (plain arrays out; no diffship types).

A :class:`Scenario` is one truth: a vessel, at most one hidden effect (or none), its size
(``weak`` ≈ barely above the noise, ``medium``, ``strong``), and a seed (excitation and noise).
``label`` is the library effect a correct diagnosis should name (``"none"`` for null cases);
out-of-family truths (``kind == "out"``) are scored by ``family`` instead.

Runs: the USV gets 4 training and 2 validation runs (40 s at 10 Hz) of open-loop jet commands
(:func:`~.vessels.usv_commands`, different seeds, so validation manoeuvres differ from training);
the ship gets 4 training and 2 validation zigzags (70 s) of different amplitudes (closed loop). Noise
is white Gaussian with this generator's own sensor levels (:data:`NOISE`).

The ship's null truth has no rudder offset, and ``rudder_offset`` is one of the ship's in-family
effects (an injected rudder-angle offset, :class:`~.effects.RudderOffset`; the USV's constant sway force and
yaw moment, :class:`~.effects.ConstantForce`, is ``constant_force``, named ``rudder_offset`` before 2026-11-29,
with the same data); before 2026-11-25 the
truth ship carried a built-in offset in every scenario, so its nulls were not null under
diffship's effect definitions (see :mod:`.vessels`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from . import effects as fx
from .vessels import DEG, USV, Ship, Zigzag, simulate, usv_commands

__all__ = ["NOISE", "SIZES", "Scenario", "generate", "scenarios"]

#: Sensor noise (one standard deviation): GNSS position, log/GNSS velocity, compass, gyro.
NOISE = {"usv": {"x0": 0.4, "y0": 0.4, "psi": 0.4 * DEG, "u": 0.04, "v": 0.04, "r": 0.15 * DEG},
         "ship": {"psi": 0.3 * DEG, "r": 0.1 * DEG}}

#: Size multipliers of the "strong" value.
SIZES = {"weak": 0.25, "medium": 0.5, "strong": 1.0}


def _usv_effect(label: str, k: float) -> fx.Effect | None:
    """The USV's hidden effect ``label`` at ``k`` × its strong size (in family, then out)."""
    return {
        "actuator_lag": lambda: fx.Lag(T=2.0 * k, channels=(1, 2)),
        "input_delay": lambda: fx.Delay(tau=1.6 * k, channels=(1, 2)),
        "constant_force": lambda: fx.ConstantForce(Y0=40.0 * k, N0=-170.0 * k),
        "heading_bias": lambda: fx.SensorBias(b=8.0 * DEG * k, channel="psi"),
        "current": lambda: fx.Current(V=0.4 * k, beta=2.2),
        "damping_vv": lambda: fx.Damping(Nvv=-250.0 * k),
        "damping_vr": lambda: fx.Damping(Yvr=-750.0 * k, Nvr=-3000.0 * k),
        "damping_rr": lambda: fx.Damping(Yrr=-8000.0 * k),
        # out of family
        "rotating_current": lambda: fx.Current(V=0.4 * k, beta=0.5, omega=2 * np.pi / 300.0),
        "ramped_current": lambda: fx.Current(V=0.5 * k, beta=-1.0, ramp=60.0),
        "varying_lag": lambda: fx.Lag(T=0.5 * k, T_end=3.0 * k, t_end=60.0, channels=(1, 2)),
        "wave": lambda: fx.Wave(F_mean=150.0 * k, beta=1.0, F_osc=150.0 * k, N_osc=600.0 * k, period=6.0),
        "cubic_damping": lambda: fx.Damping(Nrrr=-9000.0 * k, Yvvv=-3000.0 * k),
        "none": lambda: None,
    }[label]()


def _ship_effect(label: str, k: float) -> fx.Effect | None:
    """The ship's hidden effect ``label`` at ``k`` × its strong size.

    ``rudder_offset``: the hull sees the logged rudder plus δ_off, strong 1.0° (weak 0.25°). That
    is the size met in practice: the neutral helm of a single-screw ship (the rudder angle that
    holds a straight course, from the propeller's asymmetric inflow) found in straight-run sea
    trials and basin runs is of the order of 0.5–2°, and a rudder-angle indicator's zero error of
    about a degree passes unnoticed in service; 0.25° is at the resolution of a logged rudder angle.
    """
    return {
        "actuator_lag": lambda: fx.Lag(T=3.0 * k, channels=(0,)),
        "input_delay": lambda: fx.Delay(tau=2.0 * k, channels=(0,)),
        "rate_limit": lambda: fx.RateLimit(rate=2.5 * DEG / np.sqrt(k), channels=(0,)),
        "rudder_offset": lambda: fx.RudderOffset(delta_off=1.0 * DEG * k, channels=(0,)),
        "damping_rr": lambda: fx.Damping(Nrr=-250.0 * k),
        # out of family
        "varying_lag": lambda: fx.Lag(T=0.5 * k, T_end=5.0 * k, t_end=70.0, channels=(0,)),
        "cubic_damping": lambda: fx.Damping(Nrrr=-20000.0 * k),
        "none": lambda: None,
    }[label]()


#: Library family of each truth label (out-of-family truths: the family a right answer names).
FAMILY = {"actuator_lag": "actuator", "input_delay": "actuator", "rate_limit": "actuator",
          "varying_lag": "actuator", "rudder_offset": "bias", "constant_force": "bias", "heading_bias": "sensor",
          "current": "environment", "rotating_current": "environment", "ramped_current": "environment",
          "wave": "environment", "damping_vv": "damping", "damping_vr": "damping", "damping_rr": "damping",
          "cubic_damping": "damping", "none": "none"}

IN_FAMILY = {"usv": ("actuator_lag", "input_delay", "constant_force", "heading_bias", "current", "damping_vv",
                     "damping_vr", "damping_rr"),
             "ship": ("actuator_lag", "input_delay", "rate_limit", "rudder_offset", "damping_rr")}
OUT_OF_FAMILY = {"usv": ("rotating_current", "ramped_current", "varying_lag", "wave", "cubic_damping"),
                 "ship": ("varying_lag", "cubic_damping")}


@dataclasses.dataclass(frozen=True)
class Scenario:
    vessel: str
    label: str
    kind: str  # "in", "out" or "none"
    size: str
    seed: int

    @property
    def family(self) -> str:
        return FAMILY[self.label]

    @property
    def name(self) -> str:
        return f"{self.vessel}-{self.label}-{self.size}-s{self.seed}"

    def effect(self) -> fx.Effect | None:
        k = SIZES[self.size]
        return (_usv_effect if self.vessel == "usv" else _ship_effect)(self.label, k)


def scenarios(vessels=("ship", "usv"), sizes=("weak", "strong"), seeds=(1, 2), nulls: int = 2,
              out_of_family: bool = True) -> list[Scenario]:
    """The grid: every in-family effect × sizes × seeds, ``nulls`` null cases per vessel and seed,
    and the out-of-family effects at the strongest listed size × seeds."""
    out = []
    for v in vessels:
        for s in seeds:
            for lab in IN_FAMILY[v]:
                out += [Scenario(v, lab, "in", z, s) for z in sizes]
            out += [Scenario(v, "none", "none", "strong", 100 * s + i) for i in range(nulls)]
            if out_of_family:
                out += [Scenario(v, lab, "out", sizes[-1], s) for lab in OUT_OF_FAMILY[v]]
    return out


SHIP_ZIGZAGS = [(10, 10, 1), (20, 20, -1), (15, 5, 1), (25, 10, -1), (30, 15, 1), (10, 5, -1)]


def generate(sc: Scenario, dt: float = 0.1) -> dict:
    """Training and validation runs of ``sc``: ``{"train": [...], "val": [...]}``, each run a
    dict with ``name``, ``time``, ``channels`` (measured outputs with noise and biases, and the
    logged inputs), ``clean`` (noise-free measured outputs) and ``params`` (the true effect)."""
    eff = sc.effect()
    effs = [eff] if eff is not None else []
    rng = np.random.default_rng(sc.seed * 7919 + (0 if sc.vessel == "ship" else 1))
    runs = []
    if sc.vessel == "usv":
        vessel = USV()
        t = np.arange(0.0, 40.0, dt)
        for i in range(6):
            sim = simulate(vessel, effs, t, commands=usv_commands(t, rng), u0=2.0)
            runs.append((f"usv{i}", sim))
    else:
        vessel = Ship()
        t = np.arange(0.0, 70.0, dt)
        for i, (a, s, side) in enumerate(SHIP_ZIGZAGS):
            sim = simulate(vessel, effs, t, pilot=Zigzag(a * DEG, s * DEG, side=side * (1 if sc.seed % 2 else -1)))
            runs.append((f"zz{a}_{s}", sim))
    noise = NOISE[sc.vessel]
    out = []
    for name, sim in runs:
        ch = {c: y + rng.normal(0.0, noise[c], size=y.shape) for c, y in sim["clean"].items()}
        for j, n in enumerate(vessel.inputs):
            ch[n] = sim["commands"][:, j].copy()
        out.append({"name": name, "time": sim["time"], "channels": ch, "clean": sim["clean"],
                    "params": eff.params if eff is not None else {}})
    return {"train": out[:4], "val": out[4:]}
