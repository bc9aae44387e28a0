"""Real logs with withheld effects: exact effects injected into the HSVA KVLCC2 zigzags.

The HSVA free-running zigzags of the KVLCC2 model (``../shared/data/kvlcc2_hsva``, SIMMAN 2008;
never copied into the repository) carry whatever the real basin put in them. On top of that, each
scenario injects one effect *exactly*, at a magnitude model basins and sea trials see:

==================  ===============================================  ===========================  ============
scenario            what is done to the logged columns               expected library effect      magnitude
==================  ===============================================  ===========================  ============
none                nothing (the real gap alone)                     —                            —
clock_offset        rudder logged ``tau`` s early against motion:    input_delay (τ_d = tau)      0.5 s
                    δ_log(t) = δ(t + tau), so the hull answers
                    δ_log(t − tau)
rudder_zero         rudder indicator zero error: δ_log = δ − δ_z     rudder_offset                1.0°
                    (the hull sees δ_log + δ_z)
heading_bias        ψ_log = ψ + b (compass / tracker misalignment)   heading_bias (b)             1.0°
water_drift         basin water moving at v_c (NED): positions       current (v_c)                0.02 m/s
                    + v_c t, over-ground u, v + Rᵀ(ψ) v_c
==================  ===============================================  ===========================  ============

Extra rows (run with ``--only``, not counted): stronger versions (``heading_bias_5deg``,
``water_drift_5cm``), the other sign of the clock offset (``clock_offset_late``: the rudder logged
0.5 s late) and a rate-gyro zero error (``gyro_zero``: r + 0.05°/s, which no library effect carries;
the data check's own ``rate_bias``).

Magnitudes: logging clocks of separate acquisition systems drift or are offset by 0.1–1 s;
rudder indicators are set to about ±0.5–1°; heading references (gyro, optical tracking)
are aligned to about 0.5–1°; residual basin circulation after a run is 1–3 cm/s at model
scale. The current and heading bias change only the kinematics (a uniform current does not
change the hydrodynamics in the water frame), so their injections are exact.

For each scenario the benchmark trains on four zigzags and diagnoses on the held-out ones
(:func:`diffship.diagnose.diagnose`, every candidate effect of the library, nothing told).

**Base** (``--base``): ``published`` refits the model's default free set from its published
values (the first look); ``study`` (mmg) is the best base a user has — the KVLCC2 study's MAP fit
(:func:`diffship.studies.kvlcc2.study_fit`: 33 coefficients under their ±50 % priors), made on the
scenario's own (injected) training logs as a user would make it, its ten core coefficients
(:data:`~diffship.studies.kvlcc2.TEN_FREE`) refitted in the diagnosis, as
``benchmarks/diagnose_kvlcc2.py --base study``.

**Found** (the real gap is in every scenario, so a selection alone is not enough):

- *selected*: the injected effect is among the diagnosis' selected effects — first, or at a
  greedy step after what the real gap needs (the none row's selections); first-selected hits
  are counted on their own;
- *magnitude*: its fitted size (the one the verdict attributes: its single refit when selected
  first, the joint refit of its step when selected later; else its single refit) minus what the **none** row estimates for the same effect (the
  real logs may carry some already: the none row's value when it selects or refits it and its
  standard error is finite; else 0 — an undetermined none-row value, such as a delay at the
  Padé realisation's floor of 1.5 sample intervals, where every smaller delay is the same
  model, says nothing about what the logs carry; the raw and none-row values are reported)
  lies within ±30 % of the injected size (for the current: the vector difference within 30 % of
  the injected speed). The 95 % interval of the scenario's estimate, and the final model's value
  (all selected effects refitted jointly), are reported beside it;
- **found** = selected and magnitude right. A selection with the wrong size is reported as
  "selected, wrong size", never as found.
- *waiting* (reported, never counted as found): the injected effect was not selected but the
  verdict names it as also passing the rule at the greedy path's last step when the path stopped
  at its cap (``greedy_steps``) with a structural gap left (:attr:`diffship.diagnose.Diagnosis.waiting`).
- *in the base*: where the base model itself has the injected effect as a free coefficient —
  MMG's rudder neutral angle δ_0 (``d = δ + δ_0``) is exactly a rudder zero error — the
  diagnosis' own rudder-offset candidate (a constant sway force and yaw moment on 3-DOF models)
  has nothing left to find: the base fit's δ_0 minus the none row's, within ±30 % of the
  injected zero error, is counted as **found in the base fit**, in its own column and count.
- *in the data check*: a measurement error the diagnosis settles from the logs alone, with no
  hull coefficient (:mod:`diffship.diagnose.consistency`, ``Diagnosis.in_data``: the heading
  against the track and over-ground u, v; the time the motion follows the logged rudder) — when
  the check states it as a finding and its estimate minus the none row's lies within ±30 % of
  the injected size, it is counted as **found in the data check**, in its own column and count.

Usage::

    python -m benchmarks withheld_real --model nomoto1 --only none,clock_offset,rudder_zero
    python -m benchmarks withheld_real --model mmg --base study --greedy-steps 3   # all five (minutes each)

Each finished scenario is appended to ``benchmarks/results/withheld_real_<model>.jsonl`` (a run
that stops keeps what it measured; ``--resume`` skips scenarios already there for the same
settings); the report ``benchmarks/results/withheld_real_<model>.md`` / ``.csv`` is written from it.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import re
import sys
import time
from pathlib import Path

import numpy as np

import diffship  # noqa: F401
from diffship.data import Run, kvlcc2_runs
from diffship.diagnose import DiagnoseOptions, diagnose
from diffship.models import get_model

from benchmarks.common.injections import inject_current

TRAIN = ("Z_10_05", "Z_20_05", "Z_35_05", "Z_20_10_S")
VALIDATE = ("Z_10_10_P", "Z_20_10_P", "Z_15_05")
OUT = Path(__file__).resolve().parent / "results"
D = math.pi / 180
SCENARIOS = {  # name: (expected effect, magnitude, needs positions)
    "none": (None, 0.0, False),
    "clock_offset": ("input_delay", 0.5, False),
    "rudder_zero": ("rudder_offset", 1.0 * D, False),
    "heading_bias": ("heading_bias", 1.0 * D, True),
    "water_drift": ("current", 0.02, True),
    # extra rows, stronger than basins see (run with --only): is the size or the data the limit?
    "heading_bias_5deg": ("heading_bias", 5.0 * D, True),
    "water_drift_5cm": ("current", 0.05, True),
    # the other sign: the rudder logged 0.5 s late (the motion leads it; no delay model can represent it)
    "clock_offset_late": ("input_delay", -0.5, False),
    # a rate-gyro zero error (no library effect carries it; the data check does)
    "gyro_zero": ("rate_bias", 0.05 * D, False),
}
EXTRA = ("heading_bias_5deg", "water_drift_5cm", "clock_offset_late", "gyro_zero")
EXTRA_WHY = {"heading_bias_5deg": "stronger than basins see", "water_drift_5cm": "stronger than basins see",
             "clock_offset_late": "the other sign: the rudder logged late",
             "gyro_zero": "a rate-gyro zero error, r + 0.05°/s: no library effect, the data check's own"}
DRIFT_DIR = 0.8  # rad, NED direction the basin water moves towards
TOL = 0.30  # relative tolerance of a found magnitude
#: the effect's parameter(s) that measure the injected size (a vector for the current)
MEASURE = {"input_delay": ("tau_d",), "rudder_offset": ("delta_off",), "heading_bias": ("b_psi",),
           "current": ("Vcx", "Vcy")}
#: a base-model coefficient that is the injected effect itself (MMG's rudder neutral angle)
IN_BASE = {"rudder_offset": "delta0"}
#: the data-consistency check that measures the injected effect (:mod:`diffship.diagnose.consistency`)
IN_DATA = {"heading_bias": "heading_bias", "input_delay": "rudder_timing", "rate_bias": "rate_bias"}
UNIT = {"input_delay": (1.0, "s"), "rudder_offset": (D, "°"), "heading_bias": (D, "°"), "current": (1.0, "m/s"),
        "rate_bias": (D, "°/s")}


def injected_vector(scenario: str) -> np.ndarray:
    """The injected size in the measuring parameters' units (:data:`MEASURE`)."""
    exp, a, _ = SCENARIOS[scenario]
    if exp == "current":
        return np.array([a * math.cos(DRIFT_DIR), a * math.sin(DRIFT_DIR)])
    return np.array([a])


