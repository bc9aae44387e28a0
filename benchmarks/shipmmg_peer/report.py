"""The report of the shipmmg peer benchmark: figure, verdict and Markdown tables.

:func:`report` writes ``results/shipmmg_peer[_quick].md`` from the rows of
:func:`benchmarks.shipmmg_peer.main` (one per fitted variant, judged by :func:`.judge.judge`);
:func:`verdict` states the benchmark's criterion (no blow-up in a 35° turn, tactical diameter within
5 % of the peer's) and the diagnosis from the numbers; :func:`figure` draws the turning tracks
and the held-out 20/20 heading.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .data import HELM_RATE_DEG_S, MODEL_TEST_NOISE, U0
from .judge import CHANNELS, FIT_DT, MAX_STEPS, partial_turn


def _fmt(v, spec=".1f"):
    return "–" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, spec)


def figure(path: Path, peer: dict, rows: list[dict]) -> None:
    """Turning tracks (both sides) and the held-out 20/20 heading: one row of panels per group of fits."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups = [[r for r in rows if r["group"] in ("reference", "main")], [r for r in rows if r["group"] == "remedy"]]
    groups = [g for g in groups if g]
    fig, axes = plt.subplots(len(groups), 3, figsize=(19, 5.2 * len(groups)), squeeze=False)
    for gi, (group, ax_row) in enumerate(zip(groups, axes)):
        colours = plt.cm.tab10(np.linspace(0, 1, 10))
        for ax, key in zip(ax_row[:2], ("turnS", "turnP")):
            c = peer[key]["channels"]
            ax.plot(c["y0"] / 7.0, c["x0"] / 7.0, "k", lw=2.5, label="shipmmg (peer)")
            for k, row in enumerate(group):
                lab = row["label"] if row["group"] != "remedy" else row["remedy"]
                run = row.get(f"{key}_run")
                if run is not None:
                    ax.plot(run["y0"] / 7.0, run["x0"] / 7.0, lw=1, color=colours[k % 10], label=lab)
                elif row.get("model") is not None:
                    x, y, t_bad = partial_turn(row["model"], peer[key], row["n"])
                    ax.plot(y / 7.0, x / 7.0, lw=1, ls=":", color=colours[k % 10],
                            label=f"{lab} (blows up at {t_bad:.0f} s)")
                    ax.plot(y[-1:] / 7.0, x[-1:] / 7.0, "x", color=colours[k % 10])
            ax.set(xlabel="y0 / L (starboard)", ylabel="x0 / L (approach course)", aspect="equal",
                   title=f"35° turning circle, {'starboard' if key == 'turnS' else 'port'}"
                   + (" — fits" if gi == 0 else " — remedies (clean data, priors on)"))
            ax.legend(fontsize=6, loc="lower left" if key == "turnS" else "lower right")
        c = peer["zz20P"]["channels"]
        ax_row[2].plot(c["time"], np.degrees(c["psi"]), "k", lw=2.5, label="shipmmg (peer)")
        for k, row in enumerate(group):
            run = row.get("zz20P_run")
            if run is not None:
                ax_row[2].plot(run.time, np.degrees(run["psi"]), lw=1, color=colours[k % 10])
        ax_row[2].set(xlabel="t [s]", ylabel="ψ [°]", title="held-out 20/20 zigzag, port first (closed loop)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _row_cells(r: dict) -> list[str]:
    f = r.get("fit") or {}
    par = f.get("params", {})
    adm = "ADMISSIBLE" if r["admissible"] else "NOT admissible" + (f" ({', '.join(r['offending'])})"
                                                                  if r["offending"] else "")
    return [_fmt(r["turnS_TD_err_pct"], "+.1f"), _fmt(r["turnP_TD_err_pct"], "+.1f"),
            _fmt(r["turnS_advance_err_pct"], "+.1f"), _fmt(r["turnP_advance_err_pct"], "+.1f"),
            "**yes**" if r["blowup"] else "no", adm,
            f"{_fmt(r['zz10P_os1_err'], '+.2f')} / {_fmt(r['zz10P_os2_err'], '+.2f')}",
            f"{_fmt(r['zz20P_os1_err'], '+.2f')} / {_fmt(r['zz20P_os2_err'], '+.2f')}",
            _fmt(par.get("Nrrr", -0.013), "+.4f"), _fmt(par.get("Nvvr", -0.294), "+.3f"),
            _fmt(f.get("rp_crit", math.inf), ".2f") if f else "∞"]


_HEAD = ("| TD err S % | TD err P % | adv. err S % | adv. err P % | blow-up in 35° turn | admissibility | "
         "held-out 10/10 P: Δ1st / Δ2nd overshoot [°] | held-out 20/20 P: Δ1st / Δ2nd [°] | N'_rrr | N'_vvr | "
         "r'_crit |")


def _meets(r: dict) -> bool:
    """The criterion: no blow-up in the 35° turns, TD within 5 % of the peer's on both sides."""
    return (not r["blowup"]) and all(abs(r[f"{k}_TD_err_pct"]) <= 5.0 for k in ("turnS", "turnP"))


def max_rprime(recs) -> float:
    """Largest non-dimensional yaw rate |r| L / U over peer records (L = 7 m, U midship speed)."""
    return max(float(np.max(np.abs(c["r"]) * 7.0 / np.hypot(c["u"], c["v"]))) for c in (r["channels"] for r in recs))


def verdict(rows: list[dict], rp: dict[str, float] | None = None) -> list[str]:
    """The verdict on the criterion and the diagnosis, from the numbers."""
    L = ["## Verdict (no blow-up in a 35° turn, tactical diameter within 5 % of the peer's)", ""]
    dflt = [r for r in rows if r["group"] == "main" and r["free"] == "default" and r["priors"]]
    for r in dflt + [r for r in rows if r["group"] == "main" and r["free"] == "study" and r["priors"]]:
        L.append(f"- {r['free']} free set, default priors, noise {r['noise']}: "
                 + ("blows up in the 35° turn" if r["blowup"] else
                    f"TD error {r['turnS_TD_err_pct']:+.1f} % (S) / {r['turnP_TD_err_pct']:+.1f} % (P)")
                 + f" → **{'MET' if _meets(r) else 'NOT MET'}**; admissibility check: "
                 + ("admissible" if r["admissible"] else "NOT admissible, offending " + ", ".join(r["offending"])))
    clean = next((r for r in dflt if r["noise"] == "none"), None)
    if clean is None:
        return L
    f = clean["fit"]
    z = dict(f["far_from_prior"]).get("Nrrr", math.nan)
    tau = float(np.median(list(f["tau"].values())))
    if f["params"]["Nrrr"] < 0:
        return L + ["", "## Why", "",
                    f"- **No blow-up.** N'_rrr stays negative ({f['params']['Nrrr']:+.4f}: the MMG's damping "
                    "derivatives are bounded ≤ 0, and with priors the data are weighted by their effective sample "
                    f"size; residual memory τ ≈ {tau:.0f} samples).",
                    "- **The remaining tactical-diameter error is structural**: the peer's wake (exp(−4β_P²), "
                    "drift at −x_G) differs from Yasukawa's C1/C2± wake. The ten-parameter default set cannot absorb "
                    "it; freeing the wake's manoeuvring correction (the `study` free set of "
                    "`diffship.studies.kvlcc2`, 33 coefficients under their priors, or `wake C1, C2± free` below) "
                    "does."]
    L += ["", "## Why", "",
          (f"- **N'_rrr turns positive.** The clean default-prior fit moves N'_rrr from −0.013 to "
          f"{f['params']['Nrrr']:+.4f} ({z:+.1f} prior SDs), so the hull's yaw damping N'_r + 3N'_rrr r'² changes "
          f"sign at r' = {f['rp_crit']:.2f}; the peer's 35° turns reach r' = {rp['turn']:.2f}, the training zigzags "
          f"{rp['train']:.2f}. "
          "The identifiability report finds no poorly identified direction (condition number "
          f"{f['condition'] if isinstance(f['condition'], str) else format(f['condition'], '.3g')}) but warns "
          f"of the sign flip ({', '.join(f['sign_flips'])}) and the distance from the prior; the admissibility "
          f"check fails r-motion self-damping and names {', '.join(clean['offending'])}."),
          ("- **It is not noise and not a lack of data: the data pull it there.** The peer and diffship's MMG "
          "differ in structure (module docstring: drift angle at −x_G, a symmetric wake exp(−4β_P²) against "
          "Yasukawa's C1/C2± wake, x_G, k_zz, x'_P), and N'_rrr (with N'_vvr, J'_z) absorbs that misfit on the "
          "zigzags. Without priors the same happens, further."),
          (f"- **Why the ±50 % priors lose.** The fit weighs its residuals as independent, but the residuals of a "
          f"structural misfit have memory: integrated autocorrelation time τ ≈ {tau:.0f} samples "
          f"({', '.join(f'{c} {t:.0f}' for c, t in f['tau'].items())}), so the data are over-counted about "
          f"{tau:.0f}-fold against the priors and a ±50 % prior acts like ±{50 * math.sqrt(tau):.0f} %.")]
    rem = [r for r in rows if r["group"] == "remedy"]
    if rem:
        ok = [r["remedy"] for r in rem if _meets(r) and r["admissible"]]
        L += [(f"- **What fixes it** (table below; same clean data): meeting the target *and* admissible: "
              f"{'; '.join(ok) or 'none of the changes tried'}.")]
        for r in rem:
            L.append(f"  - {r['remedy']}: " + ("blows up" if r["blowup"] else
                     f"TD {r['turnS_TD_err_pct']:+.1f} / {r['turnP_TD_err_pct']:+.1f} %")
                     + f", {'admissible' if r['admissible'] else 'not admissible'}")
    return L + [""]


def report(rows: list[dict], pm: dict, n: float, *, quick: bool, wall: float, version: str,
           rp: dict[str, float]) -> str:
    main_rows = [r for r in rows if r["group"] in ("reference", "main")]
    rem = [r for r in rows if r["group"] == "remedy"]
    train = next((r["train"] for r in rows if r["group"] == "main"), ())
    L = [f"# shipmmg peer: fit diffship's MMG on another implementation's zigzags{' (quick)' if quick else ''}", "",
         (f"Command: `python -m benchmarks shipmmg_peer{' --quick' if quick else ''}`; wall time "
         f"{wall / 60:.1f} min on a shared 2-core machine (timings disturbed by other sessions). Peer: shipmmg "
         f"{version} with its own KVLCC2 L7 parameters and simulators (module docstring of "
         "`benchmarks/shipmmg_peer/data.py`: conventions, conversions, structural differences)."), "",
         (f"Model scale L = 7 m, U0 = {U0} m/s, propeller {n:.3f} rev/s (the peer's self-propulsion point at U0), "
         f"helm {HELM_RATE_DEG_S} °/s. Training zigzags (first rudder to starboard): {', '.join(train)}. "
         f"Fit: output error on {', '.join(CHANNELS)} resampled to {FIT_DT} s, {MAX_STEPS} LM steps per pass. "
         f"Model-test noise: {', '.join(f'{k} {v:.3g}' for k, v in MODEL_TEST_NOISE.items())} (SI, rad), white, one seed per noisy variant (`model-test`, `#2`, `#3`: different seeds)."), "",
         *verdict(rows, rp),
         "## Peer's own manoeuvres (the truth)", "",
         "| manoeuvre | tactical diameter | advance | 1st overshoot | 2nd overshoot |", "|---|---|---|---|---|"]
    for k, m in pm.items():
        L.append(f"| {k} | {_fmt(m.get('TD'), '.2f')} m ({_fmt(m.get('TD', math.nan) / 7.0, '.2f')} L) | "
                 f"{_fmt(m.get('advance'), '.2f')} m | {_fmt(m.get('os1'), '.2f')}° | {_fmt(m.get('os2'), '.2f')}° |")
    L += ["", "## Fits on the zigzags, judged on the 35° turns and held-out zigzags", "",
          ("Errors are diffship − peer (TD, advance in % of the peer's; overshoots in degrees). `reference` is "
          "diffship's KVLCC2 L7 model with the published coefficients, not fitted. r'_crit: the "
          "non-dimensional yaw rate above which the fitted hull's yaw damping ∂N'_H/∂r' = N'_r + 3N'_rrr r'² "
          f"(v' = 0) turns positive (the peer's 35° turns reach r' = {rp['turn']:.2f})."), "",
          "| free set | priors | noise " + _HEAD, "|---" * 14 + "|"]
    for r in main_rows:
        pri = "–" if r["group"] == "reference" else ("reference ±50 %" if r["priors"] else "off")
        L.append(f"| {r.get('free', 'none (published)')} | {pri} | {r.get('noise', '–')} | "
                 + " | ".join(_row_cells(r)) + " |")
    if rem:
        L += ["", "## What would fix the default-prior fit (same clean training data, default free set, priors on)", "",
              "| change " + _HEAD, "|---" * 12 + "|"]
        for r in rem:
            L.append(f"| {r['remedy']} | " + " | ".join(_row_cells(r)) + " |")
    L += ["", "## Fits in detail", ""]
    for r in rows:
        f = r.get("fit")
        if not f:
            continue
        par = ", ".join(f"{k} {v:+.4g}" for k, v in f["params"].items())
        far = ", ".join(f"{k} {z:+.1f} σ" for k, z in f["far_from_prior"]) or "–"
        L += [f"### {r['label']}", "",
              (f"- fit: {f['status']} after {f['iterations']} steps, {f['fit_s']:.0f} s (+ compile {f['compile_s']:.0f} s); "
              f"{f['prior_note']}"),
              f"- parameters: {par}",
              (f"- furthest from the prior mean (in prior SDs): {far}; sign flips against the reference: "
              f"{', '.join(f['sign_flips']) or 'none'}; condition number {_fmt(f['condition'], '.3g') if isinstance(f['condition'], float) else f['condition']}"),
              f"- poorly identified directions (identifiability report): {'; '.join(f['weak']) or 'none'}",
              "- residual autocorrelation time τ [samples of 0.2 s] (data over-counted ≈τ-fold against the priors): "
              + ", ".join(f"{c} {t:.0f}" for c, t in f["tau"].items()),
              "", "```", r["admissibility"], "```", ""]
    return "\n".join(L) + "\n"
