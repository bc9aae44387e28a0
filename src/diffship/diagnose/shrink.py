r"""How far the gap shrinks: candidate models scored on the held-out runs, and the greedy path.

Every compared model (the base, each refit, each pair or greedy step) is simulated on the
validation runs from the start the same rule gives every model (:mod:`.start`: logged states
move only within a few noise floors of the log), and scored by the noise-normalised error

.. math::
    E = \sqrt{\mathrm{mean}_c (\mathrm{RMSE}_c/\sigma_c)^2}

(:func:`~.where.normalised_error`, σ_c the noise floor, so E = 1 at the noise floor), overall
and per run. Noise and structural error are independent, so they add in quadrature,
:math:`E^2 = 1 + S^2`, and the **structural gap** of a model is :math:`S(E) = \sqrt{\max(E^2 - 1, 0)}`
(the RMS error above the noise floor, in noise units). The **shrink** of a step from
:math:`E_{from}` to :math:`E_{to}` is the share of the base model's structural gap it closes,

.. math::
    \mathrm{shrink} = (S(E_{from}) - S(E_{to})) / S(E_0) \quad (0 \text{ when } E_0 \le 1),

so steps add up and a model at the noise floor has shrink 1. (A linear form
:math:`(E_0 - E)/(E_0 - 1)` over-states it: from E₀ = 1.5 to E = 1.1 it reads 0.80 while
only 59 % of the structural RMS error is gone.) The shrink of the total error is
:math:`(E_0 - E)/E_0`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from ..data import Run
from ..metrics import Evaluation, evaluate
from ..models import AbstractModel
from .screen import RefitResult, Workspace
from .start import StartInfo, StartRule, held_out_starts
from .where import normalised_error

__all__ = ["Score", "Validation", "PathStep", "structural_gap", "structural_shrink", "rmse_per_channel"]


def structural_gap(E: float) -> float:
    """S(E) = √max(E² − 1, 0): the RMS error above the noise floor (noise units)."""
    return float(np.sqrt(max(E * E - 1.0, 0.0)))


def structural_shrink(E0: float, E_from: float, E_to: float) -> float:
    """Share of the base model's structural gap S(E0) closed going from ``E_from`` to ``E_to``."""
    return float((structural_gap(E_from) - structural_gap(E_to)) / structural_gap(E0)) if E0 > 1 else 0.0


def rmse_per_channel(ev: Evaluation, channels: Sequence[str]) -> dict[str, float]:
    return {c: float(ev.rmse[c]) for c in channels if c in ev.rmse}


@dataclasses.dataclass(frozen=True, eq=False)
class Score:
    """A model simulated on the validation runs: its evaluation, E overall and per run."""

    model: AbstractModel
    evaluation: Evaluation
    E: float
    E_runs: dict[str, float]
    start: StartInfo | None = None


class Validation:
    """The held-out runs, their noise floor and channels; scores the workspace's models."""

    def __init__(self, ws: Workspace, runs: Sequence[Run], floor: dict[str, float], channels: Sequence[str],
                 start: StartRule = StartRule()):
        self.ws = ws
        self.start = start
        self.runs = tuple(runs)
        self.floor = floor
        self.channels = tuple(channels)
        self.data = ws.data(self.runs)

    def _score(self, model: AbstractModel, x0, start: StartInfo) -> Score:
        ev = evaluate(model, self.runs, x0=x0, integrator=self.ws.integrator)
        return Score(model, ev, normalised_error(ev, self.floor, self.channels),
                     {r.name: normalised_error(ev, self.floor, self.channels, r.name) for r in self.runs}, start)

    def starts(self, values: dict[str, float], base_values: dict[str, float] | None):
        """Initial states of the held-out runs by the start rule (:mod:`.start`)."""
        return held_out_starts(self.ws, self.data, values, base_values, self.floor, self.start,
                               [r.name for r in self.runs])

    def base(self) -> Score:
        """The base model (no effects)."""
        nb = len(self.ws.base.state_names)
        x0, info = self.starts({}, None)
        return self._score(self.ws.base, [x[:nb] for x in x0], info)

    def refit(self, rf: RefitResult) -> Score:
        """The workspace model at a refit's effect and base values."""
        x0, info = self.starts(rf.values, rf.base_values)
        return self._score(self.ws.model_with(rf.values, rf.base_values), x0, info)


@dataclasses.dataclass(frozen=True)
class PathStep:
    """One step of the greedy path (``effect`` may be ``a+b`` for a joint pair or a swap)."""

    effect: str
    E_before: float
    E_after: float
    shrink_of_structural_gap: float
    rmse_before: dict[str, float]
    rmse_after: dict[str, float]
    params: dict[str, float]
    stderr: dict[str, float]
    note: str | None = None

    @classmethod
    def between(cls, effect: str, before: Score, after: Score, E0: float, rf: RefitResult, channels: Sequence[str],
                note: str | None = None) -> PathStep:
        return cls(effect=effect, E_before=float(before.E), E_after=float(after.E),
                   shrink_of_structural_gap=structural_shrink(E0, before.E, after.E),
                   rmse_before=rmse_per_channel(before.evaluation, channels),
                   rmse_after=rmse_per_channel(after.evaluation, channels),
                   params=dict(rf.values), stderr=dict(rf.stderr), note=note)

    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        if self.note is None:
            del d["note"]
        return d
