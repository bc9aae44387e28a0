r"""What a user may do with a fit: one verdict per method, with its reasons in words.

A :class:`Verdict` joins what the solver said (:attr:`FitResult.result`, :mod:`diffship.fit.status`)
with what the whole-horizon simulations of the training and held-out runs show
(:class:`diffship.metrics.Evaluation`) and what the data identify:

* **FAILED** — not usable: the solver's outcome is unusable (the simulation blows up, the filter
  diverges, every start diverges), or the simulation is worse than the measured mean
  (NRMSE fit < 0 %) on *every* training run, or on the pooled training runs while no held-out run
  is followed either;
* **FAILED** also — held-out runs a fit does not predict: a fitted channel whose pooled NRMSE fit on the
  held-out runs is below :data:`HELD_OUT_SHARE` (half) of its training fit, or below 0 %; or a held-out standard
  manoeuvre of a type the fit was trained on (a zigzag of a zigzag-trained fit) whose metric misses the measured
  one by more than its 95 % interval and its tolerance (:mod:`diffship.predict.cross`) — the run, channel or
  metric named;
* **not followed (per run)** — a training or held-out run whose simulation is worse than its
  mean in a fitted channel is named with the channel and the time from which the error stays
  above the level the other runs reach (:func:`run_problems`); when the other training runs and
  the held-out runs are followed, the fit stays usable and says so;
* **not converged** — the solver stopped at its step limit (usable, with a warning);
* **FAILED** also — a free parameter with an infinite standard error (the data leave it entirely
  free: a rank-deficient Jacobian), or every free parameter unidentified as below, or a solve that did not
  converge with a parameter unidentified (it stopped where its steps ran out): the values identify nothing,
  however well the simulation follows the runs;
* **unidentifiable** — a free parameter with a standard error larger than
  :data:`WEAK_RATIO` × its value (or infinite): the data do not determine it; the cause is named
  where the data show it (a degree of freedom that hardly varies: "surge speed hardly varies:
  excite it or fix Xu").

Whatever the label, a verdict names every parameter the data do not determine (``unidentified``) and every
parameter on one of its bounds (``on_bound``, from the fit's identifiability: the data push it past what the
model allows, so its standard error is no interval), also in a FAILED verdict whose first reason is another.

The verdict travels: the fit file (``usable``, ``verdict``), the JSON report, the text report and
the exit status of ``python -m diffship.fit`` (1 when no method is usable, the reason on the last
line); ``predict`` and ``diagnose`` read it from the fit file and warn.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import numpy as np

from .data import Run
from .metrics import Evaluation

__all__ = ["HELD_OUT_SHARE", "WEAK_RATIO", "RunProblem", "Verdict", "held_out_problem", "manoeuvre_miss",
           "on_bound", "run_problems", "unidentified", "verdict"]

#: A free parameter whose standard error exceeds this multiple of its magnitude is not identified.
WEAK_RATIO = 10.0
#: A fit is not usable when a fitted channel's held-out fit % falls below this share of its training fit %.
HELD_OUT_SHARE = 0.5
#: Surge or sway "hardly varies" when the spread of its measured speed is below this share of the
#: mean surge speed.
QUIET_SHARE = 0.02

#: A yaw or roll rate whose spread is below this [rad/s] (0.2°/s) hardly varies.
QUIET_RATE = float(np.radians(0.2))

#: Which channel excites the parameters whose names start with each letter (MMG/VMM/Fossen names).
_DOF = {"X": ("u", "surge speed"), "Y": ("v", "sway speed"), "N": ("r", "yaw rate"), "K": ("p", "roll rate")}


@dataclasses.dataclass(frozen=True)
class RunProblem:
    """A run the model does not follow: ``run``, ``channel``, NRMSE ``fit`` [%] of that run and
    channel, ``from_s``: the time [s] from which the error stays large (``nan`` if from the start),
    ``kind``: ``"training"`` or ``"validation"``."""

    run: str
    channel: str
    fit: float
    from_s: float
    kind: str

    def text(self) -> str:
        when = (f" from t = {self.from_s:.0f} s" if math.isfinite(self.from_s) else "")
        return (f"{self.kind} run {self.run}: the model does not follow {self.channel}{when} "
                f"(fit {self.fit:.0f} % on this run)")

    def as_json(self) -> dict:
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True)
class Verdict:
    """One method's verdict: ``label`` (``"usable"``, ``"FAILED"``, ``"not converged"``,
    ``"unidentifiable"``), ``usable``, ``reasons`` (sentences), ``runs`` (per-run problems),
    ``weak`` (parameters the data do not determine, with the cause where known) and ``bound``
    (parameters on one of their bounds, in words)."""

    method: str
    label: str
    usable: bool
    reasons: tuple[str, ...] = ()
    runs: tuple[RunProblem, ...] = ()
    weak: tuple[str, ...] = ()
    bound: tuple[str, ...] = ()

    def lines(self) -> list[str]:
        name = self.method.replace('_', ' ')
        if not self.usable:
            why = self.reasons[0] if self.reasons else "no usable estimate"
            head, rest = f"{name}: FAILED — {why}; do not use these values", self.reasons[1:]
        else:
            head, rest = f"{name}: {self.label}", self.reasons
        out = [head] + [f"  - {r}" for r in rest] + [f"  - {p.text()}" for p in self.runs]
        out += [f"  - not identified: {w}" for w in self.weak]
        out += [f"  - on its bound: {b}" for b in self.bound]
        return out

    def as_json(self) -> dict:
        return {"label": self.label, "usable": self.usable, "reasons": list(self.reasons),
                "runs": [p.as_json() for p in self.runs], "unidentified": list(self.weak),
                "on_bound": list(self.bound)}


def _onset(t: np.ndarray, e: np.ndarray, level: float) -> float:
    """The first time from which at least 80 % of the later samples have ``|e| > level``
    (``nan`` when that is the first sample or never)."""
    big = np.abs(e) > level
    if not big.any():
        return math.nan
    later = np.cumsum(big[::-1])[::-1] / np.arange(len(big), 0, -1)  # share of big samples from k on
    k = int(np.argmax((later >= 0.8) & big))
    return float(t[k]) if k > 0 else math.nan


def run_problems(ev: Evaluation, runs: Sequence[Run], channels: Sequence[str], angles: Sequence[str] = ("psi",),
                 kind: str = "training") -> list[RunProblem]:
    """Runs of ``ev`` whose simulation is worse than their mean (fit < 0 %) in one of ``channels``,
    with the time from which the error stays above twice the channel's RMSE on the runs that are
    followed (or above the run's own spread when none is)."""
    out = []
    good_rmse = {c: [v["rmse"][c] for v in ev.per_run.values() if c in v["rmse"] and v["fit_percent"].get(c, -1) >= 0]
                 for c in channels}
    for run in runs:
        pr = ev.per_run.get(run.name)
        if pr is None:
            continue
        for c in channels:
            f = pr["fit_percent"].get(c)
            if f is None or (math.isfinite(f) and f >= 0.0):
                continue
            y = np.asarray(run[c])
            yh = np.asarray(ev.simulated[run.name][c])
            e = yh - y
            if c in angles:
                e = np.arctan2(np.sin(e), np.cos(e))
            level = 2.0 * float(np.median(good_rmse[c])) if good_rmse[c] else float(np.std(y))
            from_s = _onset(np.asarray(run.time), np.where(np.isfinite(e), e, np.inf), level) if level > 0 else math.nan
            out.append(RunProblem(run.name, c, float(f) if math.isfinite(f) else -math.inf, from_s, kind))
    return out


def _spread(runs: Sequence[Run], c: str) -> tuple[float, float] | None:
    vals = [np.asarray(r[c]) for r in runs if r.has(c)]
    if not vals:
        return None
    y = np.concatenate(vals)
    return float(np.std(y)), float(np.mean(np.abs(y)))


def unidentified(params: Mapping[str, float], stderr: Mapping[str, float], free: Sequence[str],
                 runs: Sequence[Run]) -> list[str]:
    """Free parameters with ``SE > WEAK_RATIO·|value|`` (or infinite), each with the cause where the data
    show one: the degree of freedom its name belongs to (X: surge, Y: sway, N: yaw) hardly varies."""
    out = []
    u = _spread(runs, "u")
    for n in free:
        v, se = float(params.get(n, math.nan)), float(stderr.get(n, math.nan))
        if not (math.isinf(se) or (math.isfinite(se) and se > WEAK_RATIO * max(abs(v), 1e-300))):
            continue
        text = f"{n} = {v:.3g} ± {se:.3g}"
        dof = _DOF.get(n[:1])
        sp = _spread(runs, dof[0]) if dof else None
        if dof and sp is not None:
            # surge and sway against the mean surge speed [m/s]; rates against QUIET_RATE [rad/s]
            ref = (sp[1] if dof[0] == "u" else (u[1] if u else 0.0)) * QUIET_SHARE if dof[0] in ("u", "v") else QUIET_RATE
            if sp[0] < ref:
                unit = "m/s" if dof[0] in ("u", "v") else "rad/s"
                text += (f": {dof[1]} hardly varies in the runs (spread {sp[0]:.3g} {unit}, below {ref:.3g}): "
                         f"excite it or fix {n} (--fix {n}=VALUE)")
        if ":" not in text:
            text += f": the data do not determine it; fix it (--fix {n}=VALUE), give a prior, or add runs that excite it"
        out.append(text)
    return out


def on_bound(result) -> list[str]:
    """Free parameters the fit left on one of their bounds (its identifiability, :mod:`diffship.fit.identifiability`),
    each in words: the data push it past what the model allows, so its standard error is no interval."""
    found = ((result.info or {}).get("identifiability") or {}).get("on_bound") or ()
    return [f"{b['name']} = {b['value']:.4g} is on its bound {b['bound']:g}: the data push it past what the model "
            "allows, so its standard error is no interval; look for a missing effect (diagnose) or reconsider the bound"
            for b in found]


def held_out_problem(train_ev: Evaluation | None, val_ev: Evaluation | None, channels: Sequence[str]) -> str:
    """Why a fit does not predict its held-out runs, or "": a fitted channel whose pooled held-out NRMSE fit is
    below :data:`HELD_OUT_SHARE` of its training fit (or below 0 %), or a held-out simulation that blows up."""
    if val_ev is None or train_ev is None:
        return ""
    if not val_ev.ok:
        return "its simulation of the held-out runs blows up"
    for c in channels:
        ft, fv = train_ev.fit_percent.get(c, math.nan), val_ev.fit_percent.get(c, math.nan)
        if not (math.isfinite(ft) and math.isfinite(fv)):
            continue
        if fv < 0.0 or (ft > 0.0 and fv < HELD_OUT_SHARE * ft):
            runs = ", ".join(f"{r} {v['fit_percent'].get(c, math.nan):.0f} %" for r, v in val_ev.per_run.items())
            return (f"it does not predict its held-out runs: {c} fit {fv:.0f} % on them against {ft:.0f} % in training "
                    f"(below {HELD_OUT_SHARE:.0%} of it; per run: {runs})")
    return ""


def manoeuvre_miss(checks) -> str:
    """Why a fit misses a held-out standard manoeuvre of a type it was trained on, or "": ``checks`` is the
    cross-manoeuvre validation (:func:`diffship.predict.cross.cross_validate` with ``trained_types``); a metric
    of a trained type's run that misses the measured value by more than its interval and tolerance (MISS)."""
    trained = {t.kind for t in getattr(checks, "train_types", ())}
    for c in getattr(checks, "checks", ()):
        if c.type.kind not in trained:
            continue
        for mt in c.metrics:
            if mt.flagged and getattr(mt, "outside_tolerance", True):
                iv = f" (95 % interval {mt.interval[0]:.4g}–{mt.interval[1]:.4g})" if mt.interval else ""
                return (f"it misses a held-out {c.type.label}, a manoeuvre type it was trained on: {c.run} "
                        f"{mt.name} predicted {mt.predicted:.4g} {mt.unit}, measured {mt.measured:.4g} {mt.unit}{iv}")
    return ""


def verdict(result, train_ev: Evaluation | None, train: Sequence[Run], val_ev: Evaluation | None = None,
            val: Sequence[Run] = (), manoeuvres=None) -> Verdict:
    """The verdict of one method's fit (see the module docstring); ``manoeuvres``: the cross-manoeuvre validation of
    the held-out runs (trained types included), whose misses of a trained type make the fit not usable."""
    m = result.method
    angles = tuple(getattr(result.model, "angle_outputs", ("psi",)))
    if not result.usable:  # no estimate (every start diverged, ...): its standard errors say nothing of the data
        return Verdict(m, "FAILED", False, (result.status,))
    # named in every verdict, FAILED ones included: a program reading the JSON finds them whatever the first reason
    weak = tuple(unidentified(result.params, result.stderr, result.free, train))
    bound = tuple(on_bound(result))
    chans = [c for c in (result.channels or ()) if train_ev is not None and c in train_ev.channels]
    if train_ev is not None and not chans:
        chans = [c for c in train_ev.channels if c not in ("x0", "y0")]
    reasons, probs = [], []
    if train_ev is not None:
        if not train_ev.ok:
            return Verdict(m, "FAILED", False, ("its simulation of the training runs blows up",), (), weak, bound)
        probs = run_problems(train_ev, train, chans, angles, "training")
    vprobs = run_problems(val_ev, val, chans, angles, "validation") if val_ev is not None and val else []
    bad_train = {p.run for p in probs}
    val_followed = bool(val) and val_ev is not None and val_ev.ok and not vprobs
    pooled_bad = train_ev is not None and any(not (train_ev.fit_percent.get(c, -1.0) >= 0.0) for c in chans)
    if train and bad_train and len(bad_train) == len(train):
        worst = min(probs, key=lambda p: p.fit)
        return Verdict(m, "FAILED", False, (f"its simulation is worse than the measured mean on every training run "
                                            f"(worst: {worst.run}, {worst.channel} fit {worst.fit:.0f} %)",),
                       tuple(probs + vprobs), weak, bound)
    if pooled_bad and not val_followed:
        worst = min(((c, train_ev.fit_percent.get(c, math.nan)) for c in chans), key=lambda x: x[1])
        return Verdict(m, "FAILED", False, (f"its simulation of the training runs is worse than the measured mean "
                                            f"({worst[0]} fit {worst[1]:.0f} %)"
                                            + ("" if val else "; no held-out run shows it predicts"),),
                       tuple(probs + vprobs), weak, bound)
    held = held_out_problem(train_ev, val_ev, chans) if val else None
    if held:
        return Verdict(m, "FAILED", False, (held,), tuple(probs + vprobs), weak, bound)
    miss = manoeuvre_miss(manoeuvres) if manoeuvres is not None else None
    if miss:
        return Verdict(m, "FAILED", False, (miss,), tuple(probs + vprobs), weak, bound)
    label = "usable"
    if probs:
        followed = len(train) - len(bad_train)
        reasons.append(f"{len(bad_train)} of {len(train)} training runs not followed (listed below); the other "
                       f"{followed}" + (" and the held-out runs are" if val_followed else " are") + " followed")
    if not result.converged:
        label = "not converged"
        reasons.append(result.status)
    lost = [n for n in result.free if math.isinf(float(result.stderr.get(n, 0.0)))]
    if weak and not result.converged and not lost:
        # the solver stopped before its optimum along a direction the data do not determine: where it stopped
        # is where the steps ran out, not an estimate
        names = [w.split(" = ")[0] for w in weak]
        return Verdict(m, "FAILED", False, (f"the solver did not converge and the data do not determine "
                                            f"{', '.join(names)} (SE > {WEAK_RATIO:g}× value): the values are where "
                                            "the steps ran out; fix some of them (--fix NAME=VALUE), give priors, or "
                                            "add runs that excite them",), tuple(probs + vprobs), weak, bound)
    if lost or (weak and len(weak) == len(result.free)):
        # values the data leave entirely free (a rank-deficient Jacobian), or not one parameter determined:
        # whatever the simulation shows, these values are not an identification of anything
        why = (f"the data leave {', '.join(lost)} entirely free (infinite standard errors: the Jacobian is rank "
               "deficient); the values are arbitrary" if lost else
               f"not one of the {len(weak)} free parameters is determined by the data (SE > {WEAK_RATIO:g}× value)")
        return Verdict(m, "FAILED", False, (why + "; fix some of them (--fix NAME=VALUE), give priors, or add runs "
                                            "that excite them",), tuple(probs + vprobs), weak, bound)
    if weak and label == "usable":
        label = "unidentifiable"
    if weak:
        reasons.append(f"{len(weak)} free parameter(s) not determined by the data (SE > {WEAK_RATIO:g}× value); "
                       "their values are arbitrary, predictions that depend on them are not supported")
    return Verdict(m, label, True, tuple(reasons), tuple(probs + vprobs), weak, bound)
