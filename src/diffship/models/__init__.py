"""Models as pure JAX vector fields (one module per model family)."""

from collections.abc import Callable

from ._base import AbstractModel as AbstractModel, LinearForm as LinearForm, param as param
from ._rigid3 import AbstractShip3 as AbstractShip3
from .actuators import ForceInput as ForceInput, WaterJet as WaterJet
from .fossen3 import Fossen3 as Fossen3, USV_STANDARD as USV_STANDARD, usv_standard as usv_standard
from .nomoto import Nomoto1 as Nomoto1, Nomoto2 as Nomoto2
from .mmg import MMG as MMG, kvlcc2_mmg as kvlcc2_mmg
from .vmm import VMMAbkowitz as VMMAbkowitz, VMMLinear as VMMLinear, VMMSimple as VMMSimple
from .fossen6 import Fossen6 as Fossen6
from .decay import Decay1 as Decay1, Decay2 as Decay2

#: Models selectable by name (``--model NAME``).
MODELS: dict[str, type[AbstractModel] | Callable[[], AbstractModel]] = {
    "nomoto1": Nomoto1,
    "nomoto2": Nomoto2,
    "fossen3": Fossen3,
    "fossen3_waterjet": lambda: usv_standard(actuator=WaterJet()),
    "mmg": MMG,
    "vmm_linear": VMMLinear,
    "vmm_simple": VMMSimple,
    "vmm_abkowitz": VMMAbkowitz,
    "fossen6": Fossen6,
    "decay1": Decay1,
    "decay2": Decay2,
}


def get_model(name: str) -> AbstractModel:
    """A model instance with its reference (default) parameter values, by name."""
    from ..errors import ModelError

    try:
        return MODELS[name]()
    except KeyError:
        raise ModelError(f"unknown model {name!r}; choose one of: {', '.join(MODELS)}") from None
