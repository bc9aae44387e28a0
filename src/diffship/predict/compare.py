"""The training manoeuvres flown again beside what was measured (a ``compare``, as in MATLAB's SITB).

Before a prediction of new manoeuvres means anything, the model must reproduce the manoeuvres it
was trained on when flown as a prediction is flown: closed loop from the approach condition, with
the measured helm rate and the switch delay of each training zigzag. :func:`compare_training`
reads the fit file's ``training_manoeuvres`` (type, rudder and switch angles, side, measured IMO
metrics, switch delay; written by ``python -m diffship.fit``), flies each standard one with
:func:`diffship.predict.core.predict` and returns the predicted metrics beside the measured ones;
:func:`compare_text` prints them as the first table of ``python -m diffship.predict``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

from ..errors import DataError, ModelError
from ..fitfile import LoadedFit
from .core import METRIC_KINDS, ManoeuvreSpec, predict

__all__ = ["CompareRow", "compare_text", "compare_training"]

_KINDS = {"zigzag": "zigzag", "turning_circle": "turning_circle", "pull_out": "pull_out"}


@dataclasses.dataclass(frozen=True)
class CompareRow:
    """One training run flown again: its ``run`` name, ``spec``, ``measured`` and ``predicted`` metrics
    (common keys), the switch ``delay_s`` used, and ``note`` (why it could not be flown, if so)."""

    run: str
    spec: ManoeuvreSpec | None
    measured: dict[str, float]
    predicted: dict[str, float]
    delay_s: float = 0.0
    note: str = ""


def compare_training(fit: LoadedFit, **condition) -> list[CompareRow]:
    """Fly each standard training manoeuvre of ``fit`` (``condition``: the keyword arguments of
    :func:`~diffship.predict.core.predict` other than the manoeuvres and the delay; no intervals)."""
    rows = []
    condition = {k: v for k, v in condition.items() if k not in ("delay_s", "samples")}
    for m in fit.document.get("training_manoeuvres") or ():
        kind = _KINDS.get(m.get("kind", ""))
        measured = {k: float(v) for k, v in (m.get("measured") or {}).items()}
        if kind is None or not m.get("rudder_deg"):
            rows.append(CompareRow(m.get("run", "?"), None, measured, {}, note=f"{m.get('kind')}: not flown"))
            continue
        spec = ManoeuvreSpec(kind, float(m["rudder_deg"]),
                             float(m["switch_deg"]) if kind == "zigzag" and m.get("switch_deg") else None,
                             float(m.get("side") or 1.0))
        delay = float(m.get("switch_delay_s") or 0.0)
        try:
            p = predict(fit, [spec], delay_s=delay, samples=0, **condition)
        except (DataError, ModelError) as exc:
            rows.append(CompareRow(m.get("run", "?"), spec, measured, {}, delay, f"not flown: {exc}"))
            continue
        pred = p.manoeuvres[0].metrics
        rows.append(CompareRow(m.get("run", "?"), spec, measured, {k: float(v) for k, v in pred.items()}, delay))
    return rows


def _f(v: float) -> str:
    return "—" if v is None or not math.isfinite(v) else f"{v:.4g}"


def compare_text(rows: list[CompareRow], units: Mapping[str, str] | None = None) -> str:
    """The compare table: per training run, each metric measured, predicted and their difference."""
    if not rows:
        return ("training manoeuvres: the fit file lists none (refit with this version of python -m diffship.fit "
                "to compare the prediction with the measured training manoeuvres)")
    lines = ["training manoeuvres flown again as predicted (closed loop, measured helm rate and switch delay) "
             "beside the measured ones:",
             f"  {'run':<28}{'manoeuvre':<28}{'metric':<22}{'unit':>6}{'measured':>11}{'predicted':>11}{'diff':>9}"]
    for r in rows:
        label = r.spec.label if r.spec else "—"
        if r.note or not r.predicted:
            lines.append(f"  {r.run[:27]:<28}{label[:27]:<28}{r.note or 'no common metric'}")
            continue
        keys = [k for k in r.predicted if k in r.measured]
        if not keys:
            lines.append(f"  {r.run[:27]:<28}{label[:27]:<28}no metric measured and predicted alike")
        for i, k in enumerate(keys):
            unit = (units or {}).get(k) or METRIC_KINDS.get(k, ("", ""))[1]
            mv, pv = r.measured[k], r.predicted[k]
            lines.append(f"  {(r.run[:27] if i == 0 else ''):<28}{(label[:27] if i == 0 else ''):<28}{k:<22}{unit:>6}"
                         f"{_f(mv):>11}{_f(pv):>11}{_f(pv - mv):>9}")
    return "\n".join(lines)