def inject(run: Run, scenario: str) -> Run:
    """``run`` with the scenario's effect put in exactly (module docstring); a new Run."""
    kind, a, _ = SCENARIOS[scenario]
    t = np.asarray(run.time, dtype=float)
    ch = {c: np.asarray(run[c], dtype=float).copy() for c in run.channels}
    if kind == "input_delay":
        ch["delta"] = np.interp(t + a, t, ch["delta"])  # held at the last value past the end
    elif kind == "rudder_offset":
        ch["delta"] = ch["delta"] - a
    elif kind == "heading_bias":
        ch["psi"] = ch["psi"] + a
    elif kind == "rate_bias":
        ch["r"] = ch["r"] + a
    elif kind == "current":
        return inject_current(run, *injected_vector(scenario), label=scenario)
    return Run(run.name, t, ch, {**run.metadata, "injected": scenario})


def estimates(d, model_params) -> dict:
    """Per library effect: its fitted size (final model if selected, else its single refit), 95 % half-width, source.

    Also ``"base:" + name`` for the base coefficients of :data:`IN_BASE` (the base fit's value and
    standard error).
    """
    out = {}
    final = d.final_model.param_values()
    for r in d.ranking:
        names = MEASURE.get(r.effect)
        if not names:
            continue
        if r.effect in d.selected and all(n in final for n in names):
            val, src = [float(final[n]) for n in names], "selected (final model)"
        elif r.params and all(n in r.params for n in names):
            val, src = [float(r.params[n]) for n in names], "single refit"
        else:
            continue
        se = [float((r.stderr or {}).get(n, float("nan"))) for n in names]
        out[r.effect] = {"value": val, "half95": [1.96 * x for x in se], "source": src}
    for eff, name in IN_BASE.items():
        f = d.base_fit
        if name in f.free:
            out["base:" + eff] = {"value": [float(f.params[name])],
                                  "half95": [1.96 * float(f.stderr.get(name, float("nan")))],
                                  "source": f"base fit's own {name}"}
    for eff, check in IN_DATA.items():
        f = d.in_data.get(check)
        if f is not None:
            out["data:" + eff] = {"value": [float(f.value)], "half95": [float(f.half95())], "found": bool(f.found),
                                  "source": f"data check {check} ({'a finding' if f.found else 'not a finding: ' + f.reason})"}
    return out


