"""Models selectable by name (``--model NAME``), with their reference (default) parameter values."""

from __future__ import annotations

from collections.abc import Callable

from ..errors import ModelError
from ._base import AbstractModel
from .actuators import WaterJet
from .decay import Decay1, Decay2
from .fossen3 import Fossen3, usv_standard
from .fossen6 import Fossen6
from .mmg import MMG
from .nomoto import Nomoto1, Nomoto2
from .vmm import VMMAbkowitz, VMMLinear, VMMSimple

__all__ = ["MODELS", "get_model"]

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
    try:
        return MODELS[name]()
    except KeyError:
        raise ModelError(f"unknown model {name!r}; choose one of: {', '.join(MODELS)}") from None
