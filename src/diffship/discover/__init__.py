"""Structure discovery: the terms a vessel's equations need beyond its base model.

``discover(base, train, validate)`` (or ``python -m diffship.discover``): two screens of a term library
(:mod:`diffship.models.terms`) — greedy forward selection on the output-error Jacobian at the base fit
(:mod:`.oescreen`) and on equation error (:mod:`.screen`) —, an output-error refit of every proposed
structure through the one driver, ranking by information criteria on output residuals with bootstrap
inclusion probabilities (:mod:`.rank`), selection with a margin, inclusion ≥ 0.5 and held-out confirmation
(:mod:`.discovery`), equivalent explanations named with the manoeuvre that would separate them
(:mod:`.separate`); text, JSON and figure in :mod:`.report`.
"""

from .discovery import Candidate as Candidate, Discovery as Discovery, discover as discover
from .oescreen import OEScreen as OEScreen, oe_screen as oe_screen
from .screen import Screen as Screen, screen as screen
from .separate import Separation as Separation, separating_manoeuvre as separating_manoeuvre

__all__ = ["discover", "Discovery", "Candidate", "Screen", "screen", "OEScreen", "oe_screen", "Separation",
           "separating_manoeuvre"]
