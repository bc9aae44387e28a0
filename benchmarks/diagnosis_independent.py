"""Gap diagnosis judged on data it was not built from.

Scenarios come from :mod:`benchmarks.independent` (NumPy-only truths, own integrator, own
effect implementations; shares no code with diffship). For each scenario: wrap the generated
arrays into :class:`diffship.data.Run` objects *here*, run
``diffship.diagnose.diagnose(base, train, val)`` (base fit by output error on the training runs,
selection on the held-out runs), and score

* **top-1**: the first selected effect is the hidden one (null cases: nothing selected);
* **top-3**: the hidden effect is among the first three of the ranking (selected first, then by
  validation gain, only candidates with a positive gain);
* **shrink**: share of the structural validation gap closed, 1 − S(E_after)/S(E_base) with
  S(E) = √(E² − E_truth²) (noise and model error add in quadrature), E_truth the truth's own
  error on the validation runs (pure noise, same normalisation) — the real floor; the CSV also
  has the linear form (E_base − E_after)/(E_base − E_truth);
* **null false alarms**; **out of family**: the first selected effect is of the right family;
* the confusion matrix (true × first selected), in and out of family separately;
* the CPU time (``time.process_time``, compilation included) of the screen of all candidates.

**Which counting the headline numbers use.** top-1 and "right family first" count only the
*first selected* effect (an attribution). Reported separately, never in the headline:

* **possible** hits: under the gap gate nothing is selected, but the diagnosis may name a
  *possible* effect (low confidence); a possible hit is an in-family scenario whose hidden effect
  is the first possible one (on null cases any possible effect is a possible false alarm);
* **right family named, partial counted** (out of family): the first selected effect is of the
  right family, or nothing is selected and the verdict's nearest miss (the candidate with the
  largest validation gain, stated as at most a partial explanation) is of the right family;
* **partial**: the selected effects leave a structural gap (E_after ≥ the gate) and the verdict
  says so.

Usage::

    python -m benchmarks diagnosis_independent --quick   # strong sizes, one seed (≈ 20–30 min on 2 shared cores)
    python -m benchmarks diagnosis_independent           # weak + strong, two seeds, two nulls per vessel
    python -m benchmarks diagnosis_independent --only usv-current   # scenarios whose name contains the text

Writes ``benchmarks/results/diagnosis_independent[_quick].md``, ``.csv`` and a confusion-matrix figure.
"""

from __future__ import annotations

import argparse
import csv
import time
from collections import Counter
from pathlib import Path

import numpy as np

import diffship  # noqa: F401  (float64)
from diffship.data import Run
from diffship.diagnose import FAMILY, DiagnoseOptions, diagnose
from diffship.diagnose.verdict import nearest_miss
from diffship.models import Fossen3, Nomoto1

from benchmarks import independent  # the generator: no diffship inside
from benchmarks.common.timing import commit as git_commit

OUT = Path(__file__).resolve().parent / "results"


COMMIT = git_commit()  # the commit the diagnosis ran from (rows merged from older runs say which code)


def to_runs(gen: list[dict]) -> list[Run]:
    return [Run(g["name"], g["time"], g["channels"], {"source": "benchmarks.independent"}) for g in gen]


def truth_error(gen: list[dict], floor: dict[str, float], channels) -> float:
    """E of the truth itself on the validation runs (measurement minus noise-free truth)."""
    z = []
    for c in channels:
        d = np.concatenate([g["channels"][c] - g["clean"][c] for g in gen])
        z.append(np.mean(d * d) / floor[c] ** 2)
    return float(np.sqrt(np.mean(z)))


