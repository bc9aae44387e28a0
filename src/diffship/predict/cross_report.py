"""Reports of a :class:`~diffship.predict.cross.CrossValidation`: text table, JSON keys, figure."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .cross import UNDETERMINED, CrossValidation
from ..figures import pyplot

__all__ = ["cross_json", "cross_text", "plot_cross"]


def _f(v) -> str:
    return "—" if v is None or not math.isfinite(v) else f"{v:.4g}"


def cross_text(cv: CrossValidation) -> str:
    """The cross-manoeuvre section of a report: training types, one table per held-out run, verdict."""
    lines = ["Manoeuvre validation on held-out runs (trained on: "
             + ", ".join(f"{t.label}" for t in cv.train_types) + ")",
             ("  held-out standard manoeuvres from their estimated initial state: zigzags flown closed loop by the "
              "autopilot (measured side, execute time, helm rate and switch delay), other types open loop with "
              f"their measured inputs; IMO metrics measured vs predicted; intervals: {cv.interval_method}"),
             ("  flagged (MISS): measured value outside the 95 % interval and error beyond 5 % (lengths, rates), "
              "10 % (times) or 1.5° (overshoots); UNDETERMINED: the 95 % interval reaches beyond "
              f"{UNDETERMINED:g} such tolerances (the fit does not determine the metric)")]
    for c in cv.checks:
        trained = c.type.kind in {t.kind for t in cv.train_types}
        lines += ["", f"  {c.run}: {c.type.label} ({c.type.reason})"
                  + ("; a trained manoeuvre type" if trained else "; a manoeuvre type NOT in the training runs")
                  + (f"; {c.draws_failed} of {c.draws_used + c.draws_failed} draws failed" if c.draws_failed else "")]
        if c.note:
            lines.append(f"  {c.note}")
        lines.append(f"    {'metric':<22}{'unit':>6}{'measured':>12}{'predicted':>12}{'95 % interval':>24}"
                     f"{'error':>11}{'rel.':>8}  verdict")
        for m in c.metrics:
            iv = f"[{_f(m.interval[0])}, {_f(m.interval[1])}]" if m.interval else "—"
            rel = f"{100 * m.relative_error:+.1f}%" if math.isfinite(m.relative_error) else "—"
            verdict = (("MISS" if m.outside_tolerance else "UNDETERMINED") if m.flagged
                       else ("ok" if math.isfinite(m.measured) else "n/a"))
            lines.append(f"    {m.name:<22}{m.unit:>6}{_f(m.measured):>12}{_f(m.predicted):>12}{iv:>24}"
                         f"{_f(m.error):>11}{rel:>8}  {verdict}")
    for run, why in cv.skipped:
        lines.append(f"  not judged here: {run}: {why}")
    if not cv.checks:
        lines.append("  no held-out run is a standard manoeuvre: nothing to judge")
    else:
        def names(c, missed):
            return ", ".join(m.name for m in c.metrics if m.flagged and bool(m.outside_tolerance) == missed)
        # a miss (measured outside the interval and beyond tolerance, or a blow-up) fails; an interval wider than
        # five tolerances around a prediction within tolerance only says the training runs do not determine it
        miss = [f"{c.run} ({names(c, True) or 'blew up'})" for c in cv.checks
                if c.flagged and (names(c, True) or not names(c, False))]
        wide = [f"{c.run} ({names(c, False)})" for c in cv.checks if names(c, False)]
        if cv.passed:
            text = "the model PREDICTS the held-out manoeuvres within their intervals or tolerances"
        elif miss:
            text = ("FAILS cross-manoeuvre validation: misses " + "; ".join(miss)
                    + (f"; undetermined: {'; '.join(wide)}" if wide else "")
                    + ". Add such manoeuvres to the training set or constrain the model (priors, bounds)")
        else:
            text = ("no held-out metric is missed, but the training manoeuvres do not determine "
                    + "; ".join(wide) + " (95 % intervals wider than five tolerances): add such manoeuvres to the "
                    "training set or constrain the model (priors, bounds)")
        lines += ["", "  verdict: " + text]
    return "\n".join(lines)


def cross_json(cv: CrossValidation) -> dict:
    """``cross_manoeuvre`` JSON: train types, per held-out run type and metric: measured, predicted,
    interval, error; the verdict. NaN written as ``null``."""

    def num(v):
        return None if v is None or not math.isfinite(v) else float(v)

    def rtype(t):
        return t.as_json()

    return {
        "train_types": sorted(set(cv.train_kinds)), "train_runs": [dict(run=n, **rtype(t))
                                                                   for n, t in zip(cv.train_runs, cv.train_types)],
        "interval_method": cv.interval_method, "passed": cv.passed if cv.checks else None,
        "heldout": [{"run": c.run, "type": rtype(c.type), "flagged": c.flagged, "note": c.note or None,
                     "draws_used": c.draws_used, "draws_failed": c.draws_failed,
                     "metrics": {m.name: {"unit": m.unit, "measured": num(m.measured), "predicted": num(m.predicted),
                                          "interval_95": [num(x) for x in m.interval] if m.interval else None,
                                          "error": num(m.error), "relative_error": num(m.relative_error),
                                          "flagged": m.flagged} for m in c.metrics}} for c in cv.checks],
        "not_judged": [{"run": r, "why": w} for r, w in cv.skipped],
    }


def plot_cross(cv: CrossValidation, path: str | Path | None = None):
    """Predicted vs measured per metric (error bars: 95 % interval), one panel per held-out run, plus
    measured and predicted tracks (or headings) of each run."""
    plt = pyplot()

    n = max(1, len(cv.checks))
    fig, axes = plt.subplots(n, 2, figsize=(11, 3.6 * n), squeeze=False)
    for i, c in enumerate(cv.checks):
        ax = axes[i, 0]
        ms = [m for m in c.metrics if math.isfinite(m.measured) and m.measured != 0]
        for j, m in enumerate(ms):  # normalised by the measured value: 1 = exact
            y = m.predicted / m.measured
            if m.interval:
                lo, hi = sorted((m.interval[0] / m.measured, m.interval[1] / m.measured))
                ax.errorbar(j, y, yerr=[[max(y - lo, 0.0)], [max(hi - y, 0.0)]], fmt="o", capsize=4,
                            color="C3" if m.flagged else "C0")
            else:
                ax.plot(j, y, "o", color="C3" if m.flagged else "C0")
        ax.axhline(1.0, color="k", lw=0.8)
        ax.set_xticks(range(len(ms)), [m.name for m in ms], rotation=30, ha="right", fontsize=7)
        ax.set_ylabel("predicted / measured [-]", fontsize=8)
        ax.set_title(f"{c.run}: {c.type.label} — {'MISS' if c.flagged else 'ok'} (bars: 95 % interval, red: "
                     "flagged)", fontsize=8)
        ax.grid(alpha=0.3)
        ax = axes[i, 1]
        if c.measured.has("x0", "y0") and c.predicted is not None and c.predicted.has("x0", "y0"):
            ax.plot(np.asarray(c.measured["y0"]), np.asarray(c.measured["x0"]), "k", lw=1.2, label="measured")
            ax.plot(np.asarray(c.predicted["y0"]), np.asarray(c.predicted["x0"]), "C0--", lw=1.2, label="predicted")
            ax.set_aspect("equal", adjustable="datalim")
            ax.set_xlabel("y0 [m]", fontsize=8)
            ax.set_ylabel("x0 [m]", fontsize=8)
        elif c.predicted is not None:
            ax.plot(c.measured.time, np.degrees(np.unwrap(c.measured["psi"])), "k", label="measured ψ")
            ax.plot(c.predicted.time, np.degrees(np.unwrap(c.predicted["psi"])), "C0--", label="predicted ψ")
            ax.set_xlabel("time [s]", fontsize=8)
            ax.set_ylabel("heading [deg]", fontsize=8)
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
    if not cv.checks:
        axes[0, 0].text(0.5, 0.5, "no held-out run of another manoeuvre type", ha="center", va="center")
    fig.suptitle(f"diffship — cross-manoeuvre validation of {cv.model_name}, trained on "
                 + ", ".join(cv.train_kinds), fontsize=9)
    fig.tight_layout()
    if path is not None:
        fig.savefig(path, dpi=110)
        plt.close(fig)
    return fig
