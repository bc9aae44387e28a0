"""Structure discovery (issue 29): the terms a vessel's equations need beyond its base model.

``discover(base, train, validate)`` (or ``python -m diffship.discover``): a fast equation-error screen of
a term library (:mod:`diffship.models.terms`, :mod:`.screen`), an output-error refit of every candidate
structure through the one driver, ranking by information criteria on output residuals (:mod:`.rank`),
confirmation on held-out runs (:mod:`.discovery`); text, JSON and figure in :mod:`.report`.
"""

from .discovery import Candidate as Candidate, Discovery as Discovery, discover as discover
from .screen import Screen as Screen, screen as screen

__all__ = ["discover", "Discovery", "Candidate", "Screen", "screen"]
