"""The effect library: names, families, which effects apply to a base model, and factories.

Library (names as on the command line, in the order a diagnosis lists them):

=================  ===============================  ==============================================
name               parameters (null = 0)            model
=================  ===============================  ==============================================
current            Vcx, Vcy [m/s] (NED)             hydrodynamics see the velocity through the water
                                                    ν_g − Rᵀv_c; states and GNSS are over ground
input_delay        tau_d [s]                        steering inputs delayed by tau_d, realised with
                                                    a 2nd-order Padé approximant (2 states/input)
actuator_lag       T_act [s]                        first-order lag of the steering inputs
rate_limit         T_slew [s]                       steering slew rate limited to A_i/T_slew
                                                    (A_i = largest |input| in the training data)
rudder_offset      delta_off [rad] (Nomoto)         rudder angle offset δ + δ_off (the base's own
                                                    delta0 held at 0 in the diagnosis' base fit); on
                                                    MMG the base's own delta0
constant_force     Y0 [N], N0 [N m]                 constant sway force and yaw moment fixed to the
                                                    hull (prop walk, jet/thruster misalignment);
                                                    3-DOF models
heading_bias       b_psi [rad]                      compass reads ψ + b; shows only in positions
damping_vv         Nvv                              N_|v|v |v|v   (3-DOF; Y_|v|v is in fossen3)
damping_rr         Yrr  (Norrbin c_rr for Nomoto)   Y_|r|r |r|r   (N_|r|r is in fossen3)
damping_vr         Yvr, Nvr                         (Y, N)_|v|r |v| r
damping_rv         Yrv, Nrv                         (Y, N)_|r|v |r| v
speed_dependence   k_U [-]                          linear damping scaled by 1 + k_U (U − U0)/U0
wind               Cwx, Cwy, Cwn [N/(m/s)², ·m]     ½ρA C(γ) V_rw² from measured wind_speed,
                                                    wind_dir (direction the wind comes from)
current_trend      Vcx_0, Vcy_0 [m/s], dVcx, dVcy   a current changing linearly along the run
                   [m/s²]                           (possible only: :data:`POSSIBLE_ONLY`)
lag_trend          T_act0 [s], dT_act [s/s]         an actuator lag changing along the run
                                                    (possible only)
wave               A_Yc, A_Ys [N], A_Nc, A_Ns       sway force and yaw moment at encounter period
                   [N m], T_w [s] (start: given)    T_w (cos/sin amplitudes; Nomoto: a rudder-
                   a_c, a_s [rad] (Nomoto)          equivalent δ + a_c cos + a_s sin); a candidate
                                                    only with a start period (``starts``)
=================  ===============================  ==============================================

Each name maps to its implementations (:data:`EFFECTS`); the first whose
:meth:`~._base.Effect.applicability` accepts the base model is used (``damping_rr`` is a sway
force on 3-DOF models and Norrbin's term on Nomoto models). A new effect is one class in its
family's module plus one entry here.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import equinox as eqx
import jax.numpy as jnp

from ...errors import ModelError
from .._base import AbstractModel
from ._base import DataFacts, Effect
from .actuator import ActuatorLag, ConstantForce, InputDelay, LagTrend, NomotoRudderOffset, RateLimit
from .augmented import Augmented
from .current import Current, CurrentTrend
from .damping import DampingRR, DampingRV, DampingVR, DampingVV, NorrbinRR, SpeedDependence
from .sensor import HeadingBias
from .wave import NomotoWave, Wave
from .wind import Wind

__all__ = ["EFFECTS", "EFFECT_NAMES", "POSSIBLE_ONLY", "FAMILY", "applicability", "make_effect", "library", "augment"]

#: Implementations per effect name, in the library's order (first applicable wins).
EFFECTS: dict[str, tuple[type[Effect], ...]] = {
    "current": (Current,),
    "input_delay": (InputDelay,),
    "actuator_lag": (ActuatorLag,),
    "rate_limit": (RateLimit,),
    "rudder_offset": (NomotoRudderOffset,),
    "constant_force": (ConstantForce,),
    "heading_bias": (HeadingBias,),
    "damping_vv": (DampingVV,),
    "damping_rr": (DampingRR, NorrbinRR),
    "damping_vr": (DampingVR,),
    "damping_rv": (DampingRV,),
    "speed_dependence": (SpeedDependence,),
    "wind": (Wind,),
    "current_trend": (CurrentTrend,),
    "lag_trend": (LagTrend,),
    "wave": (Wave, NomotoWave),
}

#: Effects that are only ever *possible* (never attributed), with the constant effect they vary:
#: a trend stands for any slow change, and whether the change is real is settled by an experiment.
POSSIBLE_ONLY: dict[str, str] = {"current_trend": "current", "lag_trend": "actuator_lag"}

#: Effect names accepted by ``--effects``.
EFFECT_NAMES: tuple[str, ...] = tuple(EFFECTS)

#: Effect family, for "right family" scoring of out-of-family truths.
FAMILY: dict[str, str] = {n: classes[0].family for n, classes in EFFECTS.items()}


def _implementation(base: AbstractModel, name: str, runs=None) -> tuple[type[Effect] | None, str]:
    """The class implementing ``name`` for ``base``, or ``(None, reason)``."""
    if name not in EFFECTS:
        raise ModelError(f"unknown effect {name!r}; choose from: {', '.join(EFFECT_NAMES)}")
    why = ""
    for cls in EFFECTS[name]:
        why = cls.applicability(base, runs)
        if not why:
            return cls, ""
    return None, why


def applicability(base: AbstractModel, name: str, runs=None) -> str:
    """Empty string if ``name`` applies to ``base`` (and the data), else the reason it does not."""
    return _implementation(base, name, runs)[1]


def make_effect(base: AbstractModel, name: str, runs=None, **values: float) -> Effect:
    """One effect configured for ``base`` (steering inputs, amplitudes, U0 from ``runs``), at its
    null value or at ``values``."""
    cls, why = _implementation(base, name)
    if cls is None:
        raise ModelError(f"effect {name} does not apply: {why}")
    eff = cls.for_data(base, DataFacts.from_runs(base, runs))
    if values:
        unknown = set(values) - set(eff.param_names)
        if unknown:
            raise ModelError(f"effect {name}: unknown parameter(s) {sorted(unknown)}; it has {eff.param_names}")
        eff = eqx.tree_at(lambda m: tuple(getattr(m, n) for n in values), eff,
                          tuple(jnp.asarray(float(v), dtype=jnp.float64) for v in values.values()))
    return eff


def library(base: AbstractModel, runs=None, names: Sequence[str] | str = "all",
            starts: Mapping[str, Mapping[str, float]] | None = None) -> tuple[list[Effect], dict[str, str]]:
    """Effects applicable to ``base`` and ``runs``, and ``{name: reason}`` for those skipped.

    ``starts``: ``{effect name: {parameter: value}}`` found in the data, the values the effect is
    built with (and its null for that parameter, e.g. the wave's period ``T_w`` from a periodic
    residual). An effect whose class declares ``needs_start`` is skipped without one."""
    if names == "all":
        names = EFFECT_NAMES
    starts = starts or {}
    out, skipped = [], {}
    for n in names:
        why = applicability(base, n, runs)
        need = getattr(_implementation(base, n, runs)[0], "needs_start", "") if not why else ""
        if not why and need and need not in starts.get(n, {}):
            why = (f"no start for its parameter {need} from the data (for the wave: no periodic residual "
                   "that the steering does not drive in the base fit's training residuals)")
        if why:
            skipped[n] = why
        else:
            out.append(make_effect(base, n, runs, **dict(starts.get(n, {}))))
    return out, skipped


def augment(base: AbstractModel, *effects: Effect | str, runs=None, **values: float) -> Augmented:
    """``Augmented(base, effects)``; effects may be given by name (configured from ``runs``)."""
    effs = [make_effect(base, e, runs) if isinstance(e, str) else e for e in effects]
    m = Augmented(base, effs)
    return m.with_params(values) if values else m
