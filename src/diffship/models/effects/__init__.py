"""Candidate unmodelled effects as composable model augmentations, one family per module.

* :mod:`._base` — the :class:`Effect` base and its null-value contract;
* :mod:`.augmented` — :class:`Augmented`, a base model with effects, itself a model;
* :mod:`.current`, :mod:`.sensor`, :mod:`.actuator`, :mod:`.damping`, :mod:`.wind`, :mod:`.wave` — the
  effects by family;
* :mod:`.registry` — names, families, applicability and factories (the library table).

Importing this package loads models, params and errors only (not fit, metrics or the rest of
:mod:`diffship.diagnose`).
"""

from ._base import DataFacts as DataFacts
from ._base import Effect as Effect
from ._base import is_ship3 as is_ship3
from ._base import parts as parts
from ._base import steering_inputs as steering_inputs
from .actuator import ActuatorLag as ActuatorLag
from .actuator import InputDelay as InputDelay
from .actuator import RateLimit as RateLimit
from .actuator import ConstantForce as ConstantForce
from .actuator import NomotoRudderOffset as NomotoRudderOffset
from .augmented import Augmented as Augmented
from .current import Current as Current
from .damping import DampingRR as DampingRR
from .damping import DampingRV as DampingRV
from .damping import DampingVR as DampingVR
from .damping import DampingVV as DampingVV
from .damping import NorrbinRR as NorrbinRR
from .damping import SpeedDependence as SpeedDependence
from .registry import EFFECT_NAMES as EFFECT_NAMES
from .registry import EFFECTS as EFFECTS
from .registry import FAMILY as FAMILY
from .registry import POSSIBLE_ONLY as POSSIBLE_ONLY
from .registry import applicability as applicability
from .registry import augment as augment
from .registry import library as library
from .registry import make_effect as make_effect
from .sensor import HeadingBias as HeadingBias
from .current import CurrentTrend as CurrentTrend
from .actuator import LagTrend as LagTrend
from .wind import Wind as Wind
from .wave import Wave as Wave
from .wave import NomotoWave as NomotoWave

__all__ = [
    "Effect", "DataFacts", "Augmented", "EFFECTS", "EFFECT_NAMES", "FAMILY", "POSSIBLE_ONLY", "applicability", "make_effect",
    "library", "augment", "is_ship3", "parts", "steering_inputs",
    "Current", "HeadingBias", "InputDelay", "ActuatorLag", "RateLimit", "ConstantForce", "NomotoRudderOffset",
    "DampingVV", "DampingRR", "DampingVR", "DampingRV", "SpeedDependence", "NorrbinRR", "Wind",
    "CurrentTrend", "LagTrend", "Wave", "NomotoWave",
]