def run_one(sc, options: DiagnoseOptions, say=None) -> dict:
    g = independent.generate(sc)
    train, val = to_runs(g["train"]), to_runs(g["val"])
    base = Nomoto1() if sc.vessel == "ship" else Fossen3()
    c0, t0 = time.process_time(), time.perf_counter()
    d = diagnose(base, train, val, options=options, progress=say)
    cpu, wall = time.process_time() - c0, time.perf_counter() - t0
    E_truth = truth_error(g["val"], d.noise_floor, d.channels)
    # structural gap above the truth's own error, in quadrature (noise and model error are independent)
    S0 = np.sqrt(max(d.E_before ** 2 - E_truth ** 2, 0.0))
    S1 = np.sqrt(max(d.E_after ** 2 - E_truth ** 2, 0.0))
    real_gap = d.E_before > 1.05 * E_truth
    shrink = 1.0 - S1 / S0 if real_gap else float("nan")
    shrink_linear = (d.E_before - d.E_after) / (d.E_before - E_truth) if real_gap else float("nan")
    first = d.selected[0] if d.selected else "none"
    ranked = [r.effect for r in d.ranking if r.effect in d.selected or (r.validation_gain or 0) > 0][:3]
    if sc.kind == "none":
        top1 = top3 = not d.selected
    elif sc.kind == "out":
        top1 = first != "none" and FAMILY[first] == sc.family
        top3 = any(FAMILY[r] == sc.family for r in ranked)
    else:
        top1 = first == sc.label
        top3 = sc.label in ranked
    row = next((r for r in d.ranking if r.effect == first), None)
    poss = d.possible[0] if d.possible else "none"
    miss = nearest_miss(d.ranking) if not d.selected and d.E_before >= d.gap_gate else None
    nearest = miss.effect if miss is not None else "none"
    if sc.kind == "none":
        possible_hit = False
        named = not d.selected
    elif sc.kind == "out":
        possible_hit = poss != "none" and FAMILY[poss] == sc.family
        named = top1 or (not d.selected and nearest != "none" and FAMILY[nearest] == sc.family)
    else:
        possible_hit = poss == sc.label
        named = top1
    return {"scenario": sc.name, "vessel": sc.vessel, "kind": sc.kind, "truth": sc.label, "size": sc.size,
            "seed": sc.seed, "selected": "+".join(d.selected) or "none", "first": first, "top1": top1, "top3": top3,
            "E_base": d.E_before, "E_after": d.E_after, "E_truth": E_truth, "shrink": shrink, "shrink_linear": shrink_linear,
            "possible": "+".join(d.possible) or "none", "possible_hit": possible_hit, "partial": d.partial,
            "nearest_miss": nearest, "family_named": named,
            "confidence": getattr(row, "confidence", "") if row is not None else "",
            "verdict": d.verdict[1],
            "in_data": "+".join(f"{k}={f.shown()}" for k, f in d.in_data.items() if f.found) or "none",
            "screen_cpu_s": d.timings.get("screen_cpu", float("nan")),
            "screen_s": d.timings["screen"], "n_candidates": len(d.screen), "cpu_s": cpu, "wall_s": wall,
            "finished_utc": time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime()), "commit": COMMIT}


