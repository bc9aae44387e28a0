"""Verdicts: the ranking of every candidate with a one-line verdict, and the three-line summary.

Per-candidate verdicts, in order of precedence: *attributed* (selected; later greedy steps
numbered); *confusable with W* (passes the rule and comes within ``confusable_margin`` of the
winner W's validation error — the separating manoeuvre is named); *explains part of the gap*;
*helps on validation but removes less than min_shrink of the structural gap*; *not identifiable*
(absorbed by the base parameters, or no effect on the fitted channels); *rejected on validation
(improves the training fit only)*; *rejected* with the failed parts of the rule; *not refitted*;
*not applicable*; under the gate, *possible effect (low confidence)*. The summary says where (worst channel and phase), which (selected effects with
95 % intervals, confusable and rejected ones) and how far (error before → after, shrink).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

from ..models.effects import FAMILY, POSSIBLE_ONLY, Effect
from .options import DiagnoseOptions
from .screen import ScreenResult
from .where import GapBudget, WhereAnalysis
from .which import Candidate

__all__ = ["RankedEffect", "rank", "verdict_lines", "format_params", "nearest_miss", "in_base", "in_base_line"]

#: The experiment that settles a possible effect under the gap gate.
SETTLE_SMALL_GAP = ("more validation runs, longer or with larger inputs, so that the gap rises above the gate "
                    "(or vanishes)")


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
    runs_improved: str | None = None
    why: str | None = None

    def to_dict(self) -> dict:
        out = {}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if v is not None:
                out[f.name] = list(v) if isinstance(v, tuple) else v
        return out


def _verdict(s: ScreenResult, c: Candidate, e: Effect, selected: Sequence[str], winner: Candidate | None,
             train_cost: float, o: DiagnoseOptions, possible: Sequence[str] = ()) -> str:
    n, j = s.effect, c.judgement
    if n in selected:
        return "attributed" if n == selected[0] else f"attributed (greedy step {selected.index(n) + 1})"
    if n in possible:
        return (f"possible effect (low confidence): the gap is under the gate, but it closes {100 * j.shrink:.0f} % "
                f"of it on {j.runs_improved} validation runs with an interval excluding the null")
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
         note: str = "", possible: Sequence[str] = (),
         not_refitted: dict[str, str] | None = None) -> tuple[RankedEffect, ...]:
    """Every screened candidate with its verdict: selected first, then by validation gain; the
    effects that do not apply last. ``train_cost``: the base fit's cost on the training runs;
    ``confidence``, ``rivals``, ``note``: how sure the first selected effect is
    (:meth:`~.which.Search._confidence`); ``not_refitted``: candidates left out because another
    closed the gap alone, with the reason (:meth:`~.which.Search.refit_singles`)."""
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
            if n in POSSIBLE_ONLY:
                verdict = (f"possible only (a {POSSIBLE_ONLY[n]} changing along the run): checked for the selected "
                           "effect, see time_variation")
            elif s.orthogonal_fraction == 0.0 and s.predicted_fraction == 0.0:
                verdict = "not identifiable from these runs (no effect on the fitted channels)"
            elif n in (not_refitted or {}):
                verdict = not_refitted[n]
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
        elif n in possible:
            conf = (f"low (possible effect under the gap gate): settle with {SETTLE_SMALL_GAP}"
                    + (f", then {e.separating}" if e.separating else ""))
        rows.append(RankedEffect(
            **common, params={k: rf.values[k] for k in e.param_names},
            stderr={k: rf.stderr.get(k, float("nan")) for k in e.param_names},
            validation_gain=float(c.judgement.gain), shrink=float(c.judgement.shrink), validation_E=float(c.score.E),
            train_cost_reduction=1 - rf.train_cost / train_cost,
            verdict=_verdict(s, c, e, selected, winner, train_cost, options, possible), confidence=conf,
            runs_improved=c.judgement.runs_improved or None, why=c.judgement.why or None))
    rows.sort(key=lambda r: (0 if r.effect in selected else 1, 0 if r.effect in possible else 1, -r.validation_gain))
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


def in_base(fit, model) -> dict[str, dict]:
    """Library effects the base model carries as a parameter of its own
    (:meth:`~diffship.models.AbstractModel.effect_twins`), estimated by the base fit or held at a
    given non-zero value (a study's earlier fit): ``{effect: {parameter, value, stderr, unit,
    held, excludes_zero}}`` — a rudder zero error is a Nomoto or MMG model's rudder neutral angle
    ``delta0``, so the base has already taken what the effect's own candidate would find."""
    units = {p.name: p.unit for p in model.spec().params}
    out = {}
    for eff, par in model.effect_twins().items():
        if par not in fit.params:
            continue
        v = float(fit.params[par])
        held = par not in fit.free
        if held and v == 0.0:  # held at zero (e.g. by the diagnosis, whose candidate then stands for it)
            continue
        se = math.nan if held else float(fit.stderr.get(par, math.nan))
        out[eff] = {"parameter": par, "value": v, "stderr": se, "unit": units.get(par, ""), "held": held,
                    "excludes_zero": bool(math.isfinite(se) and abs(v) > 1.96 * se)}
    return out


