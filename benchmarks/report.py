"""The suite's report: ``report*.md`` (headline table first, then one table per case) and the figures.

* :func:`headline` — the headline rows: speed ratio scipy/diffship output error at equal final
  cost (warm and including compilation), the EE/OE parameter-error ratio over noise seeds, the
  fossen3_speed.py reference, batched time per fit, the GPU line;
* :func:`figures` — ``fig_*.png``: parameter error vs noise, the Nomoto sweeps, wall time per
  method (compilation shaded), batched vs looped time per fit;
* :func:`write_report` — the Markdown report from a :class:`benchmarks.record.Recorder`.

Everything here reads the recorder only (``--report-only`` rewrites the report from the CSV).
"""

from __future__ import annotations

import csv
import math
import os
from pathlib import Path

import jax
import numpy as np

from benchmarks.record import METHODS, seed_stats

#: identical methods overlap (OE = scipy at equal cost, EE = OLS for Nomoto): different line styles keep both visible
STYLE = {"diffship_oe": dict(marker="o", ls="-", ms=7), "scipy_lm_numpy_rk4": dict(marker="x", ls="--", ms=9),
         "diffship_ee": dict(marker="s", ls="-", ms=7, mfc="none"), "numpy_ols": dict(marker="+", ls=":", ms=10),
         "stlsq_sindy": dict(marker="^", ls="-.", ms=6)}
LABEL = {"diffship_oe": "diffship output error", "diffship_ee": "diffship equation error",
         "scipy_lm_numpy_rk4": "scipy least_squares + NumPy RK4", "numpy_ols": "NumPy OLS (inverse dynamics)",
         "stlsq_sindy": "STLSQ sparse regression (SINDy)"}


