"""Text, JSON and figure of a :class:`~.discovery.Discovery`.

JSON (``"schema": "diffship.discover/1"``): ``selected`` has the layout of one method of
``python -m diffship.fit``'s JSON — ``params``, ``stderr``, ``train`` and ``validation`` metrics
(``validation.per_run.<run>.rmse.<channel>``, SI, rad, as ``methods.output_error.validation.per_run``) —
plus ``terms`` (value, standard error, inclusion probability of the output-error ranking bootstrap, the
screen's inclusion, readable form), ``confirmed``, ``possible`` (terms not selected: inclusion probability
and readable form), ``not_selected`` (why better-ranked structures were passed over), ``tradeoffs``,
``equivalent`` (structures within the criterion's margin: terms, criterion difference, held-out RMSE) and
``separating_manoeuvre``; ``usable`` and ``verdict`` (:mod:`diffship.usability`, as in the fit's JSON) where the
command gives the verdicts;
``base`` the same for the base model; ``candidates`` the ranked table (with each structure's bootstrap
win frequency and whether it is the selected one); ``screen`` the equation-error screen; ``oe_screen``
the output-error screen's forward path (score statistics, linearised values); ``polish`` the polish of the
best-ranked structure (its start, the structure it ends at, each move taken with its criterion, refits, seconds).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

from ..data import CHANNEL_UNITS
from ..models.terms import term_label
from ..report import plot_fit
from .discovery import MARGIN, Candidate, Discovery

__all__ = ["discovery_json", "discovery_text", "plot_discovery"]


def _metrics(ev) -> dict:
    if ev is None:
        return {"rmse": {}, "fit_percent": {}, "per_run": {}}
    return {"rmse": dict(ev.rmse), "fit_percent": dict(ev.fit_percent), "ok": ev.ok,
            "per_run": {k: {"rmse": v["rmse"], "fit_percent": v["fit_percent"], "ok": v["ok"]} for k, v in ev.per_run.items()}}


def _method(c: Candidate, d: Discovery, v=None) -> dict:
    r = c.result
    said = {"usable": v.usable, "verdict": v.as_json()} if v is not None else {}
    return {**said,
            "terms": {t: {"value": r.params[t], "stderr": r.stderr.get(t, math.nan),
                          "inclusion_probability": d.inclusion.get(t, math.nan),
                          "screen_inclusion": d.screen.inclusion.get(t, math.nan), "label": term_label(t)}
                      for t in c.terms},
            "params": dict(r.params), "stderr": dict(r.stderr), "free": list(r.free), "status": r.status,
            "converged": bool(r.converged), "criteria": dict(c.criteria), "n_params": c.n_params,
            "held_out_relative_rmse": c.held_out, "train": _metrics(c.train), "validation": _metrics(c.validation)}


def discovery_json(d: Discovery, model_name: str, verdicts=None) -> dict:
    """The ``--json`` document (module docstring); ``verdicts``: ``{"selected": Verdict, "base": Verdict}``
    (:func:`diffship.usability.verdict`) where known."""
    verdicts = verdicts or {}
    sel = {**_method(d.selected, d, verdicts.get("selected")), "confirmed": d.confirmed,
           "possible": {t: {"inclusion_probability": d.inclusion.get(t, 0.0),
                            "screen_inclusion": d.screen.inclusion.get(t, math.nan), "label": term_label(t)}
                        for t in d.possible},
           "not_selected": dict(d.reasons),
           "tradeoffs": [{"a": a, "b": b, "correlation": c} for a, b, c in d.tradeoffs],
           "equivalent": [{"terms": list(c.terms), "delta_" + d.criterion: c.criteria[d.criterion]
                           - d.selected.criteria[d.criterion], "held_out_relative_rmse": c.held_out}
                          for c in d.equivalent],
           "separating_manoeuvre": None if d.separation is None else d.separation.to_dict()}
    table = [{"rank": i + 1, "terms": list(c.terms), "n_params": c.n_params, "aic": c.criteria["aic"],
              "bic": c.criteria["bic"], "held_out_relative_rmse": c.held_out, "bootstrap_wins": c.wins,
              "selected": i == d.chosen, "status": c.result.status}
             for i, c in enumerate(d.candidates)]
    sc = d.screen
    return {"schema": "diffship.discover/1", "model": model_name, "criterion": d.criterion,
            "effective_samples": d.n_eff, "seconds": d.seconds, "ranking_bootstrap": d.n_boot, "selected": sel,
            "base": _method(d.base, d, verdicts.get("base")),
            "candidates": table,
            "screen": {"library": list(sc.terms), "inclusion": sc.inclusion, "coefficients": sc.coefficients,
                       "forward_path": [list(v) for v in sc.path.values()], "min_gain": sc.threshold,
                       "n_boot": sc.n_boot, "block_s": sc.block_s},
            "oe_screen": None if d.oe_screen is None else {
                "path": list(d.oe_screen.path), "statistic": list(d.oe_screen.statistic),
                "supported": list(d.oe_screen.supported), "linearised_values": d.oe_screen.values,
                "cost_fraction": list(d.oe_screen.fraction), "inflation": d.oe_screen.inflation,
                "seconds": d.oe_screen.seconds},
            "polish": None if d.polish is None else {
                "start": list(d.polish.start), "selected": list(d.polish.selected),
                "moves": [{"kind": k, "move": w, "structure": list(st), "criterion": c}
                          for k, w, st, c in d.polish.path],
                "refits": d.polish.refits, "seconds": d.polish.seconds}}


def _held(v) -> str:
    """A held-out score, or "—" where there is none (no held-out run)."""
    return "—" if v is None or not math.isfinite(v) else f"{v:.3f}"


def discovery_text(d: Discovery, model_name: str, verdict=None) -> str:
    """A short text report: the selected model's verdict first where it is given (``verdict``,
    :func:`diffship.usability.verdict`), the selected terms, the ranked candidates, held-out errors, warnings."""
    sel = d.selected
    lines = [f"structure discovery on {model_name}: {len(d.screen.terms)} library terms screened, "
             f"{len(d.candidates)} structures refitted by output error, ranked by {d.criterion.upper()} on output "
             f"residuals ({d.seconds:.0f} s)"]
    if verdict is not None:  # FAILED, not converged, unidentified parameters: said before the terms
        lines += dataclasses.replace(verdict, method="selected model").lines()
    if sel.terms:
        lines.append("selected terms (value ± standard error, inclusion probability: bootstrap of the output-error "
                     "ranking; screen: of the equation-error screen):")
        for t in sel.terms:
            lines.append(f"  {t:>10s}  {term_label(t):<12s} {sel.result.params[t]: .5g} ± "
                         f"{sel.result.stderr.get(t, math.nan):.2g}   inclusion {d.inclusion.get(t, math.nan):.2f}"
                         f"   screen {d.screen.inclusion.get(t, math.nan):.2f}")
    else:
        lines.append(f"selected: no term beyond {model_name}")
    for t in d.possible:
        lines.append(f"possible (not selected): {t} ({term_label(t)}), inclusion probability "
                     f"{d.inclusion.get(t, 0.0):.2f}")
    for label, why in d.reasons.items():
        lines.append(f"not selected: {label}: {why}")
    if d.oe_screen is not None and d.oe_screen.path:
        lines.append("output-error screen (score statistic T of each forward step, * above the BIC cut): "
                     + ", ".join(f"{t} {T:.1f}{'*' if s else ''}" for t, T, s in
                                 zip(d.oe_screen.path, d.oe_screen.statistic, d.oe_screen.supported)))
    if d.polish is not None:
        moves = ", ".join(f"{k} {w}" for k, w, _, _ in d.polish.path) or "no move lowered the criterion"
        lines.append(f"polish from {' + '.join(d.polish.start)}: {moves} → {' + '.join(d.polish.selected)} "
                     f"({d.polish.refits} refits, {d.polish.seconds:.0f} s)")
    for a, b, c in d.tradeoffs:
        lines.append(f"warning: {a} and {b} trade off (estimates correlated {c:+.2f}); runs that separate them "
                     "would be needed to tell them apart")
    if d.equivalent:
        crit = d.criterion.upper()
        delta = lambda c: c.criteria[d.criterion] - sel.criteria[d.criterion]  # noqa: E731
        lines.append(f"equivalent explanations ({crit} within {MARGIN:g} of the selected; these runs do not decide "
                     "between them): " + "; ".join(f"{' + '.join(c.terms) or '(base)'} ({crit} {delta(c):+.1f}, "
                                                   f"held-out RMSE/base {_held(c.held_out)})" for c in d.equivalent))
        lines.append("  the manoeuvre that tells them apart: " + (d.separation.text() if d.separation is not None
                                                                  else "none found (every probe blew up)"))
    lines.append("")
    lines.append(f"  rank  {d.criterion.upper():>10s}  held-out RMSE/base  bootstrap wins  terms")
    for i, c in enumerate(d.candidates):
        lines.append(f"  {i + 1:>4d}  {c.criteria[d.criterion]:>10.1f}  {_held(c.held_out):>18s}  {c.wins:>14.2f}  "
                     + (" + ".join(c.terms) or "(base)") + ("   <- selected" if i == d.chosen else ""))
    if sel.validation is not None:
        lines.append("")
        lines.append("held-out runs, RMSE of a whole-horizon simulation, base → selected:")
        for run, pr in sel.validation.per_run.items():
            b = d.base.validation.per_run[run]["rmse"]
            lines.append(f"  {run}: " + ", ".join(
                f"{c} {b[c] * CHANNEL_UNITS.get(c, ('', 1.0))[1]:.3g} → {v * CHANNEL_UNITS.get(c, ('', 1.0))[1]:.3g}"
                f" {CHANNEL_UNITS.get(c, ('-', 1.0))[0]}" for c, v in pr["rmse"].items()))
        lines.append("confirmed on the held-out runs" if d.confirmed else
                     "NOT confirmed: the selected structure predicts the held-out runs worse than the base model")
    return "\n".join(lines)


def plot_discovery(d: Discovery, model_name: str, train, val, path: str | Path) -> None:
    """The fit CLI's figure, base and selected structure side by side."""
    names = {"base": d.base, "selected": d.selected}
    ev_t = {k: c.train for k, c in names.items()}
    ev_v = {k: c.validation for k, c in names.items() if c.validation is not None}
    plot_fit(model_name, train, val, ev_t, ev_v, path)
