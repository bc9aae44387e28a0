"""Reports of a :class:`~diffship.predict.core.Prediction`: text table with units, figures, JSON."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from .core import METRIC_KINDS, Prediction
from ..figures import pyplot

__all__ = ["plot_prediction", "prediction_json", "prediction_text", "write_prediction"]

_NAMES = {
    "advance": "advance", "transfer": "transfer", "tactical_diameter": "tactical diameter",
    "steady_diameter": "steady turning diameter", "advance_L": "advance / L", "tactical_diameter_L":
    "tactical diameter / L", "steady_diameter_L": "steady diameter / L", "time_to_90": "time to 90° heading change",
    "time_to_180": "time to 180° heading change", "speed_ratio": "speed in steady turn / approach speed",
    "first_overshoot": "first overshoot", "second_overshoot": "second overshoot",
    "initial_turning_time": "initial turning time", "time_to_check": "time to check yaw",
    "distance_at_10deg_L": "distance at 10° heading change / L", "r_turn": "yaw rate before release",
    "r_residual": "residual yaw rate",
}


def _f(v: float) -> str:
    return "—" if v is None or not math.isfinite(v) else f"{v:.4g}"


def prediction_text(p: Prediction) -> str:
    """The printed report: condition, one table per manoeuvre (units on every row), IMO criteria."""
    c = p.condition
    lam = c.scale
    lines = [f"diffship prediction — model {p.model_name} from {p.fit_path}",
             f"approach: {c.approach}",
             (f"helm rate {c.helm_rate_deg_s:.3g} °/s, autopilot delay {c.delay_s:g} s, time step {c.dt:.3g} s "
              "(all at the fit's scale)")]
    if c.length:
        lines.append(f"ship length L = {c.length:g} m" + (f" (full scale {c.length * lam:g} m)" if lam else "")
                     + (f"; L/V = {c.l_over_v:.3g} s" if c.l_over_v else "")
                     + (f" (full scale {c.l_over_v_full:.3g} s)" if lam and c.l_over_v_full else ""))
    if lam:
        lines.append(f"full scale by Froude scaling, λ = {lam:g}: lengths × λ, times × √λ = {math.sqrt(lam):.4g}, "
                     f"speed {c.speed * math.sqrt(lam):.4g} m/s ({c.speed * math.sqrt(lam) / 0.514444:.3g} kn)"
                     if c.speed else f"full scale by Froude scaling, λ = {lam:g}")
    lines.append(f"intervals: {p.interval_method}")
    for n in p.notes:
        lines.append(f"note: {n}")
    hdr = f"  {'quantity':<40}{'unit':>7}{'model scale':>14}{'95 % interval':>22}"
    if lam:
        hdr += f"{'full scale':>14}{'unit':>7}"
    for m in p.manoeuvres:
        lines += ["", f"{m.spec.label}" + (f"  ({m.samples_failed} of {m.samples_used + m.samples_failed} draws failed)"
                                           if m.samples_failed else ""), hdr]
        for k, v in m.metrics.items():
            unit = METRIC_KINDS.get(k, ("", ""))[1]
            iv = m.intervals.get(k)
            ivs = f"[{_f(iv[0])}, {_f(iv[1])}]" if iv else "—"
            row = f"  {_NAMES.get(k, k):<40}{unit:>7}{_f(v):>14}{ivs:>22}"
            if lam:
                fu = {"m": "m", "s": "s", "deg/s": "deg/s"}.get(unit, unit)
                row += f"{_f(m.full_scale[k]):>14}{fu:>7}"
            lines.append(row)
    lines += ["", f"IMO MSC.137(76) criteria, checked at {p.criteria_scale}:"]
    lines += ["  " + cr.row() for cr in p.criteria]
    return "\n".join(lines)


def plot_prediction(p: Prediction, path: str | Path | None = None):
    """Tracks (left) and time histories of heading, yaw rate and rudder (right), one row per manoeuvre."""
    plt = pyplot()

    n = len(p.manoeuvres)
    fig, axes = plt.subplots(n, 2, figsize=(11, 3.2 * n), squeeze=False)
    L = p.condition.length
    for i, m in enumerate(p.manoeuvres):
        run = m.run
        ax = axes[i, 0]
        if run.has("x0", "y0"):
            k = 1.0 / L if L else 1.0
            ax.plot(np.asarray(run["y0"]) * k, np.asarray(run["x0"]) * k, lw=1.2)
            ax.set_aspect("equal", adjustable="datalim")
            unit = "L" if L else "m"
            ax.set_xlabel(f"y0 (starboard) [{unit}]", fontsize=8)
            ax.set_ylabel(f"x0 (ahead) [{unit}]", fontsize=8)
            if "kinematic_track" in run.metadata:
                ax.set_title(f"{m.spec.label}: track (kinematic, {run.metadata['kinematic_track']})", fontsize=9)
            else:
                ax.set_title(f"{m.spec.label}: track", fontsize=9)
        ax.grid(alpha=0.3)
        ax = axes[i, 1]
        t = run.time
        ax.plot(t, np.degrees(np.unwrap(np.asarray(run["psi"]) - run["psi"][0])), label="heading change [deg]")
        ax.plot(t, np.degrees(np.asarray(run["delta"])), label="rudder δ [deg]")
        if run.has("r"):
            ax.plot(t, np.degrees(np.asarray(run["r"])) * 10.0, lw=0.8, label="yaw rate × 10 [deg/s]")
        ax.set_xlabel("time [s] (fit's scale)", fontsize=8)
        ax.set_ylabel("angle [deg]; yaw rate × 10 [deg/s]", fontsize=8)
        ax.set_title(f"{m.spec.label}: time histories", fontsize=9)
        ax.legend(fontsize=6)
        ax.grid(alpha=0.3)
    fig.suptitle(f"diffship — predicted manoeuvres of {p.model_name} ({p.condition.approach})", fontsize=9)
    fig.tight_layout()
    if path is not None:
        fig.savefig(path, dpi=110)
        plt.close(fig)
    return fig


def _clean(v):
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, dict):
        return {k: _clean(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_clean(x) for x in v]
    if isinstance(v, (np.floating, np.integer)):
        return _clean(v.item())
    return v


def prediction_json(p: Prediction) -> dict:
    """JSON document: condition, metrics per manoeuvre (model and full scale, intervals), criteria; ``fit``: what
    the fit file says of its fit (``usable``, ``converged``, ``verdict``: a FAILED fit's predictions are not
    supported, as the notes say)."""
    c = p.condition
    return _clean({
        "schema": "diffship.prediction/1", "model": p.model_name, "fit_file": p.fit_path, "fit": p.fit,
        "units": {k: u for k, (_, u) in METRIC_KINDS.items()},
        "condition": {"speed": c.speed, "inputs": c.inputs, "approach": c.approach, "helm_rate_deg_s": c.helm_rate_deg_s,
                      "helm_rate_source": c.helm_rate_source, "delay_s": c.delay_s, "scale": c.scale,
                      "length_m": c.length, "l_over_v_s": c.l_over_v, "l_over_v_full_s": c.l_over_v_full, "dt": c.dt},
        "interval_method": p.interval_method,
        "manoeuvres": [{"label": m.spec.label, "kind": m.spec.kind, "rudder_deg": m.spec.rudder_deg,
                        "switch_deg": m.spec.switch_deg, "side": m.spec.side, "model_scale": m.metrics,
                        "full_scale": m.full_scale if c.scale else None,
                        "interval_95": {k: list(v) for k, v in m.intervals.items()},
                        "samples_used": m.samples_used, "samples_failed": m.samples_failed} for m in p.manoeuvres],
        "criteria_scale": p.criteria_scale,
        "criteria": [{"clause": cr.clause, "text": cr.text, "value": cr.value, "limit": cr.limit, "unit": cr.unit,
                      "passed": cr.passed} for cr in p.criteria],
        "notes": list(p.notes),
    })


def write_prediction(p: Prediction, out: str | Path) -> list[Path]:
    """Write ``prediction.txt``, ``prediction.json``, ``prediction.png`` and one CSV per manoeuvre to ``out``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    files = [out / "prediction.txt", out / "prediction.json", out / "prediction.png"]
    files[0].write_text(prediction_text(p) + "\n")
    files[1].write_text(json.dumps(prediction_json(p), indent=2))
    plot_prediction(p, files[2])
    for m in p.manoeuvres:
        f = out / f"{m.spec.key}_{'stbd' if m.spec.side > 0 else 'port'}.csv"
        m.run.to_dataframe().to_csv(f, index=False)
        files.append(f)
    return files