def judge(row: dict, none_row: dict | None) -> dict:
    """``found`` / ``found_in_base`` of a scenario row against the none row (module docstring)."""
    exp = row["expected"]
    if exp in (None, "none") or row.get("first_selected") == "n/a":
        return {}
    inj = injected_vector(row["scenario"])
    s, u = UNIT[exp]
    res = {"selected_first": row["first_selected"] == exp,
           "selected_any": exp in row["selected"].split("+")}
    sel = row["selected"].split("+") if row["selected"] else []
    names = MEASURE.get(exp, ())
    single = (row.get("ranking", {}).get(exp) or {}).get("params", {})
    final = [row["params"][n] for n in names] if names and all(n in row["params"] for n in names) else None
    for key, tag in ((exp, ""), ("base:" + exp, "_in_base"), ("data:" + exp, "_in_data")):
        est = row["estimates"].get(key)
        if est is None:
            continue
        if key == exp and exp in sel and sel.index(exp) == 0 and all(n in single for n in names):
            # selected first: the size the verdict attributes is its single refit's (the first step);
            # the final model (later effects refitted jointly) is reported beside it
            est = {**est, "value": [single[n] for n in names], "source": "single refit (its selection step, the first)"}
        elif key == exp and exp in sel:
            est = {**est, "source": "final model" + (" (its selection step, the last)" if sel[-1] == exp else "")}
        ref = (none_row or {}).get("estimates", {}).get(key)
        determined = bool(ref) and bool(np.all(np.isfinite(ref["half95"])))
        v0 = np.array(ref["value"]) if determined else np.zeros_like(inj)
        delta = np.array(est["value"]) - v0
        err = float(np.linalg.norm(delta - inj) / np.linalg.norm(inj))
        h = np.array(est["half95"])
        covers = bool(np.all(np.abs(delta - inj) <= h)) if np.all(np.isfinite(h)) else False
        res[f"delta{tag}"] = [float(x) / s for x in delta]
        res[f"rel_error{tag}"] = round(err, 3)
        res[f"ci_covers{tag}"] = covers
        res[f"size_ok{tag}"] = err <= TOL and est.get("found", True)
        res[f"raw{tag}"] = [float(x) / s for x in est["value"]]
        res[f"none{tag}"] = [float(x) / s for x in ref["value"]] if ref else None
        res[f"source{tag}"] = est["source"] + (
            "" if determined else "; none row: 0 (" + ("its estimate is undetermined (infinite standard error)"
                                                      if ref else "not refitted there") + ")")
        if key == exp and exp in sel and final is not None:
            df = np.array(final) - v0
            res["final"] = [float(x) / s for x in df]
            res["rel_error_final"] = round(float(np.linalg.norm(df - inj) / np.linalg.norm(inj)), 3)
    res["unit"] = u
    res["found"] = bool(res["selected_any"] and res.get("size_ok", False))
    res["found_in_base"] = bool(res.get("size_ok_in_base", False))
    res["found_in_data"] = bool(res.get("size_ok_in_data", False))
    return res


