"""Verdicts: the ranking of every candidate with a one-line verdict, and the three-line summary.

Per-candidate verdicts, in order of precedence: *attributed* (selected; later greedy steps
numbered); *confusable with W* (passes the rule and comes within ``confusable_margin`` of the
winner W's validation error — the separating manoeuvre is named); *explains part of the gap*;
*helps on validation but removes less than min_shrink of the structural gap*; *not identifiable*
(absorbed by the base parameters, or no effect on the fitted channels); *rejected on validation
(improves the training fit only)*; *rejected* with the failed parts of the rule; *not refitted*;
*not applicable*. The summary says where (worst channel and phase), which (selected effects with
95 % intervals, confusable and rejected ones) and how far (error before → after, shrink).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

from ..models.effects import FAMILY, Effect
from .options import DiagnoseOptions
from .screen import ScreenResult
from .where import GapBudget, WhereAnalysis
from .which import Candidate

__all__ = ["RankedEffect", "rank", "verdict_lines", "format_params"]


@dataclasses.dataclass(frozen=True, kw_only=True)
class RankedEffect:
    """One row of the ranking (``to_dict()`` leaves out the parts that were not computed: no
    refit → no validation_E / train_cost_reduction; not applicable → no screen numbers)."""

    effect: str
    family: str
    params: dict[str, float]
    stderr: dict[str, float] | None = None
    validation_gain: float = 0.0
    shrink: float = 0.0
    validation_E: float | None = None
    train_cost_reduction: float | None = None
    screen_fraction: float | None = None
    orthogonal_fraction: float | None = None
    p_value: float | None = None
    verdict: str
    confidence: str | None = None
    confusable_with: tuple[str, ...] | None = None
    separating_manoeuvre: str | None = None

    def to_dict(self) -> dict:
        out = {}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if v is not None:
                out[f.name] = list(v) if isinstance(v, tuple) else v
        return out


def _verdict(s: ScreenResult, c: Candidate, e: Effect, selected: Sequence[str], winner: Candidate | None,
             train_cost: float, o: DiagnoseOptions) -> str:
    n, j = s.effect, c.judgement
    if n in selected:
        return "attributed" if n == selected[0] else f"attributed (greedy step {selected.index(n) + 1})"
    if j.ok and winner and c.score.E <= winner.score.E * (1 + o.confusable_margin) + 1e-12:
        return f"confusable with {selected[0]}: separate with {e.separating}"
    if j.ok and winner:
        return "explains part of the gap, but less than the selected effect(s)"
    if j.ok:
        return (f"helps on validation ({100 * j.gain:.0f} %) but removes only {j.shrink:.2f} of the "
                f"structural gap (< {o.min_shrink}): a partial explanation, not attributed")
    if s.orthogonal_fraction < 1e-3 and abs(j.gain) < o.min_gain:
        return "not identifiable from these runs (absorbed by the base parameters)"
    if j.gain < 0 and c.refit.train_cost < train_cost * 0.95:
        return "rejected on validation (improves the training fit only)"
    return "rejected: " + (j.why or "no validation gain")


def rank(screen: Sequence[ScreenResult], singles: dict[str, Candidate], effects: Sequence[Effect],
         selected: Sequence[str], train_cost: float, skipped: dict[str, str],
         options: DiagnoseOptions, confidence: str = "", rivals: Sequence[str] = (),
         note: str = "") -> tuple[RankedEffect, ...]:
    """Every screened candidate with its verdict: selected first, then by validation gain; the
    effects that do not apply last. ``train_cost``: the base fit's cost on the training runs;
    ``confidence``, ``rivals``, ``note``: how sure the first selected effect is
    (:meth:`~.which.Search._confidence`)."""
    by_name = {e.name: e for e in effects}
    winner = singles[selected[0]] if selected else None
    rows = []
    for s in screen:
        n, e = s.effect, by_name[s.effect]
        common = {"effect": n, "family": FAMILY[n], "screen_fraction": s.predicted_fraction,
                  "orthogonal_fraction": s.orthogonal_fraction, "p_value": s.p_value,
                  "confusable_with": tuple(e.confusable_with), "separating_manoeuvre": e.separating}
        c = singles.get(n)
        if c is None:
            if s.orthogonal_fraction == 0.0 and s.predicted_fraction == 0.0:
                verdict = "not identifiable from these runs (no effect on the fitted channels)"
            else:
                verdict = "not refitted (screen negligible)"
            rows.append(RankedEffect(**common, params={}, stderr={}, verdict=verdict))
            continue
        rf = c.refit
        conf = None
        if selected and n == selected[0]:
            conf = confidence or "medium"
            if rivals:
                conf = f"tie with {', '.join(rivals)} ({note}): separate with {e.separating}"
            elif note:
                conf = f"{conf} ({note})"
        elif n in rivals:
            conf = f"tie with {selected[0]}: separate with {e.separating}"
        rows.append(RankedEffect(
            **common, params={k: rf.values[k] for k in e.param_names},
            stderr={k: rf.stderr.get(k, float("nan")) for k in e.param_names},
            validation_gain=float(c.judgement.gain), shrink=float(c.judgement.shrink), validation_E=float(c.score.E),
            train_cost_reduction=1 - rf.train_cost / train_cost,
            verdict=_verdict(s, c, e, selected, winner, train_cost, options), confidence=conf))
    rows.sort(key=lambda r: (0 if r.effect in selected else 1, -r.validation_gain))
    rows += [RankedEffect(effect=n, family=FAMILY[n], params={}, verdict=f"not applicable: {why}")
             for n, why in skipped.items()]
    return tuple(rows)


def format_params(p: dict, se: dict | None = None) -> str:
    """``name = value ± 95 % half-width`` for each parameter."""
    out = []
    for k, v in p.items():
        s = (se or {}).get(k)
        out.append(f"{k} = {v:.4g}" + (f" ± {1.96 * s:.2g}" if s is not None and math.isfinite(s) else ""))
    return ", ".join(out)


def verdict_lines(where: WhereAnalysis, gap: GapBudget, ranking: Sequence[RankedEffect], selected: Sequence[str],
                  E_before: float, E_after: float, shrink: float, gap_gate: float) -> tuple[str, str, str]:
    """Where, which, how far — one line each."""
    pc = where.per_channel
    worst = max(pc, key=lambda c: pc[c]["share"])
    ph = where.per_phase
    worst_phase = max(ph, key=lambda p: ph[p]["E"]) if ph else "-"
    where_line = (f"Where: validation error {E_before:.2f}× the noise floor "
                  f"({100 * gap.share_struct:.0f} % structural); mostly in {worst} "
                  f"({100 * pc[worst]['share']:.0f} % of the error), worst phase: {worst_phase}.")
    if E_before < gap_gate:
        which = (f"Which: no structural gap detected (validation error within {100 * (gap_gate - 1):.0f} % of the "
                 "noise floor); no effect attributed.")
    elif not selected:
        which = ("Which: gap unexplained by the library — no candidate passed the validation rule "
                 "(see the ranking for near misses and effects not identifiable from these runs).")
    else:
        r = {x.effect: x for x in ranking}
        w = selected[0]
        conf = [x.effect for x in ranking if x.verdict.startswith("confusable")]
        rej = [x.effect for x in ranking if x.verdict.startswith("rejected on validation")]
        which = (f"Which: {w} ({format_params(r[w].params, r[w].stderr)}; confidence: {r[w].confidence})"
                 + (" then " + ", ".join(selected[1:]) if len(selected) > 1 else "")
                 + (f"; confusable: {', '.join(conf)}" if conf else "")
                 + (f"; improves training only, rejected on validation: {', '.join(rej)}" if rej else "") + ".")
    how = (f"How far: validation error {E_before:.2f} → {E_after:.2f} × noise floor; "
           f"{100 * shrink:.0f} % of the structural gap removed"
           + (f" ({', '.join(selected)})." if selected else "."))
    return where_line, which, how

