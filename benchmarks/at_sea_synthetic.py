"""At sea, synthetic: an autopilot in narrow-band waves; output error against prediction error, the loop test.

Independent truths (:mod:`benchmarks.independent.autopilot_waves`, NumPy only): a first-order Nomoto ship (K 0.08 1/s,
T 20 s, δ0 0.5°) steered by a PD autopilot with course changes, in a wave yaw disturbance of period 8 s (relative
damping 0.08, sd 0.004 rad/s²) with a random phase per run; four runs × 600 s at 2 Hz per seed, heading and yaw-rate
channels. Cases: ``waves`` (the autopilot in waves), ``calm`` (the same autopilot, no waves), ``open`` (waves,
the rudder a pre-drawn sequence: no feedback). Per seed and case (3 training runs, 1 held out):

* output error (the default fit) and prediction error with the Ornstein–Uhlenbeck disturbance: K, T1 with
  standard errors and their z against the truth; the closed-loop test (:mod:`diffship.fit.feedback`) on the
  output-error fit's errors;
* the diagnosis (:func:`diffship.diagnose.diagnose`) with its sea-state check (:mod:`diffship.diagnose.sea_state`:
  prediction error with the ``wave`` disturbance): whether it names the sea state, the wave's period, intensity
  and share of the held-out one-sample error, its K, T1; and what it attributes deterministically.

``python -m benchmarks at_sea_synthetic [--seeds 4] [--cases waves,calm,open]``; writes
``results/at_sea_synthetic.md`` and ``.csv``.

The 3-DOF USV (:func:`~benchmarks.independent.autopilot_waves.usv_autopilot_runs`): ``--usv-seeds 0,1,2
--usv-cases waves,calm`` fits it by output error and runs the sea-state check on each seed and case (minutes
each); every row is kept in ``results/at_sea_usv.jsonl`` (a seed and case run again replaces its row, so seeds can
run in separate processes) and the table of all of them is written to ``results/at_sea_usv.md``.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks.independent.autopilot_waves import autopilot_runs

CASES = {"waves": dict(), "calm": dict(waves=False), "open": dict(open_loop=True)}


def _runs(seed: int, case: str):
    from diffship.data import Run

    g = autopilot_runs(seed, n_runs=4, **CASES[case])
    runs = [Run(x["name"], x["time"], x["channels"], {"source": "benchmarks.independent"}) for x in g]
    return runs[:3], runs[3:], g[0]["truth"]


def one(seed: int, case: str) -> list[dict]:
    from diffship.diagnose import DiagnoseOptions, diagnose
    from diffship.fit import PredictionErrorOptions, fit_output_error, fit_prediction_error
    from diffship.fit.ahead import choose_disturbance
    from diffship.fit.feedback import loop_evidence
    from diffship.metrics import evaluate
    from diffship.models import Nomoto1

    train, val, tv = _runs(seed, case)
    ch = ("psi", "r")
    rows = []

    def row(label, params, stderr, seconds, status, **extra):
        r = dict(seed=seed, case=case, method=label, seconds=seconds, status=status, **extra)
        for n in ("K", "T1"):  # NaN where no estimate was made (the sea-state check ended by its screen)
            v, se = params.get(n, math.nan), stderr.get(n, math.nan)
            r.update({n: v, f"se_{n}": se, f"z_{n}": (v - tv[n]) / se})
        rows.append(r)
        print(f"seed {seed} {case:5s} {label:34s} K {r['K']:.4f} (z {r['z_K']:+.1f})  T1 {r['T1']:.2f} "
              f"(z {r['z_T1']:+.1f})  {seconds:.0f} s {extra}", flush=True)

    t0 = time.perf_counter()
    oe = fit_output_error(Nomoto1(), train, channels=ch, throw=False)
    ev = evaluate(oe.model, train, channels=ch, fitted=oe.channels, scales=oe.channel_scales)
    loop = loop_evidence(oe.model, train, ev, ch)
    row("output error", oe.params, oe.stderr, time.perf_counter() - t0, oe.status, usable=bool(oe.usable),
        closed_loop=loop["closed"], loop_r2=max(t["partial_r2"] for t in loop["tests"]))
    t0 = time.perf_counter()
    pe = fit_prediction_error(Nomoto1(), train, channels=ch, throw=False)
    t_ou = time.perf_counter() - t0
    row("prediction error (ou)", pe.params, pe.stderr, t_ou, pe.status, usable=bool(pe.usable))
    t0 = time.perf_counter()  # --disturbance auto: the wave fitted too, the lower Akaike criterion kept
    pw = fit_prediction_error(Nomoto1(), train, channels=ch, noise=PredictionErrorOptions(disturbance="wave"),
                              throw=False)
    pa = choose_disturbance({"ou": pe, "wave": pw}, train)
    aic = {k: v["aic"] for k, v in pa.info["disturbance_choice"].items()}
    row("prediction error (auto: ou or wave by AIC)", pa.params, pa.stderr, t_ou + time.perf_counter() - t0,
        pa.status, usable=bool(pa.usable), chosen=pa.info["disturbance"], aic_ou_minus_wave=aic["ou"] - aic["wave"])
    t0 = time.perf_counter()
    d = diagnose(Nomoto1(), train, val, options=DiagnoseOptions(channels=ch, sea_state="always"))
    s = d.sea_state
    row("diagnosis: sea state (prediction error, wave)", {n: v[0] for n, v in s.K_T.items()},
        {n: v[1] for n, v in s.K_T.items()}, time.perf_counter() - t0, s.fit.status if s.fit else "",
        sea_state=bool(s.found), wave_period=s.period_s, wave_damping=s.damping, wave_sd=s.intensity.get("r"),
        share_r=s.share.get("r"), attributed="+".join(d.selected) or "none")
    return rows


def usv_one(seed: int, case: str = "waves") -> dict:
    """The 3-DOF USV under its heading autopilot in a 6-s wave, or in calm water (``case="calm"``: the same runs
    without the wave) (:func:`~benchmarks.independent.autopilot_waves.usv_autopilot_runs`; 3 training runs, 1 held
    out): the default output-error fit and the sea-state check."""
    from benchmarks.independent.autopilot_waves import usv_autopilot_runs
    from benchmarks.independent.robust_truths import USV_FREE
    from diffship.data import Run
    from diffship.diagnose.sea_state import sea_state
    from diffship.fit import OutputError, fit
    from diffship.fit.feedback import loop_evidence
    from diffship.metrics import evaluate
    from diffship.models import Fossen3

    g = usv_autopilot_runs(seed, waves=case == "waves")
    tv = g[0]["truth"]
    runs = [Run(x["name"], x["time"], x["channels"], {"source": "benchmarks.independent"}) for x in g]
    train, val = runs[:3], runs[3:]
    model = Fossen3(m=tv["m"], Iz=tv["Iz"])
    ch = ("psi", "u", "v", "r")
    t0 = time.perf_counter()
    oe = fit(model, train, OutputError(reference_priors=False), spec=model.spec().only_free(USV_FREE), channels=ch,
             throw=False)
    t_oe = time.perf_counter() - t0
    ev = evaluate(oe.model, train, channels=ch, fitted=oe.channels, scales=oe.channel_scales)
    loop = loop_evidence(oe.model, train, ev, ch)
    s = sea_state(oe, train, val, ch)

    def err(vals):
        return {n: (vals[n][0] - tv[n]) / abs(tv[n]) for n in USV_FREE}, {n: (vals[n][0] - tv[n]) / vals[n][1]
                                                                         for n in USV_FREE}
    oe_rel, oe_z = err({n: (oe.params[n], oe.stderr[n]) for n in USV_FREE})
    pe_rel, pe_z = err({n: s.K_T.get(n, (math.nan, math.nan)) for n in USV_FREE})  # NaN: ended by the screen
    return dict(seed=seed, case=case, closed=loop["closed"], oe_rel=oe_rel, oe_z=oe_z, oe_s=t_oe, found=s.found,
                period=s.period_s, damping=s.damping, sd_v=s.intensity.get("v"), sd_r=s.intensity.get("r"),
                share_r=s.share.get("r"), pe_rel=pe_rel, pe_z=pe_z, pe_s=s.seconds, line=s.line(), truth=tv,
                commit=_commit())


def _commit() -> str:
    import subprocess

    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                              cwd=Path(__file__).parent, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "?"


def write_usv(rows: list[dict], out: Path) -> None:
    """Add ``rows`` to ``at_sea_usv.jsonl`` (replacing a seed and case measured before) and write the table of all
    rows to ``at_sea_usv.md``."""
    import json

    log = out / "at_sea_usv.jsonl"
    kept = {}
    if log.exists():
        for line in log.read_text().splitlines():
            if line.strip():
                r = json.loads(line)
                kept[(r.get("case", "waves"), r["seed"])] = r
    for r in rows:
        kept[(r["case"], r["seed"])] = r
    log.write_text("".join(json.dumps(r, default=float) + "\n" for r in kept.values()))
    L = ["# At sea, synthetic: the 3-DOF USV under a heading autopilot", "",
         "`python -m benchmarks at_sea_synthetic --cases \"\" --usv-seeds 0,1,2 --usv-cases waves,calm`: the water-jet "
         "USV of `benchmarks/independent/vessels.py` (10 hydrodynamic coefficients free, mass and inertia known) "
         "under a PD autopilot on its yaw moment, in narrow-band sway (sd 0.03 m/s²) and yaw (0.01 rad/s²) "
         "accelerations of period 6 s with a random phase per run (`waves`), or the same runs without them "
         "(`calm`); 3 × 300 s trained, 1 held out, 5 Hz; channels ψ, u, v, r. The output-error fit is the default; "
         "the sea-state check is `diffship.diagnose.sea_state` (prediction error with the wave disturbance, judged "
         "by held-out one-sample prediction). Rows from `results/at_sea_usv.jsonl` (each with the commit it ran "
         "at).", "",
         "| case | seed | loop closed | output error: worst \\|rel. error\\|, worst \\|z\\| | sea state named | period | "
         "sd v, r | share (r) | its fit: worst \\|rel. error\\|, worst \\|z\\| (which) | s (output error, sea state) "
         "| commit |",
         "|---|---|---|---|---|---|---|---|---|---|---|"]

    def num(x, fmt, unit=""):
        return "—" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, fmt) + unit
    for (case, seed), r in sorted(kept.items()):
        wz = max(r["pe_z"], key=lambda n: abs(r["pe_z"][n]) if math.isfinite(r["pe_z"][n]) else -1.0)
        pe = (f"{max(map(abs, r['pe_rel'].values())):.0%}, {abs(r['pe_z'][wz]):.1f} ({wz})"
              if math.isfinite(r["pe_z"][wz]) else "— (ended by the screen)")
        L.append(f"| {case} | {seed} | {r['closed']} | {max(map(abs, r['oe_rel'].values())):.0%}, "
                 f"{max(map(abs, r['oe_z'].values())):.1f} | {r['found']} | {num(r['period'], '.2f', ' s')} | "
                 f"{num(r['sd_v'], '.4f')}, {num(r['sd_r'], '.4f')} | {num(r['share_r'], '.0%')} | {pe} | "
                 f"{r['oe_s']:.0f}, {r['pe_s']:.0f} | {r.get('commit', '?')} |")
    (out / "at_sea_usv.md").write_text("\n".join(L) + "\n")


def write(df: pd.DataFrame, out: Path) -> None:
    df.to_csv(out / "at_sea_synthetic.csv", index=False)
    lines = ["# At sea, synthetic: autopilot in narrow-band waves", "",
             "Command: `python -m benchmarks at_sea_synthetic --seeds 4` (module docstring: the truth, the cases; 3 "
             "training runs and 1 held out per seed). Truth K 0.08 1/s, T1 20 s; wave period 8 s, relative damping "
             "0.08, sd 0.004 rad/s². z = (estimate − truth)/standard error. The diagnosis row is "
             "`diagnose(Nomoto1(), train, val, options=DiagnoseOptions(sea_state=\"always\"))`: its sea-state check "
             "(prediction error with the wave disturbance, judged by held-out one-sample prediction); its K and T1 "
             "are that check's prediction-error fit, — where its 20-step screen ended the check (no full fit).", "",
             "| case | method | K (median) | max \\|z_K\\| | T1 (median) | max \\|z_T1\\| | usable | loop closed | "
             "sea state named | wave period (median) | wave sd (median) | share of the one-sample error | "
             "deterministic attribution | s (median) |", "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]

    def col(g, name, fmt):
        return fmt(g[name]) if name in g and g[name].notna().any() else ""
    for (case, method), g in df.groupby(["case", "method"], sort=False):
        est = (f"{g['K'].median():.4f} | {g['z_K'].abs().max():.1f} | {g['T1'].median():.2f} | "
               f"{g['z_T1'].abs().max():.1f}" if g["K"].notna().any() else "— | — | — | —")
        lines.append(
            f"| {case} | {method} | {est} | {col(g, 'usable', lambda x: f'{int(x.sum())}/{x.notna().sum()}')} | "
            f"{col(g, 'closed_loop', lambda x: f'{int(x.sum())}/{x.notna().sum()}')} | "
            f"{col(g, 'sea_state', lambda x: f'{int(x.sum())}/{x.notna().sum()}')} | "
            f"{col(g, 'wave_period', lambda x: f'{x.median():.2f} s')} | {col(g, 'wave_sd', lambda x: f'{x.median():.4f}')} | "
            f"{col(g, 'share_r', lambda x: f'{100 * x.median():.0f} %')} | "
            f"{col(g, 'attributed', lambda x: ', '.join(sorted(set(x.dropna()))))} | {g['seconds'].median():.0f} |")
    (out / "at_sea_synthetic.md").write_text("\n".join(lines) + "\n")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--cases", default="waves,calm,open")
    ap.add_argument("--usv-seeds", default="", help="comma-separated seeds of the USV (minutes each; none: not run)")
    ap.add_argument("--usv-cases", default="waves", help="comma-separated USV cases: waves, calm")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for case in [c for c in args.cases.split(",") if c]:
        for seed in range(args.seeds):
            rows += one(seed, case)
            write(pd.DataFrame(rows), out)
    for case in [c for c in args.usv_cases.split(",") if c]:
        for seed in [int(x) for x in args.usv_seeds.split(",") if x]:
            write_usv([usv_one(seed, case)], out)
            print((out / "at_sea_usv.md").read_text(), flush=True)
    if rows:
        print((out / "at_sea_synthetic.md").read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