#: the channels an injected effect changes in the model (the rest of the validation error is out of its
#: reach): a heading bias only turns the track (ψ_t = ψ − b in the position kinematics; the hull's
#: dynamics do not depend on ψ). A current is not here: the hydrodynamics see the through-water
#: velocity ν_g − Rᵀv_c, so it changes every channel.
REACH = {"heading_bias": ("track north (x)", "track east (y)")}
_RMS = re.compile(r"([a-z() ]+?) [0-9.e+-]+ \S+ RMS \(([0-9.e+]+)× its floor")


def gain_ceiling(row: dict) -> float | None:
    """The largest relative drop of the validation error E an effect of :data:`REACH` can give:
    removing the whole error of the channels it changes, ``1 − sqrt(1 − Σ_reach E_c² / Σ_all E_c²)``
    (E = sqrt(mean_c E_c²), :mod:`diffship.diagnose.shrink`), from the per-channel ratios of the
    scenario's *where* line. Below the acceptance rule's 5 % the effect cannot be selected on these
    data, however exactly it is fitted."""
    reach = REACH.get(row.get("expected"))
    if not reach:
        return None
    ratios = {m.group(1).strip(): float(m.group(2)) for m in _RMS.finditer(row.get("verdict_where", ""))}
    if not ratios:
        return None
    tot = sum(v * v for v in ratios.values())
    part = sum(ratios.get(c, 0.0) ** 2 for c in reach)
    return 1.0 - math.sqrt(max(1.0 - part / tot, 0.0))