def headline(rec):
    """Headline rows: (quantity, value, how)."""
    rows = []
    for case, variant in (("fossen3_usv", "noise=realistic"), ("nomoto_linear", "noise=realistic")):
        # warm: the 2nd call on these data (or the 1st, if compilation was paid on an earlier variant);
        # cold: the case's first call, the one that paid the compilation (same shapes, same problem size)
        oe_w = rec.get(case, variant, "diffship_oe", "warm_wall_s")
        if not math.isfinite(oe_w) and rec.get(case, variant, "diffship_oe", "compile_s") == 0.0:
            oe_w = rec.get(case, variant, "diffship_oe", "wall_s")
        firsts = [(r["value"], r["variant"]) for r in rec.rows if r["case"] == case and r["method"] == "diffship_oe"
                  and r["metric"] == "compile_s" and r["variant"].startswith("noise=")]
        oe_c = rec.get(case, max(firsts)[1], "diffship_oe", "wall_s") if firsts else math.nan
        sp_t = rec.get(case, variant, "scipy_lm_numpy_rk4", "time_to_oe_cost_s")
        sp_wall = rec.get(case, variant, "scipy_lm_numpy_rk4", "wall_s")
        if not math.isfinite(oe_c):
            continue
        lower = not math.isfinite(sp_t)
        ref = sp_wall if lower else sp_t
        if not math.isfinite(ref):
            continue
        tag = "≥ " if lower else ""
        rows.append((f"Speed ratio scipy/diffship OE at equal final cost, warm ({case})", f"{tag}{ref / oe_w:.3g}×",
                     f"scipy time to reach within 1 % of diffship's cost {ref:.2f} s / diffship warm fit {oe_w:.2f} s"
                     + (" (scipy never got there: lower bound)" if lower else "")))
        rows.append((f"Speed ratio scipy/diffship OE at equal final cost, incl. compilation ({case})",
                     f"{tag}{ref / oe_c:.3g}×", f"{ref:.2f} s / diffship first call {oe_c:.2f} s"))
    for case in ("fossen3_usv", "nomoto_linear"):
        st = {m: seed_stats(rec, case, m) for m in ("diffship_ee", "diffship_oe")}
        if all(v[2] for v in st.values()):
            (mx_ee, rms_ee, n), (mx_oe, rms_oe, _) = st["diffship_ee"], st["diffship_oe"]
            rows.append((f"Parameter-error ratio EE/OE at realistic noise ({case})",
                         f"{rms_ee / rms_oe:.1f}× (RMS), {mx_ee / mx_oe:.1f}× (max)",
                         f"relative parameter errors, mean over {n} noise seeds: RMS over parameters EE {rms_ee:.1%} vs "
                         f"OE {rms_oe:.1%}; worst parameter EE {mx_ee:.1%} vs OE {mx_oe:.1%}"))
    ref = Path(__file__).resolve().parent / "results" / "fossen3_speed.csv"
    if ref.exists():
        with open(ref) as fh:
            rr = list(csv.DictReader(fh))
        try:
            same = str(rr[0].get("same_cost_1pct", "")).lower() in ("true", "1", "yes")
            bound = "" if same else "≥ "
            rows.append(("Reference: fossen3 3 runs × 300 s (benchmarks/fossen3_speed.py, not rerun here)",
                         f"{bound}{float(rr[0]['ratio_scipy_over_diffship_warm']):.0f}× warm, "
                         f"{bound}{float(rr[0]['ratio_scipy_over_diffship_cold']):.1f}× incl. compilation",
                         "same final cost reached by both" if same else
                         "scipy stopped by its 600 s guard far above diffship's cost: lower bounds"))
        except (KeyError, ValueError, IndexError):
            pass
    case = "nomoto_linear"
    lp = rec.get(case, "batch", "diffship_oe", "loop_fit_output_error_time_per_fit_s")
    vm = rec.get(case, "batch", "diffship_oe", "vmap_lm_time_per_fit_s")
    jl = rec.get(case, "batch", "diffship_oe", "jit_lm_loop_time_per_fit_s")
    n = rec.get(case, "batch", "diffship_oe", "n_batch")
    if math.isfinite(vm):
        rows.append(("Batched OE time per fit (vmap over starts, Nomoto)", f"{vm * 1e3:.1f} ms",
                     f"{n:.0f} starts in one vmapped fixed-iteration LM; same LM looped: {jl * 1e3:.1f} ms/fit; "
                     f"diffship fit_output_error looped: {lp * 1e3:.1f} ms/fit"))
        bb = rec.get(case, "batch", "diffship_ee", "vmap_bootstrap_time_per_fit_s")
        bn = rec.get(case, "batch", "numpy_ols", "loop_bootstrap_time_per_fit_s")
        rows.append(("Batched EE bootstrap time per fit (vmap, Nomoto)", f"{bb * 1e6:.1f} µs",
                     f"NumPy lstsq loop: {bn * 1e6:.1f} µs/fit"))
    rows.append(("GPU run", "not run", "no GPU is available in this session (CPU only, jax backend "
                 f"'{jax.default_backend()}')"))
    return rows


def method_table(rec, case, variant, metrics):
    methods = [m for m in METHODS if any(r["case"] == case and r["variant"] == variant and r["method"] == m
                                         for r in rec.rows)]
    if not methods:
        return []
    out = ["| method | " + " | ".join(metrics) + " |", "|---|" + "---:|" * len(metrics)]
    for m in methods:
        cells = []
        for k in metrics:
            v = rec.get(case, variant, m, k)
            cells.append("–" if not math.isfinite(v) else (f"{v:.3g}" if abs(v) < 1e4 else f"{v:.3e}"))
        out.append(f"| {LABEL[m]} | " + " | ".join(cells) + " |")
    return out


def _first_call_variant(rec, case, default):
    """The variant whose diffship OE call paid the compilation (the case's first call)."""
    firsts = [(r["value"], r["variant"]) for r in rec.rows if r["case"] == case and r["method"] == "diffship_oe"
              and r["metric"] == "compile_s"]
    return max(firsts)[1] if firsts else default


