"""Gap diagnosis: where a fitted model misses, which unmodelled effect explains it, how much.

``diagnose(model, train, val)`` (or ``python -m diffship.diagnose``) runs, in order:

1. the base fit by output error on ``train`` (unless given) — :mod:`.diagnosis`;
2. **where** — error split per channel, phase, region and run, residual tests, force residuals,
   gap budget — :mod:`.where`;
3. **which** — score-test screen of the effect library (:mod:`.effects`, :mod:`.screen`),
   refits of the best candidates, selection on held-out runs only, greedy path with pairs and
   swaps — :mod:`.which`;
4. **how far** — validation error before/after and the shrink of the structural gap —
   :mod:`.shrink`; verdicts and the ranking — :mod:`.verdict`; text, figures, JSON —
   :mod:`.report`.

Names are loaded on first use, so that ``import diffship.diagnose.effects`` does not load the
fitter.
"""

from importlib import import_module
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .diagnosis import Diagnosis as Diagnosis
    from .diagnosis import diagnose as diagnose
    from .effects import EFFECT_NAMES as EFFECT_NAMES
    from .effects import FAMILY as FAMILY
    from .effects import Augmented as Augmented
    from .effects import augment as augment
    from .effects import library as library
    from .effects import make_effect as make_effect
    from .options import DiagnoseOptions as DiagnoseOptions

__all__ = ["diagnose", "Diagnosis", "DiagnoseOptions", "Augmented", "augment", "make_effect", "library",
           "EFFECT_NAMES", "FAMILY"]

_SOURCE = {"diagnose": ".diagnosis", "Diagnosis": ".diagnosis", "DiagnoseOptions": ".options",
           "Augmented": ".effects", "augment": ".effects", "make_effect": ".effects", "library": ".effects",
           "EFFECT_NAMES": ".effects", "FAMILY": ".effects"}


def __getattr__(name: str):
    if name in _SOURCE:
        return getattr(import_module(_SOURCE[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