def settings_key(a) -> dict:
    return {"model": a.model, "base": a.base, "horizon": a.horizon, "dt": a.dt, "greedy_steps": a.greedy_steps}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", default="nomoto1")
    p.add_argument("--base", default="published", choices=("published", "study"),
                   help="published: the model's published values, default free set refitted; study (mmg): the KVLCC2 "
                        "study's MAP fit on the scenario's training logs, its ten core coefficients refitted")
    p.add_argument("--horizon", type=float, default=100.0, help="seconds of each run used [s]")
    p.add_argument("--dt", type=float, default=0.2)
    p.add_argument("--only", default=None, help="comma-separated scenario names")
    p.add_argument("--greedy-steps", type=int, default=None,
                   help="effects on the greedy path at most (DiagnoseOptions.greedy_steps; default the library's); "
                        "3 lets an injection be found after the two effects the real KVLCC2 gap needs")
    p.add_argument("--resume", action="store_true", help="skip scenarios already in the .jsonl for these settings")
    p.add_argument("--write-only", action="store_true", help="only write the report from the .jsonl")
    a = p.parse_args(argv)
    if a.base == "study" and a.model != "mmg":
        p.error("--base study is the KVLCC2 study's MMG fit: use it with --model mmg")
    names = a.only.split(",") if a.only else [n for n in SCENARIOS if n not in EXTRA]
    unknown = [n for n in names if n not in SCENARIOS]
    if unknown:
        p.error(f"unknown scenario(s) {unknown}; choose from {', '.join(SCENARIOS)}")
    log = OUT / f"withheld_real_{a.model}.jsonl"
    done = {}
    if log.exists() and (a.resume or a.write_only):
        for line in log.read_text().splitlines():
            r = json.loads(line)
            if r.get("settings") == settings_key(a):
                done[r["scenario"]] = r
    elif log.exists():
        log.unlink()
    if not a.write_only:
        runs = {r.metadata["test"]: r for r in kvlcc2_runs()}
        prep = {k: r.resample(a.dt).slice(None, r.t0 + a.horizon) for k, r in runs.items()}
        for sc in names:
            if sc in done:
                continue
            row = run_scenario(sc, prep, a)
            row["settings"] = settings_key(a)
            done[sc] = row
            with open(log, "a") as f:
                f.write(json.dumps(row) + "\n")
    write([done[s] for s in SCENARIOS if s in done], a)


def run_scenario(sc: str, prep: dict, a) -> dict:
    exp, mag, pos = SCENARIOS[sc]
    model = get_model(a.model)
    if pos and "x0" not in model.output_names:
        return {"scenario": sc, "expected": exp, "first_selected": "n/a",
                "note": f"{a.model} predicts no positions: a {exp} shows only in the track"}

    def say(s):
        print(f"[{sc}] {s}", file=sys.stderr, flush=True)

    train = [inject(prep[k], sc) for k in TRAIN]
    val = [inject(prep[k], sc) for k in VALIDATE]
    t0 = time.perf_counter()
    spec, base_note = None, "published values, default free set refitted"
    if a.base == "study":
        from diffship.studies.kvlcc2 import TEN_FREE, study_fit

        sf = study_fit(train, progress=say)
        model, spec = sf.model, sf.model.spec().only_free(list(TEN_FREE))
        base_note = f"study MAP fit ({len(sf.free)} coefficients, {'converged' if sf.converged else sf.status})"
    t_base = time.perf_counter() - t0
    opts = DiagnoseOptions() if a.greedy_steps is None else DiagnoseOptions(greedy_steps=a.greedy_steps)
    d = diagnose(model, train, val, spec=spec, options=opts, progress=say)
    secs = time.perf_counter() - t0
    first = d.selected[0] if d.selected else "none"
    row = {"scenario": sc, "expected": exp or "none", "magnitude": mag, "first_selected": first,
           "selected": "+".join(d.selected), "possible": "+".join(d.possible),
           "waiting": "+".join(n for n, _ in d.waiting),
           "E_before": round(d.E_before, 3), "E_after": round(d.E_after, 3), "shrink": round(d.shrink, 3),
           "params": {k: round(v, 5) for k, v in d.final_model.param_values().items()
                      if k not in get_model(a.model).param_names},
           "estimates": estimates(d, None), "base": base_note,
           "ranking": {r.effect: {"validation_gain": round(float(r.validation_gain), 4), "verdict": r.verdict,
                                  "params": {k: float(v) for k, v in (r.params or {}).items()}}
                       for r in d.ranking},
           "seconds": round(secs, 1), "seconds_study_fit": round(t_base, 1),
           "verdict_where": d.verdict[0], "verdict_which": d.verdict[1],
           "verdict_in_base": next((v for v in d.verdict if v.startswith("In the base")), ""), "in_base": d.in_base,
           "verdict_in_data": next((v for v in d.verdict if v.startswith("In the data")), ""),
           "in_data": {k: f.to_dict() for k, f in d.in_data.items()}}
    print(f"{sc}: expected {exp}, selected {d.selected}, E {d.E_before:.3g} → {d.E_after:.3g}, {secs:.0f} s",
          flush=True)
    return row


def _fmt(v) -> str:
    return ", ".join(f"{x:.3g}" for x in v) if isinstance(v, list) else ("" if v is None else str(v))