def figures(rec, out_dir, prefix):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    made = []
    # 1. parameter error vs noise
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    for ax, case in zip(axes, ("nomoto_linear", "nomoto_cubic_truth", "fossen3_usv")):
        for m in METHODS:
            xs, ys = [], []
            for i, lv in enumerate(("none", "realistic", "high")):
                v = rec.get(case, f"noise={lv}", m, "max_rel_param_err")
                if math.isfinite(v):
                    xs.append(i); ys.append(max(v, 1e-6))
            if xs:
                ax.semilogy(xs, ys, label=LABEL[m], **STYLE[m])
        ax.set_xticks([0, 1, 2], ["none", "realistic", "3× realistic"])
        ax.set_xlabel("measurement noise")
        ax.set_ylabel("max |relative parameter error|")
        ax.set_title(case)
        ax.grid(True, which="both", alpha=0.3)
    if axes[0].get_legend_handles_labels()[0]:
        axes[0].legend(fontsize=7)
    fig.tight_layout()
    p = out_dir / f"{prefix}param_error_vs_noise.png"
    fig.savefig(p, dpi=110); plt.close(fig); made.append(p)
    # 2. sweeps: parameter error and validation NRMSE of r
    fig, axes = plt.subplots(2, 3, figsize=(13, 7), sharex="col")
    for j, (kind, xl) in enumerate((("dt", "sample interval [s]"), ("duration", "run length [s]"),
                                    ("delay", "unmodelled input delay [s]"))):
        vals = sorted({float(r["variant"].split("=")[1]) for r in rec.rows
                       if r["case"] == "nomoto_linear" and r["variant"].startswith(kind + "=")})
        for i, (metric, yl) in enumerate((("max_rel_param_err", "max |relative parameter error|"),
                                          ("val_nrmse_r", "validation NRMSE of r [-]"))):
            ax = axes[i, j]
            for m in METHODS:
                ys = [rec.get("nomoto_linear", f"{kind}={v:g}", m, metric) for v in vals]
                if any(math.isfinite(y) for y in ys):
                    (ax.semilogy if i == 0 else ax.plot)(vals, ys, label=LABEL[m], **STYLE[m])
            ax.set_ylabel(yl)
            ax.grid(True, which="both", alpha=0.3)
            if i == 0:
                ax.set_title(f"Nomoto, realistic noise: {kind} sweep")
            else:
                ax.set_xlabel(xl)
    if axes[0, 0].get_legend_handles_labels()[0]:
        axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    p = out_dir / f"{prefix}sweeps.png"
    fig.savefig(p, dpi=110); plt.close(fig); made.append(p)
    # 3. wall times
    fig, ax = plt.subplots(figsize=(9, 4))
    cases = [("nomoto_linear", "noise=realistic"), ("fossen3_usv", "noise=realistic"), ("sspa_zigzag_real", "train=first25s")]
    w = 0.15
    for j, m in enumerate(METHODS):
        vv = [_first_call_variant(rec, c, v) if m == "diffship_oe" else v for c, v in cases]
        comp = [rec.get(c, v, m, "compile_s") for (c, _), v in zip(cases, vv)]
        tot = [rec.get(c, v, m, "wall_s") for (c, _), v in zip(cases, vv)]
        x = np.arange(len(cases)) + (j - 2) * w
        fitp = [t - c if math.isfinite(t) and math.isfinite(c) else t for t, c in zip(tot, comp)]
        ax.bar(x, np.nan_to_num(fitp), w, label=f"{LABEL[m]} (fit)")
        ax.bar(x, np.nan_to_num(comp), w, bottom=np.nan_to_num(fitp), color="0.7", edgecolor="k", linewidth=0.3)
    ax.set_yscale("log")
    ax.set_xticks(range(len(cases)), [c for c, _ in cases])
    ax.set_ylabel("wall time [s] (grey: compilation)")
    ax.set_ylim(bottom=1e-3)
    ax.set_title("Wall time per fit, realistic noise (diffship OE: the case's first call; grey: compilation)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    p = out_dir / f"{prefix}wall_time.png"
    fig.savefig(p, dpi=110); plt.close(fig); made.append(p)
    # 4. batch
    keys = [("diffship_oe", "loop_fit_output_error_time_per_fit_s", "fit_output_error loop"),
            ("diffship_oe", "jit_lm_loop_time_per_fit_s", "jitted LM, loop"),
            ("diffship_oe", "vmap_lm_time_per_fit_s", "jitted LM, vmap"),
            ("diffship_ee", "loop_fit_equation_error_time_per_fit_s", "fit_equation_error loop"),
            ("numpy_ols", "loop_bootstrap_time_per_fit_s", "EE bootstrap, NumPy loop"),
            ("diffship_ee", "vmap_bootstrap_time_per_fit_s", "EE bootstrap, vmap")]
    vals = [rec.get("nomoto_linear", "batch", m, k) for m, k, _ in keys]
    if any(math.isfinite(v) for v in vals):
        fig, ax = plt.subplots(figsize=(8, 3.8))
        ax.barh([lbl for *_, lbl in keys], np.nan_to_num(vals))
        ax.set_xscale("log")
        ax.set_xlabel("time per fit [s]")
        ax.set_title("Nomoto: batched (vmap) vs looped fits, CPU")
        fig.tight_layout()
        p = out_dir / f"{prefix}batch_time_per_fit.png"
        fig.savefig(p, dpi=110); plt.close(fig); made.append(p)
    return made


def write_report(rec, out_dir, stem, quick, cases_run, total_s, figs, env):
    L = [f"# diffship benchmark report ({'quick' if quick else 'full'} mode)", "",
         f"Regenerate: `python -m benchmarks suite{' --quick' if quick else ''}` "
         f"(total {total_s / 60:.1f} min on this machine). Every number below is also in `{stem.replace('report', 'all_numbers')}.csv`.",
         "", "## Headline", "", "| quantity | value | how |", "|---|---:|---|"]
    for q, v, how in headline(rec):
        L.append(f"| {q} | {v} | {how} |")
    L += ["", "How to read it: speed ratios compare diffship output error and scipy `least_squares` on the "
          "*identical* problem (same data, start, scaled parameters, channel-spread weights, estimated initial "
          "states; the NumPy residual at diffship's solution reproduces diffship's cost), timing scipy until its "
          "best cost first came within 1 % of diffship's final cost. Warm = diffship already compiled for this "
          "problem size; incl. compilation = the first call of the case. Parameter-error ratios are means over "
          "noise seeds with diffship's default noise weighting for output error; the per-case tables below are "
          "single draws.", ""]
    L += ["**Timing caveat:** measured on a shared 2-core machine with other jobs running (load average "
          f"{os.getloadavg()[0]:.1f} at the end); wall times are noisy, ratios more robust than absolute seconds.", ""]
    common = ["max_rel_param_err", "val_nrmse_psi", "val_nrmse_r", "err_overshoot1_10_10", "err_overshoot1_20_20",
              "compile_s", "wall_s", "cost"]
    sections = [
        ("nomoto_linear", ["noise=none", "noise=realistic", "noise=high"], "Nomoto (linear truth K=0.2/s, T=8 s, δ0=0.01)"),
        ("nomoto_cubic_truth", ["noise=none", "noise=realistic", "noise=high"],
         "Nonlinear Nomoto truth (T ṙ + r + a r³ = Kδ, a = 50 s²) fitted with the linear Nomoto model"),
        ("fossen3_usv", ["noise=none", "noise=realistic", "noise=high"], "Fossen 3-DOF USV (10 free parameters)"),
        ("vmm_linear_ship", ["noise=realistic"], "VMM linear ship (prime system), zigzags with thrust steps"),
        ("fossen6_rov", ["noise=realistic"], "Fossen 6-DOF ROV (BlueROV2 Heavy)"),
        ("sspa_zigzag_real", ["train=first25s"], "Real: SSPA 20/20 zigzag (train on the first 25 s, validate on the whole run)"),
    ]
    for case, variants, title in sections:
        if not any(r["case"] == case for r in rec.rows):
            continue
        L += [f"## {title}", ""]
        for v in variants:
            extra = ["time_to_oe_cost_s"] if case in ("fossen3_usv", "nomoto_linear") and v == "noise=realistic" else []
            if case == "vmm_linear_ship":
                extra = ["err_overshoot2_10_10", "err_overshoot2_20_20", "rel_err_tactical_diameter", "rel_err_advance",
                         "val_nrmse_u", "val_nrmse_v"]
            if case == "fossen3_usv":
                extra = ["val_nrmse_u", "val_nrmse_v"] + extra
            if case == "nomoto_cubic_truth":
                extra = ["rel_err_a", "cubic_term_kept"]
            t = method_table(rec, case, v, common + extra)
            if t:
                L += [f"**{v}**", ""] + t + [""]
        conv = [r for r in rec.rows if r["case"] == case and r["metric"] == "convergence_rate" and r["method"] in METHODS]
        if conv:
            L += ["Convergence from N random starts (log-uniform ×0.3…×3 of the truth; converged = final cost within "
                  "1 % of the best cost any start reached):", ""]
            for r in conv:
                tps = rec.get(case, r["variant"], r["method"], "mean_time_per_start_s")
                L.append(f"* {LABEL[r['method']]}: {r['value']:.0%} of {rec.get(case, r['variant'], r['method'], 'n_starts'):.0f} "
                         f"starts, {tps:.2f} s per start")
            L.append("")
    # sweeps
    sw = sorted({r["variant"] for r in rec.rows if r["case"] == "nomoto_linear"
                 and r["variant"].split("=")[0] in ("dt", "duration", "delay")},
                key=lambda s: (s.split("=")[0], float(s.split("=")[1])))
    if sw:
        L += ["## Sweeps (Nomoto, realistic noise): sample interval, run length, unmodelled input delay", "",
              "Max relative parameter error / validation NRMSE of r (whole-run simulation of held-out manoeuvres):", "",
              "| variant | " + " | ".join(LABEL[m] for m in METHODS) + " |", "|---|" + "---:|" * len(METHODS)]
        for v in sw:
            cells = []
            for m in METHODS:
                a = rec.get("nomoto_linear", v, m, "max_rel_param_err")
                b = rec.get("nomoto_linear", v, m, "val_nrmse_r")
                cells.append(f"{a:.3g} / {b:.3g}" if math.isfinite(a) else "–")
            L.append(f"| {v} | " + " | ".join(cells) + " |")
        L.append("")
    # kvlcc2
    kv = [r for r in rec.rows if r["case"] == "kvlcc2_hsva_real"]
    if kv:
        L += ["## Real: KVLCC2 HSVA zigzags (MMG, diffship.studies.kvlcc2)", ""]
        for r in kv:
            L.append(f"* {r['method']} {r['metric']}: {r['value']:.4g} {r['unit']} {r['note']}")
        L.append("")
    # batch
    b = [r for r in rec.rows if r["variant"] == "batch"]
    if b:
        L += ["## Scale: vmapped batches vs loops (Nomoto, CPU)", "", "| method | quantity | value | note |", "|---|---|---:|---|"]
        for r in b:
            L.append(f"| {r['method']} | {r['metric']} | {r['value']:.4g} {r['unit']} | {r['note']} |")
        L += ["", "On CPU, vmapping whole LM fits batches the small linear solves but every start runs the full "
              "fixed number of iterations (no early exit per start), so time per fit can be worse than a loop of "
              "adaptive fits; the numbers above are measured, not assumed. No GPU run: no GPU is available in "
              "this session.", ""]
    # memory
    L += ["## Memory", "",
          "* `process_max_rss_mb`: `resource.getrusage(RUSAGE_SELF).ru_maxrss` after the method — the whole "
          "process's high-water mark (monotone: includes JAX/XLA and everything run before), so it is an upper bound.",
          "* `tracemalloc_peak_mb`: Python/NumPy allocations traced by `tracemalloc` for the NumPy peers only "
          "(scipy: one LM iteration incl. one finite-difference Jacobian, which is the peak working set; OLS: the "
          "regression). tracemalloc does not see XLA buffers, so it is not used for the JAX methods.", ""]
    for case in ("nomoto_linear", "fossen3_usv"):
        for m in METHODS:
            for k in ("tracemalloc_peak_mb", "process_max_rss_mb"):
                v = rec.get(case, "noise=realistic", m, k)
                if math.isfinite(v):
                    L.append(f"* {case} / {LABEL[m]}: {k} = {v:.1f} MB")
    L += ["", "## Figures", ""] + [f"![{p.stem}]({p.name})" for p in figs]
    L += ["", "## Environment", "", f"* cases run: {', '.join(cases_run)}",
          f"* {env}", "* methods: see `benchmarks/README.md`. STLSQ is a NumPy re-implementation of SINDy's "
          "sequentially thresholded least squares (pysindy needs scikit-learn, not installed here); statsmodels "
          "is not installed, NumPy `lstsq` gives the same OLS estimates."]
    (out_dir / f"{stem}.md").write_text("\n".join(L) + "\n")