def confusion(rows, kind) -> list[str]:
    rs = [r for r in rows if r["kind"] in kind]
    if not rs:
        return []
    truths = sorted({r["truth"] for r in rs})
    cols = sorted({r["first"] for r in rs} | ({"none"} if "none" in kind else set()))
    cnt = Counter((r["truth"], r["first"]) for r in rs)
    lines = ["| true \\ selected | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for t in truths:
        lines.append(f"| {t} | " + " | ".join(str(cnt.get((t, c), "")) for c in cols) + " |")
    return lines


def pct(xs) -> str:
    return f"{100 * np.mean(xs):.0f} % ({int(np.sum(xs))}/{len(xs)})" if len(xs) else "-"


def summarise(rows) -> list[str]:
    inn = [r for r in rows if r["kind"] == "in"]
    none = [r for r in rows if r["kind"] == "none"]
    out = [r for r in rows if r["kind"] == "out"]
    shr = [r["shrink"] for r in inn if np.isfinite(r["shrink"])]
    shr_hit = [r["shrink"] for r in inn if np.isfinite(r["shrink"]) and r["top1"]]
    scpu = [r["screen_cpu_s"] for r in rows if r["vessel"] == "usv"]
    lines = [
        (f"- in family: top-1 {pct([r['top1'] for r in inn])} (target ≥ 90 %), top-3 {pct([r['top3'] for r in inn])}; "
         f"median shrink of the structural gap {np.median(shr) if shr else float('nan'):.2f} over all in-family "
         f"scenarios, {np.median(shr_hit) if shr_hit else float('nan'):.2f} over the hits (target ≥ 0.9)"),
    ]
    for size in sorted({r["size"] for r in inn}):
        rs = [r for r in inn if r["size"] == size]
        lines.append(f"  - {size}: top-1 {pct([r['top1'] for r in rs])}")
    miss_in = [r for r in inn if not r["top1"]]
    lines += [
        (f"- possible effects (low confidence, under the gate; NOT in the headline): in-family misses whose hidden "
         f"effect is named as possible {int(sum(bool(r.get('possible_hit')) for r in miss_in))}/{len(miss_in)}, "
         f"wrong possible effect {sum(1 for r in miss_in if r.get('possible', 'none') != 'none' and not r.get('possible_hit'))}; "
         f"null cases with a possible effect {sum(1 for r in none if r.get('possible', 'none') != 'none')}/{len(none)}"),
        f"- partial (a structural gap remains after the selected effects, stated in the verdict): "
        f"{sum(1 for r in rows if r.get('partial') is True)}/{sum(1 for r in rows if r['first'] != 'none')} attributions",
        f"- null cases: false alarms {pct([not r['top1'] for r in none])} (target ≤ 10 %)",
        (f"- in the data (the data-consistency findings, `Diagnosis.in_data`, beside the model search; NOT in the "
         f"headline): null cases with a finding {sum(1 for r in none if r.get('in_data', 'none') != 'none')}/{len(none)}; "
         "scenarios with one: " + (", ".join(f"{r['scenario']} ({r['in_data']})" for r in rows
                                             if r.get("in_data", "none") not in ("none", "")) or "none")),
        (f"- out of family: right family first {pct([r['top1'] for r in out])} (target ≥ 60 %), "
         f"right family in the top 3 {pct([r['top3'] for r in out])}; right family named with partial "
         f"explanations counted (NOT the headline) {pct([bool(r.get('family_named', r['top1'])) for r in out])}"),
        (f"- screen of {int(min(r['n_candidates'] for r in rows))}–{int(max(r['n_candidates'] for r in rows))} candidates, "
         f"fossen3 USV (11 applicable, no wind measured): CPU time median {np.median(scpu):.1f} s, max {np.max(scpu):.1f} s (first call includes compilation; "
         "target ≤ 30 s)") if scpu else "- screen CPU time: no USV scenario run",
        (f"- whole diagnosis (base fit, screen, refits, greedy path): wall median {np.median([r['wall_s'] for r in rows]):.0f} s, "
         f"max {max(r['wall_s'] for r in rows):.0f} s; CPU median {np.median([r['cpu_s'] for r in rows]):.0f} s"),
    ]
    return lines


def figure(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(13, 5.5))
    for ax, kind, title in ((axes[0], ("in", "none"), "in family and null cases"), (axes[1], ("out",), "out of family")):
        rs = [r for r in rows if r["kind"] in kind]
        if not rs:
            ax.set_axis_off()
            continue
        truths = sorted({r["truth"] for r in rs})
        cols = sorted({r["first"] for r in rs})
        M = np.zeros((len(truths), len(cols)))
        for r in rs:
            M[truths.index(r["truth"]), cols.index(r["first"])] += 1
        ax.imshow(M, cmap="Blues")
        ax.set_xticks(range(len(cols)), cols, rotation=60, ha="right")
        ax.set_yticks(range(len(truths)), truths)
        for i in range(len(truths)):
            for j in range(len(cols)):
                if M[i, j]:
                    ax.text(j, i, int(M[i, j]), ha="center", va="center")
        ax.set_xlabel("first selected effect")
        ax.set_ylabel("hidden effect")
        ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _typed(r: dict) -> dict:
    out = {}
    for k, v in r.items():
        if k in ("commit", "finished_utc"):
            out[k] = v  # text, even when it looks like a number
        elif v in ("True", "False"):
            out[k] = v == "True"
        else:
            try:
                out[k] = float(v) if k not in ("seed",) else int(v)
            except ValueError:
                out[k] = v
    return out


def _by_code(rows) -> list[str]:
    """When merged rows were measured by different code (commit column; empty: runs from before
    the column existed), the summary of each part."""
    groups = {}
    for r in rows:
        groups.setdefault(r.get("commit") or "before the commit column", []).append(r)
    if len(groups) < 2:
        return []
    out = []
    for c, rs in groups.items():
        out += [f"### Only the {len(rs)} rows measured at {c}", "", *summarise(rs), ""]
    return out


GENERATOR_NOTE = (
    "Generator definition (since 2026-11-25): the truth ship has **no built-in rudder offset** (δ0 = 0), and "
    "`rudder_offset` is one of the ship's in-family effects (the hull sees the logged rudder + δ_off; strong 1.0°, "
    "weak 0.25°). Before, the truth ship carried δ0 = 0.004 rad in every scenario, nulls included; diffship holds a "
    "Nomoto model's own δ0 at 0 in the base fit so that its `rudder_offset` candidate stands for it, so those ship "
    "\"nulls\" held a rudder offset (a wrong label, not a wrong diagnosis) and ship scenarios reported "
    "\"…+rudder_offset\". Results from before that date are not comparable on the ship rows.")


def write_md(rows, stem: str, command: str, wall: float):
    summ = summarise(rows)
    figure(rows, OUT / f"{stem}_confusion.png")
    md = [f"# Gap diagnosis on independent data ({stem})", "",
          (f"Command: `{command}`; {len(rows)} scenarios"
           + (f", wall time {wall:.0f} s" if np.isfinite(wall) else "")
           + " on a shared 2-core CPU (timings disturbed by other jobs)."), "",
          ("Truths from `benchmarks/independent` (NumPy-only, own RK4, physics-level effects; no diffship code). "
           "Base models: `Nomoto1` (ship zigzags, channels ψ, r) and `Fossen3` (USV, x, y, ψ, u, v, r), "
           "fitted from their defaults on 4 training runs; selection on 2 held-out runs."), "", GENERATOR_NOTE, "", *summ, "", *_by_code(rows),
          "## Confusion matrix, in family and null cases (rows: hidden effect, columns: first selected)", "",
          *confusion(rows, ("in", "none")), "", "## Confusion matrix, out of family", "", *confusion(rows, ("out",)), "",
          f"![confusion]({stem}_confusion.png)", "", "## Scenarios", "",
          "| scenario | selected | top-1 | top-3 | possible | nearest miss | E base | E after | E truth | shrink | confidence | in the data | screen CPU s | commit |",
          "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        md.append(f"| {r['scenario']} | {r['selected']} | {r['top1']} | {r['top3']} | {r.get('possible', '-')} | "
                  f"{r.get('nearest_miss', '-')} | {r['E_base']:.2f} | {r['E_after']:.2f} | "
                  f"{r['E_truth']:.2f} | {r['shrink']:.2f} | {r['confidence']} | {r.get('in_data', '-')} | {r['screen_cpu_s']:.1f} | {r.get('commit') or 'before diag5'} |")
    md += ["", "## Verdicts (which)", ""] + [f"- {r['scenario']}: {r['verdict']}" for r in rows]
    (OUT / f"{stem}.md").write_text("\n".join(md) + "\n")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="strong sizes, one seed, one null per vessel")
    p.add_argument("--only", default="", help="run only scenarios whose name contains this text (comma-separated)")
    p.add_argument("--vessels", default="ship,usv")
    p.add_argument("--verbose", action="store_true")
    p.add_argument("--stem", default="", help="result file name (without extension) instead of the default")
    p.add_argument("--merge", nargs="+", default=None,
                   help="write diagnosis_independent.md from these result CSVs (runs done separately) and stop")
    a = p.parse_args(argv)
    if a.merge:
        rows = []
        for f in a.merge:
            with open(f, newline="") as fh:
                rows += [_typed(r) for r in csv.DictReader(fh)]
        rows = list({r["scenario"]: r for r in reversed(rows)}.values())[::-1]  # a scenario run twice: the first
        write_md(rows, "diagnosis_independent", "python -m benchmarks diagnosis_independent --merge "
                 + " ".join(Path(f).name for f in a.merge), float("nan"))
        print("\n".join(summarise(rows)))
        return
    vessels = tuple(a.vessels.split(","))
    if a.quick:
        grid = independent.scenarios(vessels, sizes=("strong",), seeds=(1,), nulls=1)
    else:
        grid = independent.scenarios(vessels, sizes=("weak", "strong"), seeds=(1, 2), nulls=2)
    if a.only:
        keys = a.only.split(",")
        grid = list(dict.fromkeys(s for k in keys for s in grid if k in s.name))  # in the order asked
    stem = "diagnosis_independent" + ("_quick" if a.quick else "") + ("" if a.vessels == "ship,usv" else "_" + "_".join(vessels)) \
        + ("_" + "_".join(k.replace("-", "") for k in a.only.split(",")) if a.only else "")
    stem = a.stem or stem
    OUT.mkdir(exist_ok=True)
    t0 = time.perf_counter()
    rows = []
    for sc in grid:
        r = run_one(sc, DiagnoseOptions(), say=print if a.verbose else None)
        rows.append(r)
        with open(OUT / f"{stem}.csv", "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
        print(f"[{r['finished_utc'][11:]} UTC, {time.perf_counter() - t0:6.0f} s] {r['scenario']:34s} → {r['selected']:28s} top1={r['top1']!s:5s} "
              f"E {r['E_base']:.2f}→{r['E_after']:.2f} (truth {r['E_truth']:.2f}) shrink {r['shrink']:.2f} "
              f"[{r['confidence']}] possible {r['possible']} nearest miss {r['nearest_miss']} "
              f"screen {r['screen_cpu_s']:.1f} s CPU", flush=True)
    write_md(rows, stem, (f"python -m benchmarks diagnosis_independent{' --quick' if a.quick else ''}"
                          f"{' --vessels ' + a.vessels if a.vessels != 'ship,usv' else ''}"
                          f"{' --only ' + a.only if a.only else ''}{' --stem ' + a.stem if a.stem else ''}"),
             time.perf_counter() - t0)
    print("\n".join(summarise(rows)))
