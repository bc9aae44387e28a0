"""Diagnosis report: Markdown tables, figures and the JSON file of a :class:`~.diagnosis.Diagnosis`.

The three-line verdict and the per-candidate verdicts are decided in :mod:`.verdict`; this
module only presents them.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..data import CHANNEL_UNITS
from .verdict import format_params

__all__ = ["to_markdown", "plot_all", "write_json", "write_report"]


def to_markdown(d) -> str:
    L = ["# Gap diagnosis: " + d.model_name, ""]
    L += [f"> {x}  " for x in d.verdict] + [""]
    L += [f"- note: {n}" for n in getattr(d, "notes", ())] + ([""] if getattr(d, "notes", ()) else [])
    checks = getattr(d, "in_data", None) or {}
    if checks:
        L += ["## In the data (consistency of the logs, no hull coefficient)", "",
              "| check | estimate (95 %) | finding | held-out misfit without → with | method | why |",
              "|---|---|---|---|---|---|"]
        L += [f"| {k} | {f.shown()} | {'yes' if f.found else 'no'} | {f.heldout[0]:.3g} → {f.heldout[1]:.3g} "
              f"{f.misfit_unit} | {f.method} | {f.reason} |" for k, f in checks.items()] + [""]
    sea = getattr(d, "sea_state", None)
    if sea is not None:
        L += ["## Sea state (prediction from the Kalman filter's state, held-out runs)", "", sea.line(), ""]
        rows = sea.compare(d.base_fit.params, d.base_fit.stderr)
        if rows:
            L += ["The two estimates of the base model: output error (the measured input as given; biased where the "
                  "input answers the sea, as an autopilot does) and prediction error with the sea state "
                  "(`--method prediction-error --disturbance wave`).", "",
                  "| parameter | output error | prediction error with the sea state | apart [combined SE] |",
                  "|---|---|---|---|"]
            L += [f"| {r['name']} | {r['output_error']:.4g} ± {r['se_output_error']:.2g} | {r['prediction_error']:.4g} ± "
                  f"{r['se_prediction_error']:.2g} | {r['z']:.1f} |".replace("| nan |", "| — |") for r in rows] + [""]
    L += ["## Gap budget (validation, normalised by the noise floor)", "",
          "| total E | noise | parameter | structural |", "|---|---|---|---|",
          f"| {d.gap.E_total:.3g} | {d.gap.E_noise:.3g} | {d.gap.E_param:.3g} | {d.gap.E_struct:.3g} |", ""]
    L += ["## Where", "", "| channel [unit] | RMSE before | RMSE after | noise floor | share of error |", "|---|---|---|---|---|"]
    for c, v in d.where.per_channel.items():
        u, k = CHANNEL_UNITS.get(c, ("SI", 1.0))
        L.append(f"| {c} [{u}] | {k * d.rmse_before[c]:.4g} | {k * d.rmse_after[c]:.4g} | {k * v['noise_floor']:.3g} | "
                 f"{100 * v['share']:.0f} % |")
    L += ["", "Noise floor per channel: " + "; ".join(
        f"{c}: {CHANNEL_UNITS.get(c, ('SI', 1.0))[1] * v['sigma']:.3g} {CHANNEL_UNITS.get(c, ('SI', 1.0))[0]} ({v['method']}"
        + (f", lag-1 correlation {v['rho']:.2f}" if "rho" in v else "") + (f"; {v['note']}" if v.get("note") else "") + ")"
        for c, v in getattr(d, "noise_estimate", {}).items())]
    st = getattr(d, "start", None) or {}
    if st.get("rule"):
        L += ["", f"Held-out start: {st['rule']}."]
        for key, label in (("base", "base"), ("final", "final model")):
            info = st.get(key) or {}
            held = {r: s for r, s in (info.get("at_bound") or {}).items() if s}
            if held:
                L.append(f"- {label}: wanted to start further from the log than the noise allows in "
                         + "; ".join(f"{r}: {', '.join(s)}" for r, s in held.items()))
    L += ["", "E: RMS error over the noise floor (dimensionless); parameters in SI units, angles in rad.", "",
          "| phase | time share | E |", "|---|---|---|"]
    for p, v in d.where.per_phase.items():
        L.append(f"| {p} | {100 * v['fraction_of_time']:.0f} % | {v['E']:.3g} |")
    L += ["", "| run | E |", "|---|---|"] + [f"| {k} | {v['E']:.3g} |" for k, v in d.where.per_run.items()]
    L += ["", "| region | bins (E per quartile) |", "|---|---|"]
    for k, bins in d.where.per_region.items():
        L.append(f"| {k} | " + ", ".join(f"[{b['low']:.3g}, {b['high']:.3g}]: {b['E']:.3g}" for b in bins) + " |")
    L += ["", "| channel | residual white | independent of input | CCF(input rate) peak lag [s] |", "|---|---|---|---|"]
    for c, v in d.where.residual_tests.items():
        L.append(f"| {c} | {'yes' if v['white'] else 'no'} | {'yes' if v['independent_of_input'] else 'no'} | {v['ccf_peak_lag_s']:.2f} |")
    if d.where.force_residuals:
        fr = {k: v for k, v in d.where.force_residuals.items() if k != "notes"}
        L += ["", "Inverse-dynamics force residuals (RMS, mean) [N, N, N·m]: " + ", ".join(
            f"{k}: {v['rms']:.3g}, {v['mean']:.3g}" for k, v in fr.items())]
        L += [f"- note: {n}" for n in d.where.force_residuals.get("notes", [])]
    L += ["", "## Which (candidates, selected on validation)", "",
          "| effect | screen f_k | o_k | fitted parameters (95 %) | validation gain | shrink | verdict |",
          "|---|---|---|---|---|---|---|"]
    nan = float("nan")
    for r in d.ranking:
        sf = nan if r.screen_fraction is None else r.screen_fraction
        of = nan if r.orthogonal_fraction is None else r.orthogonal_fraction
        L.append(f"| {r.effect} | {sf:.3g} | {of:.2g} | {format_params(r.params, r.stderr)} | "
                 f"{100 * r.validation_gain:.1f} % | {r.shrink:.2f} | {r.verdict} |")
    L += ["", "## How far (greedy path)", "", "| step | effect | E before | E after | shrink of structural gap |", "|---|---|---|---|---|"]
    for i, s in enumerate(d.path):
        L.append(f"| {i + 1} | {s.effect} | {s.E_before:.3g} | {s.E_after:.3g} | {s.shrink_of_structural_gap:.2f} |")
    L += ["", "Timings [s]: " + ", ".join(f"{k} {v:.1f}" for k, v in d.timings.items()), ""]
    return "\n".join(L)


def plot_all(d, out: Path) -> list[Path]:
    """Residuals with phases shaded, ACF/CCF panels, regime heatmap, before/after overlays, waterfall,
    and the data-consistency checks (:func:`plot_data_checks`). Values in display units (degrees for
    angles, :data:`~diffship.data.CHANNEL_UNITS`), every axis labelled with its unit."""
    from ..figures import pyplot
    from ..report import axis_label

    plt = pyplot()
    out = Path(out)
    files = []
    res, lab = d.where.residuals, d.where.phases
    colors = {"approach": "0.9", "transient": "#fdd", "steady_turn": "#dfd", "counter_steer": "#ddf", "straight": "white"}
    # 1. residual time series with phases shaded
    runs = list(d.val_runs)
    fig, axes = plt.subplots(len(d.channels), len(runs), figsize=(5 * len(runs), 2.2 * len(d.channels)), squeeze=False)
    for j, run in enumerate(runs):
        t = np.asarray(run.time)
        for i, c in enumerate(d.channels):
            ax = axes[i, j]
            lb = lab[run.name]
            k0 = 0
            for k in range(1, t.size + 1):
                if k == t.size or lb[k] != lb[k0]:
                    ax.axvspan(t[k0], t[k - 1], color=colors.get(lb[k0], "white"), lw=0)
                    k0 = k
            unit, k = CHANNEL_UNITS.get(c, ("-", 1.0))
            ax.plot(t, np.asarray(res[run.name][c]) * k, lw=0.8, color="k")
            ax.set_ylabel(f"{c} residual [{unit}]", fontsize=8)
            if i == 0:
                ax.set_title(f"held-out run {run.name}", fontsize=9)
            if i == len(d.channels) - 1:
                ax.set_xlabel("time [s]")
    fig.suptitle("residual = simulated − measured; shaded: red transient, green turn with rudder held, blue counter-steer",
                 fontsize=9)
    fig.tight_layout()
    files.append(out / "residuals.png")
    fig.savefig(files[-1], dpi=90)
    plt.close(fig)
    # 2. ACF / CCF
    tests = d.where.residual_tests
    fig, axes = plt.subplots(2, len(d.channels), figsize=(3.2 * len(d.channels), 5), squeeze=False)
    for i, c in enumerate(d.channels):
        v = tests[c]
        lags = np.arange(len(v["acf"])) * v["lag_s"]
        for row, (key, title) in enumerate((("acf", "ACF"), ("ccf_input_rate", "CCF with input rate"))):
            ax = axes[row, i]
            ax.plot(lags, v[key], color="k", lw=1)
            ax.axhspan(-v["band"], v["band"], color="tab:blue", alpha=0.2, label="95 % band")
            ax.set_title(f"{title}: {c}", fontsize=9)
            ax.set_xlabel("lag [s]")
            ax.set_ylabel("correlation [-]", fontsize=8)
    fig.tight_layout()
    files.append(out / "acf_ccf.png")
    fig.savefig(files[-1], dpi=90)
    plt.close(fig)
    # 3. regime heatmap
    reg = d.where.per_region
    if reg:
        keys = list(reg)
        M = np.full((len(keys), 4), np.nan)
        for i, k in enumerate(keys):
            for j, b in enumerate(reg[k][:4]):
                M[i, j] = b["E"]
        fig, ax = plt.subplots(figsize=(6, 0.6 * len(keys) + 1.5))
        im = ax.imshow(M, cmap="viridis", aspect="auto")
        ax.set_yticks(range(len(keys)), keys)
        ax.set_xticks(range(4), ["Q1 (low)", "Q2", "Q3", "Q4 (high)"])
        ax.set_xlabel("quartile of the region's variable [-]")
        ax.set_title("validation error E per operating-region quartile", fontsize=9)
        fig.colorbar(im, ax=ax, label="E [× noise floor]")
        fig.tight_layout()
        files.append(out / "regimes.png")
        fig.savefig(files[-1], dpi=90)
        plt.close(fig)
    # 4. before/after overlays
    fig, axes = plt.subplots(len(d.channels), len(runs), figsize=(5 * len(runs), 2.2 * len(d.channels)), squeeze=False)
    for j, run in enumerate(runs):
        t = np.asarray(run.time)
        for i, c in enumerate(d.channels):
            ax = axes[i, j]
            _, k = CHANNEL_UNITS.get(c, ("-", 1.0))
            meas = np.asarray(run[c]) * k
            before = np.asarray(d.eval_before.simulated[run.name][c]) * k
            after = np.asarray(d.eval_after.simulated[run.name][c]) * k
            ax.plot(t, meas, color="0.6", lw=0.8, label="measured")
            ax.plot(t, before, "--", color="tab:red", lw=1, label="base")
            ax.plot(t, after, color="tab:blue", lw=1, label="+ " + ("+".join(d.selected) or "nothing"))
            # the start each model used (the held-out start rule, :mod:`.start`) and the logged one
            ax.plot(t[0], float(meas[0]), "o", mfc="none", color="k", ms=6, label="logged start")
            ax.plot(t[0], float(before[0]), "x", color="tab:red", ms=6, label="base start")
            ax.plot(t[0], float(after[0]), "+", color="tab:blue", ms=8, label="final start")
            ax.set_ylabel(axis_label(c), fontsize=8)
            if i == 0:
                ax.set_title(f"held-out run {run.name}", fontsize=9)
                ax.legend(fontsize=7)
            if i == len(d.channels) - 1:
                ax.set_xlabel("time [s]")
    bound = (d.start or {}).get("bound_noise_floors")
    fig.suptitle("held-out runs: measured, the base model and the diagnosed model"
                 + (f" (starts: logged ± {bound:g} noise floors)" if bound is not None else ""), fontsize=9)
    fig.tight_layout()
    files.append(out / "overlay.png")
    fig.savefig(files[-1], dpi=90)
    plt.close(fig)
    # 5. shrink waterfall
    fig, ax = plt.subplots(figsize=(5, 3.5))
    levels = [d.E_before] + [s.E_after for s in d.path]
    labels = ["base"] + ["+ " + s.effect for s in d.path]
    for i in range(1, len(levels)):
        ax.bar(i, levels[i - 1] - levels[i], bottom=levels[i], color="tab:green")
    ax.bar(0, levels[0], color="tab:red")
    ax.bar(len(levels), levels[-1], color="tab:blue")
    ax.axhline(1.0, color="k", ls=":", label="noise floor")
    ax.set_xticks(range(len(levels) + 1), labels + ["final"], rotation=20, fontsize=8)
    ax.set_ylabel("validation E [× noise floor]")
    ax.set_title("shrink waterfall", fontsize=9)
    ax.legend()
    fig.tight_layout()
    files.append(out / "waterfall.png")
    fig.savefig(files[-1], dpi=90)
    plt.close(fig)
    checks = getattr(d, "in_data", None) or {}
    if checks:
        files.append(plot_data_checks(checks, out / "data_checks.png"))
    return files


def plot_data_checks(checks, path: Path) -> Path:
    """The data-consistency checks (:mod:`.consistency`): per run, the heading bias the track implies
    and the rate bias the heading implies, with the pooled estimate and its 95 % band; the yaw
    equation error against the rudder shift, the shift of least error and the runs' own."""
    from ..figures import pyplot
    from .consistency import shown_unit

    plt = pyplot()

    fig, axes = plt.subplots(1, len(checks), figsize=(5.5 * len(checks), 3.8), squeeze=False)
    for ax, (name, f) in zip(axes[0], checks.items()):
        k, unit = shown_unit(f.unit)
        verdict = "finding" if f.found else "not a finding"
        if f.curve[0]:
            ax.plot(f.curve[0], f.curve[1], color="k", lw=1)
            ax.axvline(f.value, color="C3", lw=1.2, label=f"least error: {f.shown()}")
            ax.axvline(0.0, color="0.6", lw=0.8, ls="--")
            for v in f.per_run.values():
                ax.axvline(v, color="C0", lw=0.6, alpha=0.6, ymax=0.12)
            ax.set_xlabel(f"rudder shift tau [{unit}] (blue ticks: each run's own)")
            ax.set_ylabel(f"training RMS equation error [{f.misfit_unit.split(' ')[0]}]")
        else:
            names = list(f.per_run)
            ax.plot(range(len(names)), [k * v for v in f.per_run.values()], "o", color="C0")
            ax.axhline(k * f.value, color="C3", lw=1.2, label=f"pooled: {f.shown()}")
            h = k * f.half95()
            if np.isfinite(h):
                ax.axhspan(k * f.value - h, k * f.value + h, color="C3", alpha=0.15)
            ax.axhline(0.0, color="0.6", lw=0.8, ls="--")
            ax.set_xticks(range(len(names)), names, rotation=30, ha="right", fontsize=7)
            ax.set_ylabel(f"{f.parameter} [{unit}]")
        ax.set_title(f"{name}: {verdict}\nheld-out misfit {f.heldout[0]:.3g} → {f.heldout[1]:.3g}", fontsize=9)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, float)):
        v = float(x)
        return v if math.isfinite(v) else None
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    return x


def write_json(d, path) -> None:
    Path(path).write_text(json.dumps(_jsonable(d.to_dict()), indent=1))


def write_report(d, out) -> list[Path]:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "diagnosis.md").write_text(to_markdown(d))
    write_json(d, out / "diagnosis.json")
    return [out / "diagnosis.md", out / "diagnosis.json"] + plot_all(d, out)
