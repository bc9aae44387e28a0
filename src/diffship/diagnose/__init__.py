"""Gap diagnosis: where a fitted model misses, which unmodelled effect explains it, how much.

``diagnose(model, train, val)`` (or ``python -m diffship.diagnose``) runs, in order:

1. the base fit by output error on ``train`` (unless given) — :mod:`.diagnosis`;
2. **where** — error split per channel, phase, region and run, residual tests, force residuals,
   gap budget — :mod:`.where`;
3. **which** — score-test screen of the effect library (:mod:`diffship.models.effects`,
   :mod:`.screen`), refits of the best candidates, selection on held-out runs only, greedy path
   with pairs and swaps — :mod:`.which`;
4. **how far** — validation error before/after and the shrink of the structural gap —
   :mod:`.shrink`; verdicts and the ranking — :mod:`.verdict`; text, figures, JSON —
   :mod:`.report`.

The effects themselves are physics (model augmentations with a null value) and live in
:mod:`diffship.models.effects`; they are re-exported here for convenience.
"""

from ..models.effects import (
    EFFECT_NAMES as EFFECT_NAMES,
    FAMILY as FAMILY,
    Augmented as Augmented,
    augment as augment,
    library as library,
    make_effect as make_effect,
)
from .diagnosis import Diagnosis as Diagnosis, diagnose as diagnose
from .options import DiagnoseOptions as DiagnoseOptions

__all__ = ["diagnose", "Diagnosis", "DiagnoseOptions", "Augmented", "augment", "make_effect", "library",
           "EFFECT_NAMES", "FAMILY"]
