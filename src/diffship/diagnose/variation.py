r"""Is the effect changing during the run? A *possible* time variation, never an attribution.

A current that turns with the tide or a steering gear that slows as it warms is fitted by its
constant effect as an average, and the rest stays in the residuals. For the effect the
diagnosis selected first (or, with nothing selected, the nearest miss) that has a varying form
(:data:`~diffship.models.effects.POSSIBLE_ONLY`: ``current`` → ``current_trend``,
``actuator_lag`` → ``lag_trend``), the varying form is refitted from the constant one's
solution (its base values, the constant value at t = 0 and no trend) and scored on the held-out
runs by the same start rule (:mod:`.start`). It is reported as a **possible** time variation when

* a structural gap exists (the base's E is above the gap gate) and is left by the constant
  effect (its E is above the gate too; else the varying form is not refitted: under the gate a
  further drop would have to go beyond the noise band below the noise floor itself),
* the held-out error drops against the constant effect by at least ``min_gain`` and by more
  than the noise band ``max(gate − 1, 2 SE)`` (as in :mod:`.which`), on a majority of the runs,
* a trend parameter's 95 % interval excludes 0.

A linear trend stands for any slow change, and a fit on these runs cannot tell a real change
from another unmodelled effect that grows along the run; so it is never attributed: the report
names the experiment that settles it (the effect's ``separating``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np

from ..errors import FitError
from ..models.effects import POSSIBLE_ONLY
from .verdict import format_params

__all__ = ["TimeVariation", "time_variation", "TREND_PARAMS"]

#: The trend parameters of each varying form, and how its start comes from the constant fit.
TREND_PARAMS = {"current_trend": ("dVcx", "dVcy"), "lag_trend": ("dT_act",)}
_FROM_CONSTANT = {"current_trend": {"Vcx_0": "Vcx", "Vcy_0": "Vcy"}, "lag_trend": {"T_act0": "T_act"}}


@dataclasses.dataclass(frozen=True)
class TimeVariation:
    """The check of one selected (or nearest-miss) effect for a change along the run."""

    effect: str
    varying: str
    params: dict[str, float]
    stderr: dict[str, float]
    E_constant: float
    E_varying: float
    runs_improved: str
    possible: bool
    why: str
    settle: str

    def line(self) -> str:
        return (f"Possible (low confidence, not attributed): the {self.effect} changes during the run "
                f"({format_params(self.params, self.stderr)}; held-out E {self.E_constant:.3g} → {self.E_varying:.3g}, "
                f"{self.runs_improved} runs improved) — settle with {self.settle}.")

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


def time_variation(search, singles: dict, selected: tuple[str, ...], say: Callable[[str], None],
                   varying: dict[str, Callable] | None = None) -> TimeVariation | None:
    """Refit the varying form of the first selected effect (else of the single candidate with the
    largest held-out gain) and judge it against the constant one (module docstring).

    ``varying``: ``{varying form: build() -> (workspace, validation)}``, the workspace of the base
    and that form alone, built only when the form is refitted (:func:`.diagnosis.split_varying`: the
    all-effects workspace does not carry the varying forms). Without it the form is refitted in
    ``search.ws`` when that carries it."""
    name = selected[0] if selected else max(singles, key=lambda n: singles[n].judgement.gain, default=None)
    var = next((v for v, c in POSSIBLE_ONLY.items() if c == name), None)
    if name is None or var is None or name not in singles or not search.has_gap:
        return None
    if varying is not None:
        if var not in varying:
            return None
    elif not any(e.name == var for e in search.ws.effects):
        return None
    const = singles[name]
    if const.score.E < search.gate:
        # the constant effect already leaves no structural gap on the held-out runs: a varying form
        # would need a drop beyond the noise band below the noise floor itself (the greedy path's rule,
        # :meth:`~.which.Search.select`), so it is not refitted
        say(f"  time variation of {name}: not checked — held-out E {const.score.E:.3g} with the constant {name} "
            f"is under the gap gate {search.gate:.3g}, no structural gap left for a change along the run")
        return None
    start = {k: const.refit.values[c] for k, c in _FROM_CONSTANT[var].items()}
    start.update({k: 0.0 for k in TREND_PARAMS[var]})
    ws, validation = varying[var]() if varying is not None else (search.ws, None)
    try:
        rf = ws.refit([var], [start], progress=say, base_start=const.refit.base_values)
    except FitError as exc:
        say(f"  refit {var} failed: {exc}")
        return None
    sc = (validation if validation is not None else search.validation).refit(rf)
    o = search.options
    ref = const.score
    d = np.array([ref.E_runs[k] - sc.E_runs[k] for k in sc.E_runs])
    se = float(np.std(d, ddof=1) / math.sqrt(d.size)) if d.size >= 4 else 0.0
    thr = max(search.gate - 1.0, 2 * se)
    gain = (ref.E - sc.E) / ref.E if ref.E > 0 else 0.0
    majority = bool(np.sum(d > 0) > d.size / 2)
    trend = any(abs(rf.values[p]) > 1.96 * rf.stderr.get(p, math.inf) for p in TREND_PARAMS[var])
    ok = rf.ok and gain >= o.min_gain and (ref.E - sc.E) > thr and majority and trend
    why = []
    if not (gain >= o.min_gain and (ref.E - sc.E) > thr):
        why.append(f"held-out gain over the constant {name} {100 * gain:.1f} % (ΔE {ref.E - sc.E:.3g}) below the "
                   f"threshold ({100 * o.min_gain:.0f} % and ΔE > {thr:.2g})")
    elif not majority:
        why.append("improves fewer than half of the held-out runs")
    if not trend:
        why.append("the trend's 95 % interval includes 0")
    eff = next(e for e in ws.effects if e.name == var)
    tv = TimeVariation(name, var, dict(rf.values), dict(rf.stderr), float(ref.E), float(sc.E),
                       f"{int(np.sum(d > 0))}/{d.size}", bool(ok), "; ".join(why), eff.separating)
    say(f"  time variation of {name}: held-out E {ref.E:.3g} → {sc.E:.3g}"
        + (" — possible" if ok else f" — no: {tv.why}"))
    return tv
