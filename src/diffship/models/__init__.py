"""Models as pure JAX vector fields (one module per model family)."""

from ._base import AbstractModel as AbstractModel, LinearForm as LinearForm, param as param, scalar as scalar
from ._rigid3 import AbstractShip3 as AbstractShip3
from .actuators import (ConstantThrust as ConstantThrust, ForceInput as ForceInput,
                        OpenWaterPropeller as OpenWaterPropeller, ThrustInput as ThrustInput, WaterJet as WaterJet)
from .fossen3 import Fossen3 as Fossen3, USV_STANDARD as USV_STANDARD, usv_standard as usv_standard
from .nomoto import Nomoto1 as Nomoto1, Nomoto2 as Nomoto2
from .mmg import MMG as MMG, kvlcc2_mmg as kvlcc2_mmg
from .vmm import VMMAbkowitz as VMMAbkowitz, VMMLinear as VMMLinear, VMMSimple as VMMSimple
from .fossen6 import Fossen6 as Fossen6
from .decay import Decay1 as Decay1, Decay2 as Decay2
from .registry import MODELS as MODELS, get_model as get_model

__all__ = [
    "AbstractModel", "AbstractShip3", "LinearForm", "param", "scalar", "ConstantThrust", "ForceInput",
    "OpenWaterPropeller", "ThrustInput", "WaterJet", "Fossen3", "USV_STANDARD",
    "usv_standard", "Nomoto1", "Nomoto2", "MMG", "kvlcc2_mmg", "VMMAbkowitz", "VMMLinear", "VMMSimple", "Fossen6",
    "Decay1", "Decay2", "MODELS", "get_model",
]
