"""Withheld-effect benchmark for ``diffship.diagnose`` (one command).

Generate runs from a truth with one hidden effect (also none, two at once, and out-of-family
truths whose effect is not exactly in the library form), fit the base model without it,
diagnose, and score:

* top-1: the first selected effect is the hidden one (for no-effect data: nothing selected);
* top-3: the hidden effect is among the first three of the ranking;
* shrink: (E_base − E_after) / (E_base − E_truth) on the held-out runs (E_truth = the true
  model's error, the real floor);
* parameter recovery |φ̂ − φ*| / |φ*|;
* false alarms on no-effect data; right family for out-of-family truths.

Usage::

    python -m benchmarks withheld_effects --quick     # nomoto1 scenarios, < 3 min
    python -m benchmarks withheld_effects             # + more seeds and fossen3 scenarios

Writes ``benchmarks/results/withheld_effects[_quick].md`` and ``.csv``.
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path
from typing import ClassVar

import jax.numpy as jnp
import numpy as np

import diffship  # noqa: F401  (float64)
from diffship.diagnose import FAMILY, DiagnoseOptions, augment, diagnose
from diffship.diagnose.where import normalised_error
from diffship.metrics import evaluate
from diffship.models import Fossen3, Nomoto1
from diffship.models import scalar
from diffship.synthetic import rudder_sequence, simulate_run, usv_excitation, usv_truth

D = np.pi / 180
OUT = Path(__file__).resolve().parent / "results"


# -- out-of-family truths -------------------------------------------------------------------
class Nomoto1Cubic(Nomoto1):
    """Nomoto with a cubic yaw damping law T ṙ + r + a r³ = K(δ + δ0) (library has |r|r)."""

    name: ClassVar[str] = "nomoto1_cubic"
    a3: jnp.ndarray = scalar(0.0)

    def vector_field(self, t, x, u):
        r = x[1]
        return jnp.stack([r, (self.K * (u[0] + self.delta0) - r - self.a3 * r**3) / self.T1])


class Fossen3DriftingCurrent(Fossen3):
    """fossen3 with a current that rotates slowly in time (library: constant current)."""

    name: ClassVar[str] = "fossen3_drifting_current"
    Vc: float = 0.15
    omega: float = 2 * np.pi / 400.0

    def vector_field(self, t, x, u):
        psi = x[2]
        c, s = jnp.cos(psi), jnp.sin(psi)
        vx, vy = self.Vc * jnp.cos(self.omega * t), self.Vc * jnp.sin(self.omega * t)
        bx, by = c * vx + s * vy, -s * vx + c * vy
        xr = x.at[3].add(-bx).at[4].add(-by)
        dx = super().vector_field(t, xr, u)
        ug, vg, rg = x[3], x[4], x[5]
        dx = dx.at[0].set(c * ug - s * vg).at[1].set(s * ug + c * vg)
        # d/dt of R^T v_c: yaw rotation plus the current's own rotation
        dvx, dvy = -self.omega * vy, self.omega * vx
        dbx, dby = c * dvx + s * dvy, -s * dvx + c * dvy
        return dx.at[3].add(rg * by + dbx).at[4].add(-rg * bx + dby)


# -- run generators -------------------------------------------------------------------------
NOMOTO_BASE = dict(K=0.2, T1=8.0, delta0=0.01)
ZIGZAGS = [(10, 20), (-20, 30), (15, 24), (-25, 40), (20, 16), (-12, 36)]


DURATION = {"quick": 40.0, "full": 50.0, "mode": 50.0}


def nomoto_runs(truth, seed, duration=None, dt=0.1, delay=0.0):
    duration = duration or DURATION["mode"]
    out = []
    for i, (a, p) in enumerate(ZIGZAGS):
        t = np.arange(0.0, duration, dt)
        d = rudder_sequence(t, a * D, p + 2 * seed, rate=10 * D)
        inp = np.interp(t - delay, t, d, left=d[0]) if delay else d
        x0 = np.asarray(truth.initial_state({"delta": float(inp[0])})) if hasattr(truth, "effects") else np.zeros(len(truth.state_names))
        run = simulate_run(truth, t, {"delta": inp}, x0, name=f"zz{i}", noise="realistic", seed=1000 * seed + i)
        # the logged command (differs from inp for the exact delay); true x0 kept for the floor
        out.append((run.with_channels(delta=d), run, x0))
    return out[:4], out[4:]


def usv_runs(truth, seed, duration=49.9, dt=0.1):
    out = []
    for i in range(6):
        t, inp = usv_excitation(duration, dt, seed=7000 + 100 * seed + i)
        x0 = np.array([0, 0, 0, 2.0, 0, 0.0])
        if hasattr(truth, "effects"):
            x0 = np.asarray(truth.initial_state({"u": 2.0, **{k: float(v[0]) for k, v in inp.items()}}))
        run = simulate_run(truth, t, inp, x0, name=f"usv{i}", noise="realistic", seed=1000 * seed + i)
        out.append((run, run, x0))
    return out[:4], out[4:]


def scenarios(quick: bool):
    nb = Nomoto1(**NOMOTO_BASE)
    S = []
    seeds = (1,) if quick else (1, 2, 3)
    for s in seeds:
        S += [
            ("nomoto1", "in", ("actuator_lag",), lambda s=s: augment(nb, "actuator_lag", T_act=2.5), {"T_act": 2.5}, s, {}),
            ("nomoto1", "in", ("input_delay",), lambda s=s: augment(nb, "input_delay", tau_d=1.5), {"tau_d": 1.5}, s, {}),
            ("nomoto1", "in", ("damping_rr",), lambda s=s: augment(nb, "damping_rr", c_rr=60.0), {"c_rr": 60.0}, s, {}),
            ("nomoto1", "none", (), lambda: nb, {}, s, {}),
            ("nomoto1", "none", (), lambda: nb, {}, s + 10, {}),
            ("nomoto1", "two", ("actuator_lag", "damping_rr"), lambda: augment(nb, "actuator_lag", "damping_rr", T_act=2.5, c_rr=60.0),
             {"T_act": 2.5, "c_rr": 60.0}, s, {}),
            ("nomoto1", "out", ("input_delay",), lambda: nb, {}, s, {"delay": 1.5}),
            ("nomoto1", "out", ("damping_rr",), lambda: Nomoto1Cubic(**NOMOTO_BASE, a3=2500.0), {}, s, {}),
        ]
        if not quick:
            S.append(("nomoto1", "in", ("rate_limit",), lambda: None, {"T_slew": 10.0}, s, {"rate_limit": True}))
        if not quick and s == seeds[0]:
            S += fossen3_scenarios()
    return S


def fossen3_scenarios():
    ub = usv_truth()
    S = []
    for s in (1,):
        S += [
            ("fossen3", "in", ("current",), lambda: augment(ub, "current", Vcx=0.15, Vcy=-0.1), {"Vcx": 0.15, "Vcy": -0.1}, s, {}),
            ("fossen3", "in", ("constant_force",), lambda: augment(ub, "constant_force", Y0=60.0, N0=-300.0), {"Y0": 60.0, "N0": -300.0}, s, {}),
            ("fossen3", "in", ("damping_vv",), lambda: augment(ub, "damping_vv", Nvv=-6000.0), {"Nvv": -6000.0}, s, {}),
            ("fossen3", "in", ("actuator_lag",), lambda: None, {"T_act": 1.5}, s, {"lag_fossen": True}),
            ("fossen3", "none", (), lambda: ub, {}, s, {}),
            ("fossen3", "out", ("current",), lambda: Fossen3DriftingCurrent(Xudot=-400.0, Yvdot=-2500.0, Nrdot=-8000.0), {}, s, {}),
        ]
    return S


def run_one(family, kind, hidden, make_truth, phi, seed, opts, progress=None):
    if family == "nomoto1":
        if opts.get("rate_limit"):
            tr0, _ = nomoto_runs(Nomoto1(**NOMOTO_BASE), seed)
            truth = augment(Nomoto1(**NOMOTO_BASE), "rate_limit", runs=[r[0] for r in tr0], T_slew=phi["T_slew"])
        else:
            truth = make_truth()
        train, val = nomoto_runs(truth, seed, delay=opts.get("delay", 0.0))
        if opts.get("delay"):
            truth = Nomoto1(**NOMOTO_BASE)  # simulated with the shifted input below
        base0 = Nomoto1()
    else:
        if opts.get("lag_fossen"):
            truth = augment(usv_truth(), "actuator_lag", T_act=phi["T_act"])
        else:
            truth = make_truth()
        train, val = usv_runs(truth, seed)
        base0 = usv_truth()
    val_sim = [v[1] for v in val]  # runs with the input the truth really saw
    x0_true = [v[2] for v in val]
    train, val = [r[0] for r in train], [v[0] for v in val]
    t0 = time.perf_counter()
    kw = dict(max_refits=3, max_absorbed=2) if family == "fossen3" else {}
    d = diagnose(base0, train, val, options=DiagnoseOptions(**kw), progress=progress)
    secs = time.perf_counter() - t0
    # E of the truth on the validation runs (the real floor), same normalisation
    floor = d.noise_floor
    # the truth simulated from its true initial state: the real floor of the validation error
    E_truth = normalised_error(evaluate(truth, val_sim, x0=x0_true), floor, d.channels)
    E_ref = E_truth if np.isfinite(E_truth) else 1.0
    shrink_true = (d.E_before - d.E_after) / (d.E_before - E_ref) if d.E_before > E_ref else float("nan")
    top = d.selected[0] if d.selected else "none"
    ranked = [r.effect for r in d.ranking if (r.validation_gain or 0) > 0 or r.effect in d.selected][:3]
    if kind == "none":
        top1 = not d.selected
        top3 = top1
    elif kind == "two":
        top1 = set(d.selected[:2]) == set(hidden)
        top3 = all(h in ranked for h in hidden)
    elif kind == "out":
        top1 = bool(d.selected) and FAMILY[d.selected[0]] == FAMILY[hidden[0]]
        top3 = any(FAMILY[h] == FAMILY[hidden[0]] for h in ranked)
    else:
        top1 = top == hidden[0]
        top3 = hidden[0] in ranked
    rec = []
    for r in d.ranking:
        for k, v in phi.items():
            if k in (r.params or {}):
                rec.append(abs(r.params[k] - v) / abs(v))
    return {"model": family, "kind": kind, "hidden": "+".join(hidden) or "none", "seed": seed, "selected": "+".join(d.selected) or "none",
            "top1": top1, "top3": top3, "E_base": d.E_before, "E_after": d.E_after, "E_truth": E_truth,
            "shrink": shrink_true, "param_rel_err": float(np.max(rec)) if rec else float("nan"),
            "screen_s": d.timings["screen"], "total_s": secs}


def summarise(rows) -> list[str]:
    def pct(xs):
        return f"{100 * np.mean(xs):.0f} % ({int(np.sum(xs))}/{len(xs)})" if xs else "-"

    inn = [r for r in rows if r["kind"] == "in"]
    none = [r for r in rows if r["kind"] == "none"]
    two = [r for r in rows if r["kind"] == "two"]
    out = [r for r in rows if r["kind"] == "out"]
    shr = [r["shrink"] for r in inn if np.isfinite(r["shrink"])]
    rec = [r["param_rel_err"] for r in inn if np.isfinite(r["param_rel_err"])]
    return [
        f"- in-family single effects: top-1 {pct([r['top1'] for r in inn])} (target ≥ 90 %), top-3 {pct([r['top3'] for r in inn])}, "
        f"median shrink {np.median(shr) if shr else float('nan'):.2f} of the structural gap (target ≥ 0.9), "
        f"median parameter error {100 * np.median(rec) if rec else float('nan'):.1f} %",
        f"- no-effect data: false alarms {pct([not r['top1'] for r in none])} (target ≤ 10 %)",
        f"- two effects at once: both selected {pct([r['top1'] for r in two])}",
        f"- out-of-family: right effect family selected {pct([r['top1'] for r in out])} (target ≥ 60 %)",
        f"- screening time: median {np.median([r['screen_s'] for r in rows]):.1f} s (first includes compilation: "
        f"{rows[0]['screen_s']:.1f} s); diagnosis median {np.median([r['total_s'] for r in rows]):.1f} s, max {max(r['total_s'] for r in rows):.1f} s",
    ]


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="nomoto1 scenarios, one seed, 40 s runs (< 3 min)")
    p.add_argument("--verbose", action="store_true")
    a = p.parse_args(argv)
    DURATION["mode"] = DURATION["quick" if a.quick else "full"]
    t0 = time.perf_counter()
    rows = []
    OUT.mkdir(exist_ok=True)
    stem = "withheld_effects_quick" if a.quick else "withheld_effects"
    partial = OUT / f"{stem}_partial.csv"
    for sc in scenarios(a.quick):
        r = run_one(*sc, progress=print if a.verbose else None)
        rows.append(r)
        with open(partial, "w", newline="") as f:  # rows so far, in case a long run is stopped
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
        print(f"[{time.perf_counter() - t0:6.1f} s] {r['model']:8s} {r['kind']:4s} hidden={r['hidden']:24s} selected={r['selected']:24s} "
              f"top1={r['top1']!s:5s} E {r['E_base']:.2f}->{r['E_after']:.2f} (truth {r['E_truth']:.2f}) shrink {r['shrink']:.2f} "
              f"param err {r['param_rel_err']:.3f}", flush=True)
    with open(OUT / f"{stem}.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    summ = summarise(rows)
    md = [f"# Withheld-effect benchmark ({'quick' if a.quick else 'full'})", "",
          f"Command: `python -m benchmarks withheld_effects{' --quick' if a.quick else ''}`; wall time "
          f"{time.perf_counter() - t0:.0f} s on this CPU (shared).", "", *summ, "",
          "| model | kind | hidden | selected | top-1 | top-3 | E base | E after | E truth | shrink | param err |",
          "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        md.append(f"| {r['model']} | {r['kind']} | {r['hidden']} | {r['selected']} | {r['top1']} | {r['top3']} | {r['E_base']:.2f} | "
                  f"{r['E_after']:.2f} | {r['E_truth']:.2f} | {r['shrink']:.2f} | {r['param_rel_err']:.3f} |")
    (OUT / f"{stem}.md").write_text("\n".join(md) + "\n")
    partial.unlink(missing_ok=True)
    print("\n".join(summ))
