r"""IMO manoeuvrability criteria (Resolution MSC.137(76), 2002, section 5.2) as pass/fail checks.

With L the ship length and V the approach speed (L/V in seconds, at **full scale**):

* 5.2.1 turning ability (35° turning circle): advance ≤ 4.5 L, tactical diameter ≤ 5 L;
* 5.2.2 initial turning ability (10/10 zigzag): the ship travels at most 2.5 L by the time the
  heading has changed by 10° (the second execute);
* 5.2.3 yaw-checking and course-keeping: first overshoot of the 10/10 zigzag ≤ 10° if
  L/V < 10 s, ≤ 20° if L/V ≥ 30 s, ≤ (5 + L/(2V))° in between; second overshoot of the 10/10
  zigzag ≤ 25°, 40° and (17.5 + 0.75 L/V)° respectively; first overshoot of the 20/20 zigzag ≤ 25°;
* 5.2.4 stopping ability (track reach ≤ 15 L) is not predicted by a manoeuvring model without
  astern propulsion: reported as not assessed.

Angles and lengths in ship lengths are the same at model and full scale; only L/V scales
(by √λ), which is why the criteria are checked at full scale where a scale is given
(MSC/Circ.1053 explains how model tests are used for them).
"""

from __future__ import annotations

import dataclasses
import math

__all__ = ["Criterion", "check_criteria", "overshoot_limits"]


@dataclasses.dataclass(frozen=True)
class Criterion:
    """One IMO criterion: ``value`` against ``limit`` (both in ``unit``), ``passed`` or ``None``."""

    clause: str
    text: str
    value: float
    limit: float
    unit: str
    passed: bool | None

    def row(self) -> str:
        verdict = {True: "pass", False: "FAIL", None: "n/a"}[self.passed]
        val = "—" if math.isnan(self.value) else f"{self.value:.3g}"
        limit = f"≤ {self.limit:<6.3g}" if math.isfinite(self.limit) else f"{'—':<8}"  # no limit: no number
        return f"{self.clause:<8} {self.text:<46} {val:>8} {limit} {self.unit:<5} {verdict}"


def overshoot_limits(l_over_v: float) -> tuple[float, float]:
    """IMO limits [°] on the first and second overshoot of the 10/10 zigzag for L/V [s]."""
    if l_over_v < 10.0:
        return 10.0, 25.0
    if l_over_v >= 30.0:
        return 20.0, 40.0
    return 5.0 + 0.5 * l_over_v, 17.5 + 0.75 * l_over_v


def _c(clause, text, value, limit, unit) -> Criterion:
    ok = None if value is None or math.isnan(value) else bool(value <= limit)
    return Criterion(clause, text, math.nan if value is None else float(value), float(limit), unit, ok)


def check_criteria(metrics: dict[str, dict[str, float]], l_over_v: float | None) -> list[Criterion]:
    """Criteria for the manoeuvres present in ``metrics``.

    ``metrics``: ``{"turning_35": {"advance_L", "tactical_diameter_L"}, "zigzag_10_10":
    {"first_overshoot", "second_overshoot", "distance_at_10deg_L"}, "zigzag_20_20":
    {"first_overshoot"}}`` (any subset; several sides: the worst is checked); ``l_over_v``:
    full-scale L/V [s] (``None``: overshoot limits cannot be set).
    """
    out = []
    t = metrics.get("turning_35")
    if t:
        out.append(_c("5.2.1", "turning 35°: advance", t.get("advance_L"), 4.5, "L"))
        out.append(_c("5.2.1", "turning 35°: tactical diameter", t.get("tactical_diameter_L"), 5.0, "L"))
    z = metrics.get("zigzag_10_10")
    if z:
        out.append(_c("5.2.2", "initial turning: distance at 10° heading change", z.get("distance_at_10deg_L"),
                      2.5, "L"))
        if l_over_v is not None and math.isfinite(l_over_v):
            a1, a2 = overshoot_limits(l_over_v)
            out.append(_c("5.2.3", f"10/10 zigzag: first overshoot (L/V = {l_over_v:.3g} s)", z.get("first_overshoot"),
                          a1, "deg"))
            out.append(_c("5.2.3", "10/10 zigzag: second overshoot", z.get("second_overshoot"), a2, "deg"))
        else:
            out.append(Criterion("5.2.3", "10/10 zigzag overshoots (need L and V)", math.nan, math.nan, "deg", None))
    z = metrics.get("zigzag_20_20")
    if z:
        out.append(_c("5.2.3", "20/20 zigzag: first overshoot", z.get("first_overshoot"), 25.0, "deg"))
    out.append(Criterion("5.2.4", "stopping: track reach (not predicted)", math.nan, 15.0, "L", None))
    return out
