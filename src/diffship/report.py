"""Reports of fits: a text table, a matplotlib figure, and JSON.

Angles are shown in degrees in the text and figures (labelled), and kept in radians (SI) in
JSON and everywhere in the library.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .channels import CHANNEL_NAMES
from .figures import pyplot
from .data import CHANNEL_UNITS, Run
from .metrics import Evaluation

if TYPE_CHECKING:  # type hints only: report sits beside fit, not above it
    from .fit.result import FitResult
    from .usability import Verdict

__all__ = [
    "CHANNEL_LABELS",
    "CHANNEL_NAMES",
    "CHANNEL_UNITS",
    "axis_label",
    "comparison",
    "failed_methods",
    "is_failed",
    "metrics_json",
    "plot_fit",
    "text_report",
    "to_json_dict",
    "write_json",
]


_LABEL = {"equation_error": "equation error", "output_error": "output error", "prediction_error": "prediction error"}
HORIZON_NOTE = "metrics: whole-horizon simulation of every run from its initial state (no one-step prediction)"


def _fmt(v: float) -> str:
    return "—" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.5g}"


def is_failed(ev: Evaluation, channels: Sequence[str] | None = None) -> bool:
    """An estimate whose whole-horizon simulation blows up or is worse than the measured mean
    (NRMSE fit % below 0 in one of ``channels``, default all) has failed as a prediction."""
    fp = {c: f for c, f in ev.fit_percent.items() if channels is None or c in channels}
    return (not ev.ok) or any(f < 0.0 or math.isnan(f) for f in fp.values())


def failed_methods(evs: Mapping[str, Evaluation], results: Mapping[str, FitResult] | None = None) -> tuple[str, ...]:
    """Methods whose training evaluation :func:`is_failed` in the channels they fitted (``results``;
    without them, every channel but the positions ``x0``, ``y0``, which drift and are not fitted by default)."""
    out = []
    for m, ev in evs.items():
        fitted = tuple(c for c in (results[m].channels if results and m in results else ()) if c in ev.channels)
        chans = fitted or tuple(c for c in ev.channels if c not in ("x0", "y0"))
        if is_failed(ev, chans):
            out.append(m)
    return tuple(out)


#: What a channel is, for axis labels (the unit comes from :data:`~diffship.data.CHANNEL_UNITS`).
CHANNEL_LABELS = {"x0": "north x0", "y0": "east y0", "z0": "down z0", "psi": "heading ψ", "phi": "roll φ",
                  "theta": "pitch θ", "u": "surge speed u", "v": "sway speed v", "w": "heave speed w",
                  "r": "yaw rate r", "p": "roll rate p", "q": "pitch rate q", "delta": "rudder δ"}


def axis_label(channel: str) -> str:
    """``"heading ψ [deg]"``: what the channel is and its display unit (degrees for angles)."""
    unit = CHANNEL_UNITS.get(channel, ("-", 1.0))[0]
    return f"{CHANNEL_LABELS.get(channel, channel)} [{unit}]"


def _compared(methods: Sequence[str]) -> str:
    """``"output error against the equation-error baseline"`` (or the methods' names)."""
    names = [_LABEL.get(m, m.replace("_", " ")) for m in methods]
    if "output_error" in methods and "equation_error" in methods and len(methods) == 2:
        return "output error against the equation-error baseline"
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def comparison(results: Mapping[str, FitResult], train: Mapping[str, Evaluation],
               validation: Mapping[str, Evaluation], train_runs: Sequence[Run], val_runs: Sequence[Run],
               verdicts: Mapping[str, Verdict] | None = None) -> list[str]:
    """The point first: every method's RMSE per channel from a whole-horizon simulation of each run from
    its measured start, held-out runs first (when there are any), each row with the method's verdict."""
    methods = sorted((m for m in results if m in train or m in validation), key=lambda m: m != "output_error")
    if not methods:
        return []
    lines = [f"{_compared(methods)}: RMSE of a whole-horizon simulation of every run from its measured start"]
    for kind, evs, runs in (("held-out", validation, val_runs), ("training", train, train_runs)):
        if not evs:
            continue
        chans = [c for c in next(iter(evs.values())).channels]
        lines.append(f"  {kind + ' (' + str(len(runs)) + ' run' + ('s' if len(runs) != 1 else '') + ')':<22}"
                     + "".join(f"{c + ' [' + CHANNEL_UNITS.get(c, ('-', 1))[0] + ']':>14}" for c in chans))
        for m in methods:
            if m not in evs:
                continue
            ev = evs[m]
            row = f"    {_LABEL.get(m, m):<20}" + "".join(
                f"{ev.rmse[c] * CHANNEL_UNITS.get(c, ('', 1.0))[1]:>14.4g}" for c in chans)
            label = (verdicts[m].label if verdicts and m in verdicts
                     else ("FAILED" if m in failed_methods(train, results) else ""))
            lines.append(row + (f"   {label}" if label else "") + ("" if ev.ok else "   (simulation blew up)"))
    return lines


def text_report(
    model_name: str,
    results: Mapping[str, FitResult],
    train: Mapping[str, Evaluation],
    validation: Mapping[str, Evaluation],
    train_runs: Sequence[Run],
    val_runs: Sequence[Run],
    verdicts: Mapping[str, Verdict] | None = None,
    *,
    screen: bool = False,
    details: str | None = None,
) -> str:
    """A plain-text report: the comparison first (:func:`comparison`: each method's whole-horizon RMSE,
    held-out runs first), the parameters side by side, each method's verdict (:mod:`diffship.usability`:
    FAILED / not converged / unidentifiable / runs not followed) with its notes, then fit % and per-run
    metrics. Without ``verdicts``, a method is FAILED by :func:`failed_methods`.

    ``screen=True`` is the terminal's view: a method that is not usable gets one line with its reason
    and where its notes and per-run errors are (``details``, the full report file), instead of them."""
    methods = list(results)
    w = 26
    failed = (tuple(m for m, v in verdicts.items() if not v.usable) if verdicts is not None
              else failed_methods(train, results))
    lines = [
        f"diffship fit — model {model_name}",
        f"training runs: {', '.join(r.name for r in train_runs)}",
        f"held-out runs: {', '.join(r.name for r in val_runs) if val_runs else 'none (pass --validate RUN.csv)'}",
        "",
        *comparison(results, train, validation, train_runs, val_runs, verdicts),
        "",
        f"{'parameter [unit]':<22}" + "".join(f"{_LABEL.get(m, m) + (' (FAILED)' if m in failed else ''):>{w}}"
                                              for m in methods),
    ]
    free = []
    for m in methods:
        free += [n for n in results[m].free if n not in free]
    for n in free:
        unit = next((p.unit for r in results.values() for p in r.model.PARAMS if p.name == n), "") or "-"
        row = f"{n + ' [' + unit + ']':<22}"
        for m in methods:
            r = results[m]
            if n in r.free:
                row += f"{_fmt(r.params[n]) + ' ± ' + _fmt(r.stderr.get(n, float('nan'))):>{w}}"
            else:
                row += f"{'fixed ' + _fmt(r.params[n]):>{w}}"
        lines.append(row)
    lines.append("")
    brief = set(failed) if screen else set()
    for m in methods:
        r = results[m]
        how = r.info.get("programs", "")
        if m in brief:
            v = verdicts.get(m) if verdicts is not None else None
            why = (v.reasons[0] if v is not None and v.reasons else "its simulation is worse than the measured mean")
            where = (f"its notes and per-run errors: {details}" if details
                     else "--out DIR writes its notes and per-run errors")
            lines.append(f"{_LABEL.get(m, m)}: FAILED — {why}; do not use these values ({where})")
            continue
        if verdicts is not None and m in verdicts:
            lines += verdicts[m].lines()
        elif m in failed:
            worst = min((f for c, f in train[m].fit_percent.items() if c not in ("x0", "y0")), default=float("nan"))
            lines.append(f"{_LABEL.get(m, m)}: FAILED — its simulation "
                         + ("blows up" if not train[m].ok else f"is worse than the measured mean (fit {worst:.0f} %)")
                         + "; do not use these values (kept off the figure's axis scaling)")
        lines.append(f"{_LABEL.get(m, m)}: {r.status}; {r.iterations} iterations; fit {r.fit_seconds:.2f} s, "
                     f"compile {r.compile_seconds:.2f} s" + (f" ({how})" if how else "")
                     + (f"; integrator: {r.info['integrator']}" if "integrator" in r.info else ""))
        for msg in r.messages:
            lines.append(f"  note: {msg}")
    lines += ["", HORIZON_NOTE]
    for title, evs in (("held-out", validation), ("training", train)):
        if not evs:
            continue
        chans = next(iter(evs.values())).channels
        lines.append(f"{title} fit [%]" + " " * max(1, 15 - len(title)) + "".join(f"{c + ' [%]':>14}" for c in chans))
        for m, ev in evs.items():
            lines.append(f"  {_LABEL.get(m, m):<20}" + "".join(f"{ev.fit_percent[c]:>14.1f}" for c in chans)
                         + ("   FAILED" if m in failed else ""))
    if train:
        lines.append(_common_cost(train, train_runs, failed))
    lines += _per_run({m: e for m, e in train.items() if m not in brief},
                      {m: e for m, e in validation.items() if m not in brief})
    return "\n".join(lines)


def _per_run(train: Mapping[str, Evaluation], validation: Mapping[str, Evaluation]) -> list[str]:
    """Per-run RMSE and fit % of every method (the same numbers as the JSON's ``per_run``)."""
    lines = []
    names = [n for evs in (train, validation) for ev in list((evs or {}).values())[:1] for n in ev.per_run]
    prefix = _common_prefix(names)
    if prefix:
        lines += ["", f"per-run tables: run names without their common prefix {prefix}"]
    for title, evs in (("held-out", validation), ("training", train)):
        for m, ev in (evs or {}).items():
            chans = [c for c in ev.channels]
            lines += ["", f"{title} runs, {_LABEL.get(m, m)}: RMSE and fit [%] per run",
                      f"  {'run':<18}" + "".join(f"{c + ' [' + CHANNEL_UNITS.get(c, ('', 1))[0] + ']':>16}" for c in chans)]
            for name, pr in ev.per_run.items():
                short = name[len(prefix):] or name
                row = f"  {short[:18]:<18}"
                for c in chans:
                    unit, k = CHANNEL_UNITS.get(c, ("", 1.0))
                    if c in pr["rmse"]:
                        row += f"{pr['rmse'][c] * k:>9.3g} {pr['fit_percent'][c]:>5.0f}%"
                    else:
                        row += f"{'—':>16}"
                lines.append(row + ("" if pr.get("ok", True) else "   (simulation blew up)"))
    return lines


def _common_cost(evs: Mapping[str, Evaluation], runs: Sequence[Run], failed: Sequence[str]) -> str:
    """Training cost of every method on one scale: ½ Σ_c Σ_k (e_ck / s_c)² with s_c the spread of the
    measured channel c over the training runs (the solvers' own costs use different weights per pass)."""
    chans = next(iter(evs.values())).channels
    n = sum(r.n for r in runs)
    spread = {}
    for c in chans:
        y = np.concatenate([np.unwrap(r[c]) if c == "psi" else np.asarray(r[c]) for r in runs if r.has(c)])
        spread[c] = float(np.std(y)) or 1.0
    parts = []
    for m, ev in evs.items():
        cost = 0.5 * sum(n * (ev.rmse[c] / spread[c]) ** 2 for c in chans if c not in ("x0", "y0"))
        parts.append(f"{_LABEL.get(m, m)} {cost:.4g}" + (" (FAILED)" if m in failed else ""))
    return ("training cost on one scale, ½Σ(e/s)² with s the spread of each measured channel (x0, y0 left "
            "out) [-]: " + ", ".join(parts))


def plot_fit(
    model_name: str,
    train_runs: Sequence[Run],
    val_runs: Sequence[Run],
    train: Mapping[str, Evaluation],
    validation: Mapping[str, Evaluation],
    path: str | Path | None = None,
    max_runs: int = 6,
    failed: Sequence[str] = (),
):
    """Measured vs simulated channels (both methods) per run, plus the track where available.

    Curves of ``failed`` methods (:func:`failed_methods`) are drawn thin, labelled FAILED and
    left out of the axis limits, which follow the measurements and the other curves.
    """
    plt = pyplot()

    n_val = min(len(val_runs), max(max_runs - len(train_runs), (max_runs + 1) // 2))  # held-out runs always shown
    n_train = min(len(train_runs), max_runs - n_val)
    rows = ([(r, "train", train) for r in train_runs[:n_train]]
            + [(r, "held out", validation) for r in val_runs[:n_val]])
    evs = train or validation
    chans = list(next(iter(evs.values())).channels)
    plot_chans = [c for c in chans if c not in ("x0", "y0")]
    track = "x0" in chans and "y0" in chans
    ncol = len(plot_chans) + (1 if track else 0) + 1
    names = [r.name for r, _, _ in rows]
    prefix = _common_prefix(names)
    short = {n: (n[len(prefix):] or n) for n in names}  # HSVA_CPMC_KVLCC2_Z_10_10_P -> Z_10_10_P
    ratios = [1.0] * len(plot_chans) + ([1.3] if track else []) + [1.0]
    fig, axes = plt.subplots(len(rows), ncol, figsize=(3.6 * sum(ratios), 2.9 * len(rows)), squeeze=False,
                             gridspec_kw={"width_ratios": ratios})
    colors = {"equation_error": "tab:orange", "output_error": "tab:blue"}
    for i, (run, kind, ev_map) in enumerate(rows):
        t = np.asarray(run.time)
        for j, c in enumerate(plot_chans):
            ax = axes[i, j]
            unit, k = CHANNEL_UNITS.get(c, ("", 1.0))
            y = np.asarray(run[c])
            y = np.unwrap(y) if c == "psi" else y
            ax.plot(t, y * k, color="0.4", lw=1.0, label="measured")
            kept = [y * k]
            for m, ev in ev_map.items():
                ys = ev.simulated[run.name][c] * k
                bad = m in failed
                ax.plot(t, ys, color=colors.get(m), lw=0.6 if bad else 1.2, ls="--" if m == "equation_error" else "-",
                        label=f"{_LABEL.get(m, m)}{' FAILED' if bad else ''} "
                              f"(RMSE {ev.per_run[run.name]['rmse'][c] * k:.3g} {unit})")
                if not bad:
                    kept.append(ys)
            _limits(ax, kept)
            ax.set_title(f"{short[run.name]} ({kind}): {CHANNEL_LABELS.get(c, c)}", fontsize=8)
            ax.set_ylabel(axis_label(c), fontsize=8)
            ax.legend(fontsize=6, loc="best")
            ax.grid(alpha=0.3)
            if i == len(rows) - 1:
                ax.set_xlabel("time [s]", fontsize=8)
        j = len(plot_chans)
        if track:
            ax = axes[i, j]
            ax.plot(run["y0"], run["x0"], color="0.4", lw=1.0, label="measured")
            for m, ev in ev_map.items():
                s = ev.simulated[run.name]
                ax.plot(s["y0"], s["x0"], color=colors.get(m), lw=1.2, ls="--" if m == "equation_error" else "-", label=_LABEL.get(m, m))
            ok = [ev.simulated[run.name] for m, ev in ev_map.items() if m not in failed]
            _square_limits(ax, [np.asarray(run["y0"])] + [s["y0"] for s in ok],
                           [np.asarray(run["x0"])] + [s["x0"] for s in ok])
            ax.set_xlabel("y0 (east/starboard) [m]", fontsize=8)
            ax.set_ylabel("x0 (north/ahead) [m]", fontsize=8)
            ax.set_title(f"{short[run.name]}: track", fontsize=8)
            ax.grid(alpha=0.3)
            j += 1
        ax = axes[i, j]
        for n in [n for n in run.channel_names if n in ("delta", "tau_x", "tau_y", "tau_z", "delta_n", "rpm")]:
            unit, k = CHANNEL_UNITS.get(n, ("", 1.0))
            y = np.asarray(run[n]) * k
            scale = np.max(np.abs(y)) or 1.0
            ax.plot(t, y / scale, lw=1.0, label=f"{n} / {scale:.3g} {unit}")
        ax.set_title(f"{short[run.name]}: inputs (normalised)", fontsize=8)
        ax.set_ylabel("input / its largest value [-]", fontsize=8)
        if i == len(rows) - 1:
            ax.set_xlabel("time [s]", fontsize=8)
        ax.legend(fontsize=6)
        ax.grid(alpha=0.3)
    fig.suptitle(f"diffship — {model_name}: measured vs simulated (whole-horizon simulation)"
                 + (f"; runs {prefix}…" if prefix else ""), fontsize=11)
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 0.97))
    if path is not None:
        fig.savefig(path, dpi=110)
        plt.close(fig)
    return fig


def _common_prefix(names: Sequence[str]) -> str:
    """The common prefix of several run names, cut after its last separator (``_``, ``-``, space); ``""``
    for one name or none."""
    if len(names) < 2:
        return ""
    p = names[0]
    for n in names[1:]:
        while not n.startswith(p):
            p = p[:-1]
    cut = max(p.rfind(c) for c in "_- ")
    return p[:cut + 1] if cut >= 0 else ""


def _square_limits(ax, xs, ys, pad=0.08) -> None:
    """Equal-aspect track limits over the given curves (finite values), the shorter side widened to the
    longer one so that a long straight track is not drawn as a sliver."""
    x = np.concatenate([np.ravel(a)[np.isfinite(np.ravel(a))] for a in xs])
    y = np.concatenate([np.ravel(a)[np.isfinite(np.ravel(a))] for a in ys])
    if not (x.size and y.size):
        return
    half = max(float(np.ptp(x)), float(np.ptp(y)), 1e-9) * (0.5 + pad)
    cx, cy = 0.5 * (float(x.min()) + float(x.max())), 0.5 * (float(y.min()) + float(y.max()))
    ax.set_xlim(cx - half, cx + half)
    ax.set_ylim(cy - half, cy + half)
    ax.set_aspect("equal", adjustable="box")


def _limits(ax, ys, xs=None, pad=0.08) -> None:
    """Axis limits from the given curves only (finite values), so a failed curve cannot stretch them."""
    for arrs, setter in ((ys, ax.set_ylim), (xs, ax.set_xlim)):
        if not arrs:
            continue
        v = np.concatenate([np.ravel(a)[np.isfinite(np.ravel(a))] for a in arrs])
        if v.size:
            lo, hi = float(v.min()), float(v.max())
            d = (hi - lo) * pad or 1.0
            setter(lo - d, hi + d)


def metrics_json(ev: Evaluation | None) -> dict:
    """One evaluation's metrics as the JSON report and the fit file write them (``rmse``, ``fit_percent``, ``ok``,
    ``per_run``); empty tables for ``None``."""
    if ev is None:
        return {"rmse": {}, "fit_percent": {}}
    return {"rmse": dict(ev.rmse), "fit_percent": dict(ev.fit_percent), "ok": ev.ok,
            "per_run": {k: {"rmse": v["rmse"], "fit_percent": v["fit_percent"], "ok": v["ok"]} for k, v in ev.per_run.items()}}


def to_json_dict(model_name: str, results: Mapping[str, FitResult], train: Mapping[str, Evaluation],
                 validation: Mapping[str, Evaluation], extra: Mapping | None = None,
                 verdicts: Mapping[str, Verdict] | None = None, per_method: Mapping[str, Mapping] | None = None) -> dict:
    """The ``--json`` document: parameters in the model's SI units, metrics per channel (SI, rad), each
    method's outcome (``outcome``, ``usable``, ``verdict``); ``per_method``: further entries per method
    made by the command line (fixed values, admissibility, cross-manoeuvre checks)."""
    methods = {}
    for m, r in results.items():
        v = verdicts.get(m) if verdicts else None
        methods[m] = {
            "outcome": r.outcome,
            "usable": bool(r.usable) if v is None else v.usable,
            "verdict": v.as_json() if v is not None else None,
            "params": r.params,
            "stderr": r.stderr,
            "free": list(r.free),
            "converged": r.converged,
            "status": r.status,
            "iterations": r.iterations,
            "cost": r.cost,
            "fit_seconds": r.fit_seconds,
            "compile_seconds": r.compile_seconds,
            "programs": r.info.get("programs", ""),
            "integrator": r.info.get("integrator", ""),
            "train": metrics_json(train.get(m)),
            "validation": metrics_json(validation.get(m)),
            "messages": list(r.messages),
            "filter": r.info.get("filter"),
            "smoother": r.info.get("smoother"),
            "prior_note": r.info.get("prior_note"),
            "priors": r.info.get("priors"),
            "identifiability": r.info.get("identifiability"),
            "admissibility": r.info.get("admissibility"),
            "cross_manoeuvre": r.info.get("cross_manoeuvre"),
            "fixed": r.info.get("fixed"),
            **{k: r.info[k] for k in ("disturbance_choice", "positions_test") if k in r.info},
            **dict((per_method or {}).get(m, {})),
        }
    doc = {"model": model_name, "units": "SI, angles in rad", "metrics_horizon": HORIZON_NOTE, "methods": methods}
    if extra:
        doc.update(extra)
    return doc


def write_json(doc: dict, path: str | Path) -> None:
    def default(o):
        if isinstance(o, (np.floating, np.integer)):
            return o.item()
        if isinstance(o, np.ndarray):
            return o.tolist()
        return str(o)

    Path(path).parent.mkdir(parents=True, exist_ok=True)  # as the fit file and the HTML report do
    Path(path).write_text(json.dumps(doc, indent=2, default=default, allow_nan=True))