def in_base_line(twins: dict[str, dict]) -> str | None:
    """The verdict's line for :func:`in_base` (estimated effects whose 95 % interval excludes 0,
    and held non-zero ones), or ``None``."""
    parts = []
    for eff, t in twins.items():
        if not (t["excludes_zero"] or t.get("held")):
            continue
        deg = t["unit"] == "rad"
        k = 180 / math.pi if deg else 1.0
        unit = " °" if deg else (f" {t['unit']}" if t["unit"] else "")
        parts.append(f"{eff} as the base model's own {t['parameter']} = {k * t['value']:.3g}"
                     + (f"{unit} (held at the given value)" if t.get("held") else
                        f" ± {1.96 * k * t['stderr']:.2g}{unit} (estimated in the base fit, 95 % interval excludes 0)"))
    if not parts:
        return None
    return "In the base: " + "; ".join(parts) + "; the effect's own candidate has only what is left."


def nearest_miss(ranking: Sequence[RankedEffect]) -> RankedEffect | None:
    """The refitted candidate with the largest positive validation gain (when nothing passed)."""
    rows = [r for r in ranking if r.validation_E is not None and r.validation_gain > 0]
    return max(rows, key=lambda r: r.validation_gain) if rows else None


def verdict_lines(where: WhereAnalysis, gap: GapBudget, ranking: Sequence[RankedEffect], selected: Sequence[str],
                  E_before: float, E_after: float, shrink: float, gap_gate: float,
                  possible: Sequence[str] = (), min_shrink: float = 0.3,
                  waiting: Sequence[tuple[str, float]] = (), greedy_steps: int | None = None) -> tuple[str, str, str]:
    r"""Where, which, how far — one line each.

    *Which* says what it knows: the selected effects with their confidence, and **partial** when
    a structural gap remains after them (:math:`E_{after} \ge` ``gap_gate``: the same test that
    says a gap exists), with the share closed; with nothing accepted, the **nearest miss** (the
    candidate with the largest validation gain, its shrink and the failed parts of the rule; below
    ``min_shrink`` (:class:`~.options.DiagnoseOptions`) the line says at most a small part of the gap is of its kind);
    under the gate, a **possible** effect (low confidence) with the experiment that settles it.
    When the greedy path stopped at its cap (``greedy_steps``) with the gap left and other effects
    passing at its last step (``waiting``: ``(name, validation gain)``), the partial line names them
    instead of calling the rest unexplained by the library.
    """
    pc = where.per_channel
    worst = max(pc, key=lambda c: pc[c]["share"])
    ph = where.per_phase
    worst_phase = max(ph, key=lambda p: ph[p]["E"]) if ph else "-"
    where_line = (f"Where: validation error {E_before:.2f}× the noise floor "
                  f"({100 * gap.share_struct:.0f} % structural); mostly in {worst} "
                  f"({100 * pc[worst]['share']:.0f} % of the error), worst phase: {worst_phase}.")
    if getattr(where, "in_words", ()):
        # in a naval architect's words: heading, rate and speed first (:mod:`.words`)
        where_line = (f"Where: validation error {E_before:.2f}× the noise floor "
                      f"({100 * gap.share_struct:.0f} % structural, {100 * pc[worst]['share']:.0f} % of it in {worst}): "
                      f"{where.summary}.")
    r = {x.effect: x for x in ranking}
    if E_before < gap_gate:
        which = (f"Which: no structural gap detected (validation error within {100 * (gap_gate - 1):.0f} % of the "
                 "noise floor); no effect attributed.")
        if possible:
            p = r[possible[0]]
            which = (f"Which: no structural gap at the gate (E {E_before:.3f} < {gap_gate:.3g}); possible effect "
                     f"(low confidence): {p.effect} ({format_params(p.params, p.stderr)}; validation E "
                     f"{E_before:.3f} → {p.validation_E:.3f} on {p.runs_improved} runs improved, "
                     f"{100 * p.shrink:.0f} % of the small gap)"
                     + (f", also possible: {', '.join(possible[1:])}" if len(possible) > 1 else "")
                     + f"; not attributed — settle with {SETTLE_SMALL_GAP}"
                     + (f", then {p.separating_manoeuvre}" if p.separating_manoeuvre else "") + ".")
    elif not selected:
        m = nearest_miss(ranking)
        which = "Which: gap unexplained by the library — no candidate passed the validation rule"
        if m is not None:
            which += (f"; nearest miss: {m.effect} ({format_params(m.params, m.stderr)}; validation gain "
                      f"{100 * m.validation_gain:.1f} % on {m.runs_improved} runs improved, shrink {m.shrink:.2f}; "
                      f"failed: {m.why or m.verdict})")
            if m.shrink < min_shrink:
                which += ": at most a small part of the gap is of this kind"
            which += "."
        else:
            which += "; no candidate lowers the validation error."
    else:
        w = selected[0]
        conf = [x.effect for x in ranking if x.verdict.startswith("confusable")]
        rej = [x.effect for x in ranking if x.verdict.startswith("rejected on validation")]
        which = (f"Which: {w} ({format_params(r[w].params, r[w].stderr)}; confidence: {r[w].confidence})"
                 + (" then " + ", ".join(selected[1:]) if len(selected) > 1 else "")
                 + (f"; confusable: {', '.join(conf)}" if conf else "")
                 + (f"; improves training only, rejected on validation: {', '.join(rej)}" if rej else "") + ".")
        if E_after >= gap_gate:
            which += (f" Partial: {'they close' if len(selected) > 1 else 'it closes'} {100 * shrink:.0f} % of the "
                      f"structural gap; E {E_after:.2f} stays above the gate ({gap_gate:.3g}), ")
            if waiting:
                cap = f"its cap of {greedy_steps} effect(s)" if greedy_steps else "its cap"
                which += (f"and the path stopped at {cap} (--greedy-steps) while "
                          + ", ".join(f"{n} ({100 * g:+.1f} % validation gain)" for n, g in waiting)
                          + f" also passed at step {len(selected)}: a further step may attribute "
                          + ("it" if len(waiting) == 1 else "one of them") + " (raise --greedy-steps to test).")
            else:
                which += ("the rest is unexplained (an effect outside the library, or a variant of the selected one, "
                          "e.g. time-varying).")
    how = (f"How far: validation error {E_before:.2f} → {E_after:.2f} × noise floor; "
           f"{100 * shrink:.0f} % of the structural gap removed"
           + (f" ({', '.join(selected)})." if selected else "."))
    return where_line, which, how