def write(rows, a):
    stem = f"withheld_real_{a.model}"
    none_row = next((r for r in rows if r["scenario"] == "none"), None)
    for r in rows:
        r["judge"] = judge(r, none_row)
    flat = [{k: (json.dumps(v) if isinstance(v, (dict, list)) else v) for k, v in r.items()} for r in rows]
    keys = sorted({k for r in flat for k in r})
    with open(OUT / f"{stem}.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        w.writerows(flat)
    inj_all = [r for r in rows if r["expected"] not in ("none", None) and r.get("first_selected") != "n/a"]
    inj = [r for r in inj_all if r["scenario"] not in EXTRA]  # the counts: basin-size injections only
    first = sum(r["judge"]["selected_first"] for r in inj)
    anyk = sum(r["judge"]["selected_any"] for r in inj)
    found = sum(r["judge"]["found"] for r in inj)
    in_base = sum(r["judge"]["found_in_base"] and not r["judge"]["found"] for r in inj)
    in_data = sum(r["judge"]["found_in_data"] and not (r["judge"]["found"] or r["judge"]["found_in_base"]) for r in inj)
    # named by the verdict as passing at the capped path's last step (not selected: not counted as found)
    waiting = sum(r["expected"] in r.get("waiting", "").split("+") and not r["judge"]["selected_any"] for r in inj)
    cmd = (f"python -m benchmarks withheld_real --model {a.model} --base {a.base} --horizon {a.horizon:g} --dt {a.dt:g}"
           + (f" --greedy-steps {a.greedy_steps}" if a.greedy_steps else ""))
    default = [n for n in SCENARIOS if n not in EXTRA]
    present = [r["scenario"] for r in rows]
    if present != default:  # the rows in the .jsonl (extra rows are run with --only NAME --resume)
        cmd += f" --only {','.join(present)}"
    base = rows[0].get("base", "") if rows else ""
    L = [f"# Real logs with withheld effects ({a.model}, HSVA KVLCC2 zigzags, {a.horizon:g} s at {a.dt:g} s)", "",
         f"Command: `{cmd}` (timings on a 2-core machine). Base: {base}.", "",
         (f"Train {', '.join(TRAIN)}; validate {', '.join(VALIDATE)}. Every candidate effect of the library, "
          "nothing told. Definitions (module docstring of `benchmarks/withheld_real.py`): *selected* = among the "
          "selected effects (first or at a later greedy step); *size* = fitted size minus the none row's estimate of "
          f"the same effect, within ±{TOL:.0%} of the injected size; **found** = selected and size right; "
          "**found in the base fit** = the base model's own coefficient for the effect (MMG's rudder neutral angle δ_0) "
          "moved by the injected size (±30 %) against the none row, the diagnosis' candidate having nothing left; "
          "**found in the data check** = the diagnosis' data-consistency check (`Diagnosis.in_data`, "
          "`diffship.diagnose.consistency`: the heading against the track and over-ground u, v; the time the motion "
          "follows the logged rudder) states it as a finding, its size minus the none row's within ±30 %."), "",
         f"**Of {len(inj)} injected scenarios: first selected {first}; selected at any step {anyk}; found (selected, "
         f"size right) {found}; found in the base fit only {in_base}; found in the data check only {in_data}; "
         f"not found {len(inj) - found - in_base - in_data}"
         f" (of which named by the verdict as also passing at the path's cap, *waiting*: {waiting}).**"
         + ("".join(f" Extra row {r['scenario']} ({EXTRA_WHY[r['scenario']]}, not counted): "
                    + ("found" if r["judge"]["found"] else "found in the base fit" if r["judge"]["found_in_base"]
                       else "found in the data check" if r["judge"].get("found_in_data") else "not found") + "."
                    for r in inj_all if r["scenario"] in EXTRA)), "",
         "| scenario | injected | size | first selected | selected | possible | waiting | E before | E after | shrink | study fit s | total s |",
         "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if r.get("first_selected") == "n/a":
            L.append(f"| {r['scenario']} | {r['expected']} | | n/a | | | | | | | | {r['note']} |")
            continue
        s, u = UNIT.get(r["expected"], (1.0, ""))
        size = f"{r['magnitude'] / s:.3g} {u}" if r["expected"] != "none" else "—"
        size += f" (extra, {EXTRA_WHY[r['scenario']]})" if r["scenario"] in EXTRA else ""
        L.append(f"| {r['scenario']} | {r['expected']} | {size} | {r['first_selected']} | {r['selected']} | "
                 f"{r['possible']} | {r.get('waiting', '')} | {r['E_before']} | {r['E_after']} | {r['shrink']} | {r.get('seconds_study_fit', 0)} | "
                 f"{r['seconds']} |")
    L += ["", "Fitted against injected (fitted minus the none row's estimate; units as shown):", "",
          "| scenario | injected | fitted (raw) | none row | fitted Δ (diagnosis) | rel. error | 95 % covers | source | final model Δ (rel. error) | base Δ (own coefficient) | rel. error | data check Δ (raw; none row) | rel. error | largest E gain possible | found | found in base | found in data check |",
          "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in inj_all:
        j = r["judge"]
        s, u = UNIT[r["expected"]]
        injv = [x / s for x in injected_vector(r["scenario"])]
        data_raw = f" ({_fmt(j['raw_in_data'])}; {_fmt(j.get('none_in_data'))})" if "raw_in_data" in j else ""
        L.append(f"| {r['scenario']} | {_fmt(injv)} {u} | {_fmt(j.get('raw'))} | {_fmt(j.get('none'))} | {_fmt(j.get('delta'))} | {j.get('rel_error', '')} | "
                 f"{j.get('ci_covers', '')} | {j.get('source', 'not refitted (screen negligible or not applicable)')} | "
                 f"{_fmt(j.get('final'))}{'' if 'final' not in j else ' (' + str(j['rel_error_final']) + ')'} | "
                 f"{_fmt(j.get('delta_in_base'))} | {j.get('rel_error_in_base', '')} | "
                 f"{_fmt(j.get('delta_in_data'))}{data_raw} | "
                 f"{j.get('rel_error_in_data', '')} | "
                 f"{'' if gain_ceiling(r) is None else f'{gain_ceiling(r):.1%}'} | {'yes' if j['found'] else 'no'} | "
                 f"{'yes' if j['found_in_base'] else ('no' if 'delta_in_base' in j else '—')} | "
                 f"{'yes' if j['found_in_data'] else ('no' if 'delta_in_data' in j else '—')} |")
    L += ["", ("The injected effect's own candidate in each scenario (its single refit against the no-effect refit; "
               "the verdict as the diagnosis states it):"), "",
          "| scenario | candidate | validation gain | verdict |", "|---|---|---|---|"]
    for r in inj_all:
        k = r.get("ranking", {}).get(r["expected"])
        if k:
            L.append(f"| {r['scenario']} | {r['expected']} | {100 * k['validation_gain']:.1f} % | {k['verdict']} |")
    L += ["", "Why an injection is not found (from the numbers above):", ""]
    for r in inj_all:
        j, k = r["judge"], r.get("ranking", {}).get(r["expected"]) or {}
        if j["found"]:
            continue
        sel = r["selected"].split("+") if r["selected"] else []
        c = gain_ceiling(r)
        if j["found_in_data"] and not j["found_in_base"]:
            f = (r.get("in_data") or {}).get(IN_DATA[r["expected"]], {})
            why = (f"the data-consistency check states it: {_fmt(j['delta_in_data'])} {j['unit']} against the none row "
                   f"(raw {_fmt(j['raw_in_data'])}, none row {_fmt(j.get('none_in_data'))}; {f.get('method', '')}); "
                   "the model search, judged on held-out E, "
                   + ("selects it too" if j["selected_any"] else "does not select it")
                   + (f" (its refit: {k.get('verdict', 'not refitted')})" if not j["selected_any"] else ""))
        elif j["found_in_base"]:
            why = (f"the base model's own coefficient is the effect: it moved by {_fmt(j['delta_in_base'])} {j['unit']} "
                   f"(injected {_fmt([x / UNIT[r['expected']][0] for x in injected_vector(r['scenario'])])} {j['unit']}); "
                   "the diagnosis' own candidate of that name has nothing left to find")
        elif r["expected"] in sel:
            one = [v / UNIT[r["expected"]][0] for v in k.get("params", {}).values()]
            why = (f"selected at greedy step {sel.index(r['expected']) + 1}, after {', '.join(sel[:sel.index(r['expected'])])}, "
                   f"with size {_fmt(j.get('delta'))} {j['unit']} ({100 * j['rel_error']:.0f} % off): refitted jointly "
                   f"with the real-gap effects it trades against them (its single refit: {_fmt(one)} {j['unit']})")
        elif c is not None and c < 0.05:
            why = (f"the channels it changes carry at most {c:.1%} of E, below the 5 % minimum gain: it can pass only "
                   f"through the base coefficients refitted with it, and here they cost more than it gained "
                   f"(fitted size {_fmt(j.get('delta'))} {j['unit']}; its refit: {k.get('verdict', '')})")
        else:
            why = f"its refit: {k.get('verdict', 'not refitted')}"
        L.append(f"- {r['scenario']}: {why}.")
    ceil_rows = [r for r in inj_all if gain_ceiling(r) is not None and r["expected"] in r.get("ranking", {})]
    L += [] if not ceil_rows else ["", "*Largest E gain possible*: for an effect that changes only some channels (a heading bias: the track "
          "only), the relative drop of the validation error E if the whole "
          "error of those channels went (`gain_ceiling`), computed from the scenario's base *where* line. Below the acceptance rule's 5 % minimum "
          "gain such an effect can pass only through the base coefficients refitted with it (a bias that distorted the "
          "base fit's hull coefficients frees them) — the real heading gap dominates E. Single-refit gain against the "
          "ceiling: " + "; ".join(f"{r['scenario']} {100 * r['ranking'][r['expected']]['validation_gain']:.1f} % against "
                                   f"{100 * gain_ceiling(r):.1f} %" for r in ceil_rows) + "."]
    cols = sorted({r["first_selected"] for r in rows})
    L += ["", "Confusion (injected × first selected):", "", "| injected \\ first selected | " + " | ".join(cols) + " |",
          "|---|" + "---|" * len(cols)]
    for r in rows:
        L.append(f"| {r['expected']} | " + " | ".join("1" if r["first_selected"] == c else "" for c in cols) + " |")
    L += ["", "Where (verdict line per scenario):", ""] + [f"- {r['scenario']}: {r.get('verdict_where', '')}" for r in rows]
    L += ["", "Which:", ""] + [f"- {r['scenario']}: {r.get('verdict_which', '')}" for r in rows]
    L += ["", "In the base (the verdict's line for an effect the base model carries as a parameter of its own, "
          "`Diagnosis.in_base`; rows that do not record it are left blank):", ""] + \
        [f"- {r['scenario']}: {r.get('verdict_in_base') or ('—' if 'verdict_in_base' in r else 'not recorded')}" for r in rows]
    L += ["", "In the data (the verdict's line for the data-consistency findings, `Diagnosis.in_data`; every check's "
          "estimate in the table below, a finding or not):", ""] + \
        [f"- {r['scenario']}: {r.get('verdict_in_data') or ('—' if 'verdict_in_data' in r else 'not recorded')}" for r in rows]
    L += ["", "| scenario | check | estimate | 95 % half-width | finding | held-out misfit without → with | why |",
          "|---|---|---|---|---|---|---|"]
    for r in rows:
        for k, f in (r.get("in_data") or {}).items():
            sc_ = 180 / math.pi if f["unit"] in ("rad", "rad/s") else 1.0
            un = {"rad": "°", "rad/s": "°/s"}.get(f["unit"], f["unit"])
            L.append(f"| {r['scenario']} | {k} | {sc_ * f['value']:.3g} {un} | {sc_ * f['half95']:.2g} {un} | "
                     f"{'yes' if f['found'] else 'no'} | {f['heldout'][0]:.3g} → {f['heldout'][1]:.3g} {f['misfit_unit']} | "
                     f"{f['reason']} |")
    (OUT / f"{stem}.md").write_text("\n".join(L) + "\n")
    print("\n".join(L))
