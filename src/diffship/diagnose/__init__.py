r"""Gap diagnosis: where a fitted model misses, which unmodelled effect explains it, how much.

``diagnose(model, train, val)`` (or ``python -m diffship.diagnose``):

1. fits the base model by output error on ``train`` (unless ``fit=`` is given);
2. **where** — error split per channel, phase, operating region and run on ``val``, residual
   whiteness / cross-correlation tests, inverse-dynamics force residuals, and a gap budget
   (noise floor, parameter uncertainty, structural remainder), see :mod:`.where`;
3. **which** — screens every applicable candidate of the effect library
   (:mod:`.effects`) with a score test, refits the best with warm starts, and **selects on
   held-out validation error only** (:mod:`.screen`);
4. **how far** — a greedy path of accepted effects with validation error before/after per
   channel and as a fraction of the structural gap, effect parameters with 95 % intervals.

Acceptance rule for an effect (all must hold):

* the structural gap exists: :math:`E_{base} \ge 1.2\,E_{floor}` (E normalised by the noise
  floor, so :math:`E_{floor} = 1`);
* validation error drops by at least ``min_gain`` (5 %) **and** by more than the noise-level
  threshold ``max(0.1, 2·SE)`` in normalised units (SE of the mean per-run gain), on a
  majority of the validation runs;
* the removed part is at least 30 % of the structural gap (shrink ≥ 0.3);
* at least one effect parameter is relevant (|φ̂| ≥ min_relevant) and its 95 % interval
  excludes the null.

Candidates that also pass and come within ``confusable_margin`` of the winner's validation
error are reported as confusable, with the manoeuvre that would separate them.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Sequence

import numpy as np

from ..data import Run
from ..errors import DataError, FitError
from ..fit import fit_output_error
from ..fit.result import FitResult
from ..metrics import evaluate
from ..models._base import AbstractModel
from ..params import ParamSpec
from .effects import EFFECT_NAMES, FAMILY, Augmented, augment, library, make_effect
from .screen import Workspace
from .where import noise_floor, normalised_error, where_analysis

__all__ = ["diagnose", "Diagnosis", "Augmented", "augment", "make_effect", "library", "EFFECT_NAMES", "FAMILY"]


@dataclasses.dataclass(frozen=True, eq=False)
class Diagnosis:
    """Everything :func:`diagnose` found (``to_dict()`` gives the JSON)."""

    model_name: str
    channels: tuple[str, ...]
    noise_floor: dict[str, float]
    where: dict
    gap: dict
    screen: list
    ranking: list[dict]
    selected: list[str]
    path: list[dict]
    rmse_before: dict[str, float]
    rmse_after: dict[str, float]
    E_before: float
    E_after: float
    shrink: float
    verdict: list[str]
    base_fit: FitResult
    final_model: AbstractModel
    eval_before: object
    eval_after: object
    skipped: dict[str, str]
    timings: dict[str, float]
    val_runs: tuple = ()

    def to_dict(self) -> dict:
        w = {k: v for k, v in self.where.items() if not k.startswith("_")}
        return {
            "model": self.model_name,
            "channels": list(self.channels),
            "verdict": self.verdict,
            "where": w,
            "gap_budget": self.gap,
            "screen": [dataclasses.asdict(s) for s in self.screen],
            "ranking": self.ranking,
            "selected": list(self.selected),
            "path": self.path,
            "validation_rmse_before": self.rmse_before,
            "validation_rmse_after": self.rmse_after,
            "validation_E_before": self.E_before,
            "validation_E_after": self.E_after,
            "noise_floor": self.noise_floor,
            "shrink": self.shrink,
            "shrink_definition": "(E_before - E_after) / (E_before - E_floor): fraction of the structural "
                                 "(above-noise) validation error removed by the selected effects",
            "shrink_total_error": (self.E_before - self.E_after) / self.E_before if self.E_before > 0 else 0.0,
            "base_params": self.base_fit.params,
            "final_params": self.final_model.param_values(),
            "not_applicable": self.skipped,
            "timings_s": self.timings,
        }


def _rmse(ev, chans):
    return {c: float(ev.rmse[c]) for c in chans if c in ev.rmse}


def diagnose(
    model: AbstractModel,
    train: Sequence[Run],
    val: Sequence[Run],
    *,
    fit: FitResult | None = None,
    spec: ParamSpec | None = None,
    effects: Sequence[str] | str = "all",
    channels: Sequence[str] | None = None,
    max_refits: int = 4,
    max_absorbed: int = 3,
    refit_all: bool = False,
    greedy_steps: int = 2,
    max_pairs: int = 3,
    min_gain: float = 0.05,
    gap_gate: float = 1.2,
    min_shrink: float = 0.3,
    confusable_margin: float = 0.05,
    max_iter: int = 30,
    fit_steps: int = 200,
    noise: dict[str, float] | None = None,
    progress: Callable[[str], None] | None = None,
) -> Diagnosis:
    """Diagnose the gap of ``model`` (see the module docstring for the rules).

    Args:
        model: base model (its values are the fit's start) or the fitted model when ``fit``
            is given.
        train, val: training runs and held-out validation runs (validation is required:
            selection never uses the training fit alone).
        fit: an existing output-error fit of ``model`` on ``train`` (skips the base fit).
        spec: free/fixed parameters of the base fit.
        effects: ``"all"`` or names from :data:`EFFECT_NAMES`.
        max_refits: candidates refitted by screening rank, plus up to ``max_absorbed`` of
            those the base parameters absorb (o_k < 0.1), which the screen under-rates;
            ``refit_all`` refits every candidate.
        max_pairs: when no single effect passes, refit up to this many pairs of the best
            single candidates jointly (two effects that compensate each other alone).
        noise: per-channel noise floor (known sensor noise); estimated from the data if None.
    """
    say = progress or (lambda s: None)
    timings = {}
    if not train:
        raise DataError("diagnose: no training runs given")
    if not val:
        raise DataError("diagnose: no validation runs given (--validate VAL.csv ...); effects are selected on "
                        "held-out runs only, never on the training fit")
    names = list(EFFECT_NAMES) if effects == "all" else list(effects)
    for n in names:
        if n not in EFFECT_NAMES:
            raise DataError(f"unknown effect {n!r}; choose from: {', '.join(EFFECT_NAMES)}")
    t0 = time.perf_counter()
    spec = spec or model.spec()
    if fit is None:
        say(f"fitting the base model {model.name} by output error on {len(train)} runs...")
        from ..fit.problem import default_channels

        chans0 = tuple(channels) if channels else default_channels(model, train)
        fit = fit_output_error(model, train, spec=spec, channels=chans0, max_steps=fit_steps, progress=say,
                               estimate_x0=model.states_for_channels(chans0))
    timings["base_fit"] = time.perf_counter() - t0
    base = fit.model
    chans = tuple(fit.channels)
    base_spec = spec.with_values({n: fit.params[n] for n in spec.names})
    floor = dict(noise) if noise else noise_floor(list(train) + list(val), chans, base.angle_outputs)
    scales = {c: max(fit.noise_std.get(c, floor[c]), floor[c]) for c in chans}

    # -- which: screen -----------------------------------------------------------------
    t0 = time.perf_counter()
    effs, skipped = library(base, train, names)
    if not effs:
        raise DataError(f"no candidate effect applies to {base.name} with these runs: {skipped}")
    say(f"screening {len(effs)} candidate effects ({', '.join(e.name for e in effs)})...")
    x0_train = fit.initial_states if len(fit.initial_states) == len(train) else None
    ws = Workspace(base, base_spec, effs, train, chans, scales, x0_train=x0_train)
    scr, sinfo = ws.screen()
    timings["screen"] = time.perf_counter() - t0
    val_data = ws.data(val)
    nb = len(base.state_names)

    # -- where -----------------------------------------------------------------------------
    t0 = time.perf_counter()
    x0_val = ws.fitted_x0(val_data, {}, None)
    ev0 = evaluate(base, val, x0=[x[:nb] for x in x0_val])
    E0 = normalised_error(ev0, floor, chans)
    where = where_analysis(base, val, ev0, floor, chans)
    E0_runs = {r.name: normalised_error(ev0, floor, chans, r.name) for r in val}
    timings["where"] = time.perf_counter() - t0
    gap = _gap_budget(fit, ev0, floor, chans, E0)
    say(f"validation error {E0:.3g} × noise floor; screen took {timings['screen']:.1f} s")

    # -- which: refit and validate ---------------------------------------------------------
    t0 = time.perf_counter()
    by_name = {s.effect: s for s in scr}
    order = [s.effect for s in scr if s.orthogonal_fraction > 0 or s.predicted_fraction > 0]
    if refit_all:
        todo = order
    else:
        # the screen's best, plus the best of those it under-rates (absorbed by the base, o_k < 0.1)
        low = [s.effect for s in scr if 0 < s.orthogonal_fraction < 0.1 and s.effect not in order[:max_refits]]
        todo = order[:max_refits] + low[:max_absorbed]
    has_gap = E0 >= gap_gate

    def validate(values, base_values):
        m = ws.model_with(values, base_values)
        ev = evaluate(m, val, x0=ws.fitted_x0(val_data, values, base_values))
        E = normalised_error(ev, floor, chans)
        Er = {r.name: normalised_error(ev, floor, chans, r.name) for r in val}
        return m, ev, E, Er

    def judge(rf, E_ref, Er_ref, E, Er, effect_names):
        gain = (E_ref - E) / E_ref if E_ref > 0 else 0.0
        d = np.array([Er_ref[k] - Er[k] for k in Er])
        # run-to-run standard error only when there are enough validation runs to estimate it
        se = float(np.std(d, ddof=1) / math.sqrt(d.size)) if d.size >= 4 else 0.0
        thr = max(0.1, 2 * se)
        majority = bool(np.sum(d > 0) > d.size / 2)
        shrink = (E0 - E) / (E0 - 1.0) if E0 > 1.0 else 0.0
        relevant, ci_ok = False, False
        for e in ws.effects:
            if e.name not in effect_names:
                continue
            for n in e.param_names:
                v, s = rf.values[n], rf.stderr.get(n, float("inf"))
                relevant |= abs(v - e.null()[n]) >= e.MIN_RELEVANT.get(n, 0.0)
                ci_ok |= abs(v - e.null()[n]) > 1.96 * s
        ok = has_gap and rf.ok and gain >= min_gain and (E_ref - E) > thr and majority and relevant and ci_ok
        reasons = []
        if not has_gap:
            reasons.append("no structural gap")
        if gain < min_gain or (E_ref - E) <= thr:
            reasons.append(f"validation gain {100 * gain:.1f} % (ΔE {E_ref - E:.3g}) below the threshold "
                           f"({100 * min_gain:.0f} % and ΔE > {thr:.2g})")
        elif not majority:
            reasons.append("improves fewer than half of the validation runs")
        if not relevant:
            reasons.append("fitted magnitude below relevance")
        elif not ci_ok:
            reasons.append("95 % interval includes the null")
        return ok, gain, shrink, "; ".join(reasons), thr

    results = {}
    for name in todo:
        e = next(x for x in ws.effects if x.name == name)
        # smooth effects: LM from the null (the score test's point); non-smooth ones have a flat
        # null, so start them at the probe magnitude and around it
        starts = [e.null()] if e.smooth_null else [{k: f * v for k, v in e.PROBE.items()} for f in (1.0, 0.3, 3.0)]
        try:
            rf = ws.refit([name], starts, max_iter=max_iter, progress=say)
        except FitError as exc:
            say(f"  refit {name} failed: {exc}")
            continue
        m, ev, E, Er = validate(rf.values, rf.base_values)
        ok, gain, shrink, why, thr = judge(rf, E0, E0_runs, E, Er, [name])
        results[name] = dict(rf=rf, model=m, ev=ev, E=E, Er=Er, ok=ok, gain=gain, shrink=shrink, why=why)
        say(f"  {name}: validation E {E0:.3g} → {E:.3g} ({100 * gain:+.1f} %), shrink {shrink:.2f}"
            + ("" if ok else f" — not accepted: {why}"))
    timings["refits"] = time.perf_counter() - t0

    # -- greedy path ---------------------------------------------------------------------------
    t0 = time.perf_counter()
    accepted = sorted([n for n, r in results.items() if r["ok"] and r["shrink"] >= min_shrink], key=lambda n: results[n]["E"])
    path, selected = [], []
    cur_E, cur_Er, cur_vals, cur_base, cur_model, cur_ev = E0, E0_runs, {}, None, base, ev0
    if not accepted and has_gap and max_pairs > 0:
        # pair search: two effects at once can each fail alone (each compensates for the other
        # on some runs) yet pass together; try the best pairs by single-effect validation error
        top = sorted(results, key=lambda n: results[n]["E"])[:3]
        pairs = [(a, b) for i, a in enumerate(top) for b in top[i + 1:]][:max_pairs]
        best = None
        for a, b in pairs:
            pn = [p for e in ws.effects if e.name in (a, b) for p in e.param_names]
            if len(pn) > 5:
                continue
            st = {**results[a]["rf"].values, **results[b]["rf"].values}
            try:
                rf = ws.refit([a, b], [st], max_iter=max_iter, progress=say)
            except FitError:
                continue
            m, ev, E, Er = validate(rf.values, rf.base_values)
            ok, gain, shrink, why, thr = judge(rf, E0, E0_runs, E, Er, [a, b])
            say(f"  pair {a}+{b}: validation E {E0:.3g} → {E:.3g} ({100 * gain:+.1f} %)" + ("" if ok else f" — not accepted: {why}"))
            if ok and shrink >= min_shrink and (best is None or E < best[1]):
                best = ((a, b), E, Er, rf, m, ev)
        if best is not None:
            (a, b), E, Er, rf, m, ev = best
            order_ab = sorted((a, b), key=lambda n: results[n]["E"])
            selected = list(order_ab)
            path.append(_step("+".join(order_ab), E0, E, ev0, ev, chans, E0, rf))
            cur_E, cur_Er, cur_vals, cur_base, cur_model, cur_ev = E, Er, dict(rf.values), rf.base_values, m, ev
    if accepted:
        w = accepted[0]
        r = results[w]
        selected.append(w)
        path.append(_step(w, E0, r["E"], ev0, r["ev"], chans, E0, r["rf"]))
        cur_E, cur_Er, cur_vals, cur_base, cur_model, cur_ev = r["E"], r["Er"], dict(r["rf"].values), r["rf"].base_values, r["model"], r["ev"]
        cands = [n for n in sorted(results, key=lambda n: results[n]["E"]) if n != w and results[n]["gain"] > 0][:3]
        for _step_i in range(1, greedy_steps):
            best = None
            for n in cands:
                if n in selected:
                    continue
                effs_now = selected + [n]
                pn = [p for e in ws.effects if e.name in effs_now for p in e.param_names]
                if len(pn) > 5:
                    continue
                e = next(x for x in ws.effects if x.name == n)
                starts = [{**cur_vals, **e.null()}] if e.smooth_null else [
                    {**cur_vals, **{k: f * v for k, v in e.PROBE.items()}} for f in (1.0, 3.0)]
                try:
                    rf = ws.refit(effs_now, starts, max_iter=max_iter, progress=say)
                except FitError:
                    continue
                m, ev, E, Er = validate(rf.values, rf.base_values)
                ok, gain, shrink, why, thr = judge(rf, cur_E, cur_Er, E, Er, [n])
                say(f"  + {n}: validation E {cur_E:.3g} → {E:.3g} ({100 * gain:+.1f} %)" + ("" if ok else f" — not accepted: {why}"))
                if ok and (best is None or E < best[1]):
                    best = (n, E, Er, rf, m, ev)
            if best is None:
                break
            n, E, Er, rf, m, ev = best
            selected.append(n)
            path.append(_step(n, cur_E, E, cur_ev, ev, chans, E0, rf))
            cur_E, cur_Er, cur_vals, cur_base, cur_model, cur_ev = E, Er, dict(rf.values), rf.base_values, m, ev
        # swap pass: with two or more effects in, a confusable alternative of an early pick may now
        # fit better (e.g. a delay chosen first where a lag + damping is the truth)
        if len(selected) >= 2:
            alts = [n for n in accepted if n not in selected]
            best = None
            for i in range(len(selected)):
                for alt in alts:
                    trial = selected[:i] + [alt] + selected[i + 1:]
                    pn = [p for e in ws.effects if e.name in trial for p in e.param_names]
                    if len(pn) > 5:
                        continue
                    prev = {k: v for k, v in cur_vals.items() if k not in ws.owner or ws.owner[k].name != selected[i]}
                    e = next(x for x in ws.effects if x.name == alt)
                    try:
                        rf = ws.refit(trial, [{**prev, **(e.null() if e.smooth_null else e.PROBE)}], max_iter=max_iter,
                                      progress=say)
                    except FitError:
                        continue
                    m, ev, E, Er = validate(rf.values, rf.base_values)
                    say(f"  swap {selected[i]} -> {alt}: validation E {cur_E:.3g} → {E:.3g}")
                    if E < cur_E * 0.98 and (best is None or E < best[1]):
                        best = (trial, E, Er, rf, m, ev)
            if best is not None:
                trial, E, Er, rf, m, ev = best
                selected = trial
                cur_E, cur_Er, cur_vals, cur_base, cur_model, cur_ev = E, Er, dict(rf.values), rf.base_values, m, ev
                path = [{"effect": "+".join(selected), "E_before": float(E0), "E_after": float(E),
                         "shrink_of_structural_gap": float((E0 - E) / (E0 - 1.0)) if E0 > 1 else 0.0,
                         "rmse_before": _rmse(ev0, chans), "rmse_after": _rmse(ev, chans),
                         "params": dict(rf.values), "stderr": dict(rf.stderr), "note": "after a swap of confusable effects"}]
    timings["greedy"] = time.perf_counter() - t0

    # -- ranking and verdicts -------------------------------------------------------------------
    ranking = []
    winner = selected[0] if selected else None
    for s in scr:
        n = s.effect
        e = next(x for x in ws.effects if x.name == n)
        r = results.get(n)
        if r is None:
            if s.orthogonal_fraction == 0.0 and s.predicted_fraction == 0.0:
                verdict = "not identifiable from these runs (no effect on the fitted channels)"
            else:
                verdict = "not refitted (screen negligible)"
            ranking.append({"effect": n, "family": FAMILY[n], "params": {}, "stderr": {}, "validation_gain": 0.0,
                            "shrink": 0.0, "screen_fraction": s.predicted_fraction, "orthogonal_fraction": s.orthogonal_fraction,
                            "p_value": s.p_value, "verdict": verdict, "confusable_with": list(e.confusable_with),
                            "separating_manoeuvre": e.separating})
            continue
        if n in selected:
            verdict = "attributed" if n == winner else "attributed (greedy step %d)" % (selected.index(n) + 1)
        elif r["ok"] and winner and r["E"] <= results[winner]["E"] * (1 + confusable_margin) + 1e-12:
            verdict = f"confusable with {winner}: separate with {e.separating}"
        elif r["ok"] and winner:
            verdict = "explains part of the gap, but less than the selected effect(s)"
        elif r["ok"]:
            verdict = (f"helps on validation ({100 * r['gain']:.0f} %) but removes only {r['shrink']:.2f} of the "
                       f"structural gap (< {min_shrink}): a partial explanation, not attributed")
        elif s.orthogonal_fraction < 1e-3 and abs(r["gain"]) < min_gain:
            verdict = "not identifiable from these runs (absorbed by the base parameters)"
        elif r["gain"] < 0 and r["rf"].train_cost < sinfo["train_cost"] * 0.95:
            verdict = "rejected on validation (improves the training fit only)"
        else:
            verdict = "rejected: " + (r["why"] or "no validation gain")
        ranking.append({"effect": n, "family": FAMILY[n], "params": {k: r["rf"].values[k] for k in e.param_names},
                        "stderr": {k: r["rf"].stderr.get(k, float("nan")) for k in e.param_names},
                        "validation_gain": float(r["gain"]), "shrink": float(r["shrink"]),
                        "validation_E": float(r["E"]), "train_cost_reduction": 1 - r["rf"].train_cost / sinfo["train_cost"],
                        "screen_fraction": s.predicted_fraction, "orthogonal_fraction": s.orthogonal_fraction,
                        "p_value": s.p_value, "verdict": verdict, "confusable_with": list(e.confusable_with),
                        "separating_manoeuvre": e.separating})
    ranking.sort(key=lambda d: (0 if d["effect"] in selected else 1, -d["validation_gain"]))
    for n, why in skipped.items():
        ranking.append({"effect": n, "family": FAMILY[n], "params": {}, "validation_gain": 0.0, "shrink": 0.0,
                        "verdict": f"not applicable: {why}"})
    shrink = (E0 - cur_E) / (E0 - 1.0) if (E0 > 1.0 and selected) else 0.0
    final_model = Augmented(base, []) if not selected else _final(ws, base, selected, cur_vals, cur_base)
    d = Diagnosis(
        model_name=model.name, channels=chans, noise_floor=floor, where=where, gap=gap, screen=scr, ranking=ranking,
        selected=selected, path=path, rmse_before=_rmse(ev0, chans), rmse_after=_rmse(cur_ev, chans),
        E_before=E0, E_after=cur_E, shrink=float(shrink), verdict=[], base_fit=fit, final_model=final_model,
        eval_before=ev0, eval_after=cur_ev, skipped=skipped, timings=timings, val_runs=tuple(val),
    )
    from .report import verdict_lines

    return dataclasses.replace(d, verdict=verdict_lines(d))


def _final(ws, base, selected, vals, base_vals):
    effs = [e for e in ws.effects if e.name in selected]
    m = Augmented(base.with_params(base_vals), effs)
    return m.with_params({n: v for n, v in vals.items() if n in m.param_names})


def _step(name, E_from, E_to, ev_from, ev_to, chans, E0, rf):
    return {"effect": name, "E_before": float(E_from), "E_after": float(E_to),
            "shrink_of_structural_gap": float((E_from - E_to) / (E0 - 1.0)) if E0 > 1 else 0.0,
            "rmse_before": _rmse(ev_from, chans), "rmse_after": _rmse(ev_to, chans),
            "params": {k: v for k, v in rf.values.items()}, "stderr": dict(rf.stderr)}


def _gap_budget(fit: FitResult, ev, floor, chans, E) -> dict:
    """E² = noise² + param² + structural² (normalised units, noise floor = 1)."""
    # parameter part, approximated: with p parameters fitted to N residuals the prediction
    # variance from parameter uncertainty is about p/N of the residual variance (no validation
    # Jacobian is formed)
    n_p = len(fit.free)
    n = max(int(fit.info.get("n_residuals", 1)), 1)
    noise_sq = 1.0
    param_sq = E * E * n_p / n
    struct_sq = max(E * E - noise_sq - param_sq, 0.0)
    tot = max(E * E, 1e-300)
    return {"E_total": float(E), "E_noise": 1.0, "E_param": float(math.sqrt(param_sq)), "E_struct": float(math.sqrt(struct_sq)),
            "share_noise": float(min(noise_sq / tot, 1.0)), "share_param": float(param_sq / tot), "share_struct": float(struct_sq / tot),
            "note": "E is the validation RMS error per channel divided by the channel noise floor, averaged in "
                    "quadrature; E_param is a first-order approximation E*sqrt(p/N) (p free parameters, N residuals), "
                    "not a propagation of the covariance through a validation Jacobian"}
