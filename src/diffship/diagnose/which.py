r"""Which effect explains the gap: refits of the screened candidates, judged on held-out runs only.

After the score-test screen (:mod:`.screen`) — all candidates when there are no more than
``max_refits + max_absorbed`` of them, else the top ``max_refits`` candidates by predicted
fraction f_k, plus up to ``max_absorbed`` of those the base parameters absorb (0 < o_k < 0.1,
which the screen under-rates), or all of them, are refitted with warm starts (smooth effects
from the null, non-smooth ones from the probe magnitude × 1, 0.3, 3) and scored on the
validation runs (:mod:`.shrink`).

**Decided early** (:mod:`.decided`): the first candidate by screening rank is refitted first; when
it alone passes the rule below and brings the held-out E under the gap gate, the candidates screened
under 5 % of its share are not refitted, and their rows say so.

**Acceptance rule** for an effect (all must hold):

* the structural gap exists: :math:`E_{base} \ge` the gate (E normalised by the noise floor, so
  :math:`E_{floor} = 1`). The gate comes from the data (:func:`~.where.structural_gate`): 1 plus
  three standard deviations of E's scatter with no structural error, from the validation and
  noise-floor sample counts — about 1.05 on two 70-s zigzags. (A fixed 1.1 was used before; it
  ignored the sample count, and weak effects with E 1.06–1.09 whose refits were 14-σ significant
  and closed the gap on every validation run went unattributed.)
* validation error drops by at least ``min_gain`` (5 %) **and** by more than the noise-level
  threshold ``max(gate − 1, 2·SE)`` in normalised units — the same noise band as the gate
  (SE of the mean per-run gain, with four or more validation runs) — on a majority of the
  validation runs;
* at least one effect parameter has a 95 % interval that excludes the null, and the effect is
  relevant: |φ̂ − φ₀| ≥ MIN_RELEVANT, or its term is what lowers the validation error by the
  amounts above (against the refitted base, so not by extra base iterations) — an absolute
  coefficient threshold alone depends on the vessel's scale;
* to be selected first, the removed part is at least ``min_shrink`` (30 %) of the structural gap.

**Possible effects** (under the gate, 1 < E_base < ``gap_gate``): nothing is attributed, but a
candidate with a parameter whose 95 % interval excludes the null, that lowers E on
a majority of the validation runs by more than ``max(possible_min_dE, 2·SE)`` (the scatter of E on
no-effect data) and closes at least ``min_shrink`` of the small structural gap is reported as a
**possible** effect with *low* confidence and the experiment that would settle it (more
excitation or longer runs to lift the gap over the gate, then the effect's separating manoeuvre).

**Confidence.** The first selected effect states how sure it is (:meth:`Search._confidence`):
*high* when the runner-up misses ≥ 25 % of its validation gain, *medium* otherwise or when a
close rival is ruled out by a joint refit, *tie* when a rival within ``tie_share`` of its gain
cannot be ruled out — the verdict then names the manoeuvre that separates the two.

**Base reference (fair comparisons).** Every candidate is judged against the base refitted by
the same procedure with no effect (:meth:`~.screen.Workspace.refit` from θ̂, the same step
cap, initial-state estimation and continuation rounds — always finished), whenever that lowers
the base fit's training cost: a base fit that stopped early, was pulled by priors or used
another tolerance would otherwise let every candidate refit take credit for finishing it. The
non-smooth actuator effects (delay, lag, rate limit: nonconvex in their time constant) are
refitted from three starts (probe magnitude × 1, 0.3, 3); smooth ones from the null. Joint
refits (tie decisions, pairs, greedy steps) also start from the nested solutions — each
single's fit with the other effect at its null — so a joint fit is never judged from a worse
basin than its singles (:meth:`Search.joint_starts`). A greedy step starts the base parameters where the
previous step left them, so its nested start is that step's solution; a trial whose refit fails is
said, never dropped silently.

**Path.** The accepted candidate with the lowest validation error is selected; then up to ``greedy_steps − 1`` further
effects, each refitted jointly with those already in and judged against the previous step — while the validation error
is still at or above the gap gate (under it no structural gap is left: the path stops there without the trial refits).
When no single effect passes, up to ``max_pairs`` pairs of the best single candidates are refitted jointly (two
effects can each fail alone yet pass together). With two or more effects in, a **swap** pass replaces one by an
accepted alternative when that lowers the validation error by more than 2 % (a delay chosen first where lag + damping
is the truth). At most :data:`~.screen.P_MAX` effect parameters are refitted at once. When the path stops at its cap
(``greedy_steps``) with the validation error still at or above the gate, the effects that also passed the rule at its
last step are kept as **waiting** (:attr:`Selection.waiting`): the verdict names them rather than calling the rest of
the gap unexplained by the library (on the KVLCC2 logs with a 0.5-s rudder clock offset, input_delay passed at step 2
behind damping_rv).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence

import numpy as np

from ..errors import FitError
from ..models import AbstractModel
from ..models.effects import POSSIBLE_ONLY, Augmented, Effect
from .decided import remaining
from .options import DiagnoseOptions
from .rivals import collinear_note, collinear_rivals, heading_turn
from .screen import P_MAX, RefitResult, ScreenResult, Workspace, parallel
from .shrink import PathStep, Score, Validation, structural_shrink

__all__ = ["Judgement", "Candidate", "Selection", "refit_order", "Search", "FALLBACK_GATE", "parallel"]

#: gap gate of a :class:`Search` built without the data's sample counts (the former fixed rule)
FALLBACK_GATE = 1.1


@dataclasses.dataclass(frozen=True)
class Judgement:
    """The acceptance rule applied to one refit: pass/fail, relative gain, shrink, reasons."""

    ok: bool
    gain: float
    shrink: float
    why: str
    runs_improved: str = ""
    possible: bool = False


@dataclasses.dataclass(frozen=True, eq=False)
class Candidate:
    """A refit with some effects switched on, scored on the validation runs and judged."""

    effects: tuple[str, ...]
    refit: RefitResult
    score: Score
    judgement: Judgement


@dataclasses.dataclass(frozen=True, eq=False)
class Selection:
    """The selected effects, the greedy path, and the final validation score and values."""

    selected: tuple[str, ...]
    path: tuple[PathStep, ...]
    final: Score
    values: dict[str, float]
    base_values: dict[str, float] | None
    confidence: str = ""
    rivals: tuple[str, ...] = ()
    note: str = ""
    possible: tuple[str, ...] = ()
    #: effects that passed the rule at the path's last step beside the one taken, ``(name, validation
    #: gain)``, best first, when the path stopped at its cap (``greedy_steps``) with E still above the
    #: gate: a further step might attribute one of them; empty otherwise
    waiting: tuple[tuple[str, float], ...] = ()

    def shrink(self, E0: float) -> float:
        """Share of the structural gap S(E0) closed by the selected effects (0 if none; :mod:`.shrink`)."""
        return structural_shrink(E0, E0, self.final.E) if self.selected else 0.0


def refit_order(screen: Sequence[ScreenResult], options: DiagnoseOptions) -> list[str]:
    """Candidates to refit, in screening order (see the module docstring)."""
    # effects that are only ever possible (a changing current or lag) are refitted by :mod:`.variation`
    screen = [s for s in screen if s.effect not in POSSIBLE_ONLY]
    order = [s.effect for s in screen if s.orthogonal_fraction > 0 or s.predicted_fraction > 0]
    # few candidates (a Nomoto model's five): refit them all, within the effort the rule allows anyway
    # (a 1° rudder zero error on the KVLCC2 logs screened last, behind four probe secants, and was never refitted)
    if options.refit_all or len(order) <= options.max_refits + options.max_absorbed:
        return order
    low = [s.effect for s in screen if 0 < s.orthogonal_fraction < 0.1 and s.effect not in order[:options.max_refits]]
    return order[:options.max_refits] + low[:options.max_absorbed]


class Search:
    """Refits, judgements and the greedy path over one :class:`~.screen.Workspace`.

    Args:
        ws: the all-effects workspace of the base fit.
        validation: the held-out runs; ``base``: the base model's score on them (or None until :meth:`set_base`).
        options: effort and acceptance rule; ``say``: progress messages.
    """

    def __init__(self, ws: Workspace, validation: Validation, base: Score | None, options: DiagnoseOptions,
                 say: Callable[[str], None], gate: float | None = None):
        self.ws = ws
        self.validation = validation
        self.base = base
        self.options = options
        self.say = say
        self.null_base: dict[str, float] | None = None  # set when the base fit was continued
        # the gap gate: given, or the options' fixed value, or FALLBACK_GATE (a Search built without
        # the data's sample counts); diagnose() passes the one from structural_gate()
        self.gate = gate if gate is not None else (options.gap_gate if options.gap_gate is not None else FALLBACK_GATE)
        self.has_gap = base is not None and base.E >= self.gate  # ``base`` may come later (:meth:`set_base`)
        #: the candidate that closed the gap alone and the candidates not refitted for it, with the
        #: reason (:meth:`refit_singles`)
        self.decided: str | None = None
        self.not_refitted: dict[str, str] = {}

    def effect(self, name: str) -> Effect:
        return next(e for e in self.ws.effects if e.name == name)

    def n_params(self, names: Sequence[str]) -> int:
        return sum(len(e.param_names) for e in self.ws.effects if e.name in names)

    def _refit(self, names: Sequence[str], starts: list[dict[str, float]],
               base_start: dict[str, float] | None = None) -> tuple[RefitResult, Score]:
        rf = self.ws.refit(list(names), starts, progress=self.say, base_start=base_start)
        return rf, self.validation.refit(rf)

    def joint_starts(self, a: Candidate, b: Candidate) -> list[dict[str, float]]:
        """Starts of a joint refit of two single candidates: both fitted values, and each single's
        solution with the other effect at its null. The two effects are nested in the joint model,
        so from the nested starts the joint cost can only go below the better single's; from the
        combined start alone, LM can end in a worse basin (a delay and a lag trade off along a
        curved valley), and the encompassing test would then judge a fit worse than a single."""
        ea = [self.effect(n) for n in a.effects]
        eb = [self.effect(n) for n in b.effects]
        null_a = {k: v for e in ea for k, v in e.null().items()}
        null_b = {k: v for e in eb for k, v in e.null().items()}
        va = {k: a.refit.values[k] for k in null_a}
        vb = {k: b.refit.values[k] for k in null_b}
        return [{**va, **vb}, {**va, **null_b}, {**null_a, **vb}]

    def judge(self, rf: RefitResult, ref: Score, new: Score, effect_names: Sequence[str],
              base: Score | None = None) -> Judgement:
        """The acceptance rule for the effects ``effect_names`` of ``rf``, against ``ref``
        (``base``: the score the structural gap is measured from, default the search's base)."""
        o = self.options
        base = base if base is not None else self.base
        has_gap = base.E >= self.gate  # :attr:`has_gap` for the search's own base
        E_ref, E = ref.E, new.E
        gain = (E_ref - E) / E_ref if E_ref > 0 else 0.0
        d = np.array([ref.E_runs[k] - new.E_runs[k] for k in new.E_runs])
        # run-to-run standard error only when there are enough validation runs to estimate it
        se = float(np.std(d, ddof=1) / math.sqrt(d.size)) if d.size >= 4 else 0.0
        thr = max(self.gate - 1.0, 2 * se)  # the noise band of E (the gate's), or the run scatter
        majority = bool(np.sum(d > 0) > d.size / 2)
        relevant, ci_ok = False, False
        for e in self.ws.effects:
            if e.name not in effect_names:
                continue
            for n in e.param_names:
                v, s = rf.values[n], rf.stderr.get(n, float("inf"))
                relevant |= abs(v - e.null()[n]) >= e.MIN_RELEVANT.get(n, 0.0)
                ci_ok |= abs(v - e.null()[n]) > 1.96 * s
        # relevance: the fitted magnitude reaches MIN_RELEVANT, or the effect's own term is what
        # lowers the validation error materially (the reference is the refitted base, so the gain
        # is not the base's extra iterations). An absolute coefficient threshold alone is
        # vessel-scale dependent: it rejected a 20-σ |v|v term that closed a small USV's whole gap.
        # ``material`` is required anyway, so a passing effect is relevant by its gain; ``relevant``
        # only words the reason of a rejection.
        material = gain >= o.min_gain and (E_ref - E) > thr
        ok = has_gap and rf.ok and material and majority and ci_ok
        shrink = structural_shrink(base.E, base.E, E)
        # under the gate (1 < E < gap_gate): a significant effect that closes the small gap on most
        # validation runs is a *possible* effect (low confidence), never an attribution
        small_drop = (E_ref - E) > max(o.possible_min_dE, 2 * se)
        possible = (not has_gap and base.E > 1.0 and rf.ok and majority and ci_ok
                    and small_drop and shrink >= o.min_shrink)
        reasons = []
        if not has_gap:
            reasons.append("no structural gap")
        if gain < o.min_gain or (E_ref - E) <= thr:
            reasons.append(f"validation gain {100 * gain:.1f} % (ΔE {E_ref - E:.3g}) below the threshold "
                           f"({100 * o.min_gain:.0f} % and ΔE > {thr:.2g})")
        elif not majority:
            reasons.append("improves fewer than half of the validation runs")
        if not relevant and not material:
            reasons.append("fitted magnitude below relevance")
        elif not ci_ok:
            reasons.append("95 % interval includes the null")
        return Judgement(ok, gain, shrink, "; ".join(reasons), f"{int(np.sum(d > 0))}/{d.size}", possible)

    # -- single candidates -------------------------------------------------------------------
    def singles(self, names: Sequence[str]) -> dict[str, Candidate]:
        """Each candidate refitted alone and judged against the base."""
        return self.judge_singles(self.refit_singles(names)[0])

    def single_starts(self, name: str) -> list[dict[str, float]]:
        """Starts of a single candidate's refit: smooth effects from the null (the score test's
        point); non-smooth ones have a flat null, so at the probe magnitude and around it."""
        e = self.effect(name)
        return [e.null()] if e.smooth_null else [{k: f * v for k, v in e.PROBE.items()} for f in (1.0, 0.3, 3.0)]

    def refit_singles(self, names: Sequence[str], extra: Sequence[Callable] = (),
                      reference: Callable[[list], Score | None] | None = None,
                      shares: dict[str, float] | None = None) -> tuple[dict, list]:
        """Each candidate refitted alone (side by side, :func:`parallel`), with further
        independent jobs ``extra`` (callables) run in the same pool: ``({name: (rf, score) or
        exception}, [results of extra])``.

        With ``reference`` (the extras' results → the score candidates are judged against, or
        ``None``) and ``shares`` (screened fractions f_k), the first candidate is refitted first and
        may decide the rest (:mod:`.decided`; :attr:`not_refitted` says why).
        """
        o = self.options
        decide = (reference is not None and shares is not None and names and o.decided_share > 0
                  and not o.refit_all)
        now = list(names[:1] if decide else names)  # the first alone when it may decide the rest
        jobs = [("extra", f) for f in extra] + [("single", n) for n in now]  # the long reference refit first

        def run(job):
            kind, x = job
            return self._refit([x], self.single_starts(x)) if kind == "single" else x()
        out = parallel(run, jobs)
        extras, got = out[:len(extra)], dict(zip(now, out[len(extra):]))
        if decide:
            rest = remaining(self, names, got[names[0]], reference(extras), shares)
            got.update(zip(rest, parallel(run, [("single", n) for n in rest])))
        return {n: got[n] for n in names if n in got}, extras

    def set_base(self, base: Score) -> None:
        """Judge against ``base`` from now on (the no-effect refit, when it lowers the training cost)."""
        self.base = base
        self.has_gap = base.E >= self.gate

    def judge_singles(self, refits: dict) -> dict[str, Candidate]:
        """The singles' judgements against the base (``refits``: from :meth:`refit_singles`)."""
        E0 = self.base.E
        out = {}
        for name, got in refits.items():
            if isinstance(got, FitError):
                self.say(f"  refit {name} failed: {got}")
                continue
            if isinstance(got, Exception):
                raise got
            rf, sc = got
            j = self.judge(rf, self.base, sc, [name])
            out[name] = Candidate((name,), rf, sc, j)
            self.say(f"  {name}: validation E {E0:.3g} → {sc.E:.3g} ({100 * j.gain:+.1f} %), shrink {j.shrink:.2f}"
                     + ("" if j.ok else f" — not accepted: {j.why}"))
        return out

    # -- the path ----------------------------------------------------------------------------
    def select(self, singles: dict[str, Candidate]) -> Selection:
        """Pair search (if no single passes), the greedy path, and the swap pass."""
        o, E0 = self.options, self.base.E
        by_E = sorted(singles, key=lambda n: singles[n].score.E)
        accepted = [n for n in by_E if singles[n].judgement.ok and singles[n].judgement.shrink >= o.min_shrink]
        cur = Selection((), (), self.base, {}, None)
        if not accepted and self.has_gap and o.max_pairs > 0:
            cur = self._pair(singles, by_E) or cur
        if not self.has_gap:
            poss = tuple(n for n in by_E if singles[n].judgement.possible)
            if poss:
                cur = dataclasses.replace(cur, possible=poss, confidence="low")
        if accepted:
            name, conf, rivals, note = self._confidence(singles, accepted, by_E)
            if name == self.decided and self.not_refitted:
                note = (f"{note}; " if note else "") + (
                    f"{len(self.not_refitted)} candidate(s) screened under "
                    f"{100 * o.decided_share:.0f} % of its share not refitted: it closed the gap alone")
            w = singles[name]
            step = PathStep.between(name, self.base, w.score, E0, w.refit, self.validation.channels)
            cur = Selection((name,), (step,), w.score, dict(w.refit.values), w.refit.base_values, conf, rivals, note)
            cands = [n for n in by_E if n != name and singles[n].judgement.gain > 0][:3]
            # what else passed at the step just taken (here the first: the singles that pass the rule)
            passing = [(n, singles[n].judgement.gain) for n in by_E if n != name and singles[n].judgement.ok]
            capped = True
            for _ in range(1, o.greedy_steps):
                if cur.final.E < self.gate:  # no structural gap left: nothing more can be attributed
                    self.say(f"  validation E {cur.final.E:.3g} under the gap gate {self.gate:.3g}: no further effect")
                    capped = False
                    break
                nxt, passing = self._greedy_step(cur, cands)
                if nxt is None:
                    capped = False
                    break
                cur = nxt
            if len(cur.selected) >= 2:
                sw = self._swap(cur, [n for n in accepted if n not in cur.selected])
                if sw is not None:
                    cur = dataclasses.replace(sw, confidence="medium", note="after a swap of confusable effects")
            if capped and cur.final.E >= self.gate:
                waiting = tuple((n, g) for n, g in passing if n not in cur.selected)
                if waiting:
                    self.say(f"  the path stops at its cap of {o.greedy_steps} effect(s) (greedy_steps) with E "
                             f"{cur.final.E:.3g} above the gate; also passing at its last step: "
                             + ", ".join(f"{n} ({100 * g:+.1f} %)" for n, g in waiting))
                    cur = dataclasses.replace(cur, waiting=waiting)
        return cur

    # -- confidence and ties -----------------------------------------------------------------
    def _significant(self, rf: RefitResult, name: str) -> bool:
        """Some parameter of ``name`` has a 95 % interval that excludes the null (in the joint refit
        of two candidates that each passed the rule alone, so each is already relevant by its
        validation gain)."""
        e = self.effect(name)
        return any(abs(rf.values[n] - e.null()[n]) > 1.96 * rf.stderr.get(n, math.inf) for n in e.param_names)

    def _confidence(self, singles: dict[str, Candidate], accepted: list[str],
                    by_E: list[str]) -> tuple[str, str, tuple[str, ...], str]:
        r"""The first effect, its confidence, unresolved rivals and how it was decided.

        With :math:`\Delta_w = E_0 - E_w` the winner's validation gain, a candidate that passes the rule and comes
        within ``tie_share``·Δ_w of it — or one the headings cannot separate from it (:mod:`.rivals`) — is a
        **rival**. Each rival is refitted jointly with the winner (an encompassing test): when the winner's term stays
        significant (relevant, 95 % interval excluding the null) and the rival's does not, the rival is ruled out
        (*medium*); otherwise (both stay, both vanish, or only the rival stays: nearly collinear effects such as a
        delay and a lag trade off) the tie is unresolved: the validation winner stays first with confidence *tie*, and
        the verdict names the manoeuvre that separates them. Without rivals the confidence is *high* when the
        runner-up misses ≥ 25 % of Δ_w, else *medium*."""
        o, E0 = self.options, self.base.E
        name = accepted[0]
        span = max(E0 - singles[name].score.E, 1e-12)
        close = [n for n in accepted[1:] if singles[n].score.E - singles[name].score.E < o.tie_share * span]
        turn = heading_turn(self.ws.train["batch"])  # a pair only a larger turn separates is a rival (:mod:`.rivals`)
        close += (collinear := collinear_rivals(name, [n for n in by_E if n != name and n not in close
                                                       and singles[n].judgement.ok], turn, self.say))
        if not close:
            second = next((n for n in by_E if n != name), None)
            margin = (singles[second].score.E - singles[name].score.E) / span if second else 1.0
            return name, ("high" if margin >= 0.25 else "medium"), (), f"runner-up {second} misses {100 * margin:.0f} % of the gain" if second else ""
        unresolved, notes = [], []
        for alt in close:
            if self.n_params((name, alt)) > P_MAX:
                unresolved.append(alt)
                continue
            try:
                rf, _ = self._refit([name, alt], self.joint_starts(singles[name], singles[alt]))
            except FitError:
                unresolved.append(alt)
                continue
            s_w, s_a = self._significant(rf, name), self._significant(rf, alt)
            self.say(f"  tie {name} vs {alt}: joint refit keeps {name}: {s_w}, {alt}: {s_a}")
            if s_w and not s_a:
                notes.append(f"{alt}'s term vanishes once {name} is in")
            else:  # both stay, both vanish, or the joint fit contradicts the validation ranking
                unresolved.append(alt)
        if unresolved:  # a pair the headings cannot separate says so
            return name, "tie", tuple(unresolved), "joint refit cannot separate them" + (
                f"; {collinear_note(turn)}" if set(unresolved) & set(collinear) else "")
        return name, "medium", (), "decided by joint refit: " + "; ".join(notes)

    def _pair(self, singles: dict[str, Candidate], by_E: list[str]) -> Selection | None:
        """Two effects refitted jointly: each can fail alone (compensating the other on some runs)
        yet pass together; tries the best pairs by single-effect validation error."""
        o, E0 = self.options, self.base.E
        top = by_E[:3]
        pairs = [(a, b) for i, a in enumerate(top) for b in top[i + 1:]][:o.max_pairs]
        best = None
        pairs = [(a, b) for a, b in pairs if self.n_params((a, b)) <= P_MAX]
        got = parallel(lambda ab: self._refit(list(ab), self.joint_starts(singles[ab[0]], singles[ab[1]])), pairs)
        for (a, b), g in zip(pairs, got):
            if isinstance(g, FitError):
                self.say(f"  pair {a}+{b}: refit failed: {g}")
                continue
            if isinstance(g, Exception):
                raise g
            rf, sc = g
            j = self.judge(rf, self.base, sc, [a, b])
            self.say(f"  pair {a}+{b}: validation E {E0:.3g} → {sc.E:.3g} ({100 * j.gain:+.1f} %)"
                     + ("" if j.ok else f" — not accepted: {j.why}"))
            if j.ok and j.shrink >= o.min_shrink and (best is None or sc.E < best[3].E):
                best = (a, b, rf, sc)
        if best is None:
            return None
        a, b, rf, sc = best
        order_ab = tuple(sorted((a, b), key=lambda n: singles[n].score.E))
        step = PathStep.between("+".join(order_ab), self.base, sc, E0, rf, self.validation.channels)
        return Selection(order_ab, (step,), sc, dict(rf.values), rf.base_values)

    def _greedy_step(self, cur: Selection, cands: list[str]) -> tuple[Selection | None, list[tuple[str, float]]]:
        """The best next effect, refitted jointly with those in and judged against ``cur`` (``None``
        when none passes), and ``[(name, validation gain)]`` of the other trials that passed, best first."""
        best = None
        passed: list[tuple[str, float, float]] = []
        trials = []
        for n in cands:
            if n in cur.selected:
                continue
            effs_now = list(cur.selected) + [n]
            if self.n_params(effs_now) > P_MAX:
                continue
            e = self.effect(n)
            # the nested start (the new effect at its null) cannot end above the current step's cost
            starts = [{**cur.values, **e.null()}] if e.smooth_null else [
                {**cur.values, **{k: f * v for k, v in e.PROBE.items()}} for f in (1.0, 3.0)] + [{**cur.values, **e.null()}]
            trials.append((n, effs_now, starts))
        # the base parameters start where the current step left them: with the base fit's values
        # beside the step's effect values the "nested" start is not the current step's solution
        # (on the KVLCC2 logs with a 0.5-s clock offset, damping_vr's Nvr = 3.6e4 with the base
        # fit's hull coefficients blew up from every start of every step-2 trial, silently)
        got = parallel(lambda t: self._refit(t[1], t[2], base_start=cur.base_values), trials)  # side by side
        for (n, _, _), g in zip(trials, got):
            if isinstance(g, FitError):
                self.say(f"  + {n}: refit failed, not a candidate at this step: {g}")
                continue
            if isinstance(g, Exception):
                raise g
            rf, sc = g
            j = self.judge(rf, cur.final, sc, [n])
            self.say(f"  + {n}: validation E {cur.final.E:.3g} → {sc.E:.3g} ({100 * j.gain:+.1f} %)"
                     + ("" if j.ok else f" — not accepted: {j.why}"))
            if j.ok:
                passed.append((n, j.gain, sc.E))
            if j.ok and (best is None or sc.E < best[2].E):
                best = (n, rf, sc)
        if best is None:
            return None, []
        n, rf, sc = best
        step = PathStep.between(n, cur.final, sc, self.base.E, rf, self.validation.channels)
        # the first effect's confidence, rivals and note stay with the path (taking the rival in does not decide a tie)
        nxt = Selection(cur.selected + (n,), cur.path + (step,), sc, dict(rf.values), rf.base_values,
                        cur.confidence, cur.rivals, cur.note)
        return nxt, [(m, g) for m, g, _ in sorted(passed, key=lambda x: x[2]) if m != n]

    def _swap(self, cur: Selection, alts: list[str]) -> Selection | None:
        """With two or more effects in, a confusable alternative of an early pick may now fit
        better (e.g. a delay chosen first where a lag + damping is the truth)."""
        best = None
        sel = list(cur.selected)
        for i in range(len(sel)):
            for alt in alts:
                trial = sel[:i] + [alt] + sel[i + 1:]
                if self.n_params(trial) > P_MAX:
                    continue
                owner = self.ws.owner
                prev = {k: v for k, v in cur.values.items() if k not in owner or owner[k].name != sel[i]}
                e = self.effect(alt)
                try:
                    rf, sc = self._refit(trial, [{**prev, **(e.null() if e.smooth_null else e.PROBE)}])
                except FitError:
                    continue
                self.say(f"  swap {sel[i]} -> {alt}: validation E {cur.final.E:.3g} → {sc.E:.3g}")
                if sc.E < cur.final.E * 0.98 and (best is None or sc.E < best[2].E):
                    best = (tuple(trial), rf, sc)
        if best is None:
            return None
        trial, rf, sc = best
        step = PathStep.between("+".join(trial), self.base, sc, self.base.E, rf, self.validation.channels,
                                note="after a swap of confusable effects")
        return Selection(trial, (step,), sc, dict(rf.values), rf.base_values)

    def final_model(self, sel: Selection) -> Augmented:
        """The base model with the selected effects at their fitted values (and the refitted base)."""
        if not sel.selected:
            nb = self.null_base  # the base fit continued by the refit procedure
            return Augmented(self.ws.base.with_params(nb) if nb else self.ws.base, [])
        base: AbstractModel = self.ws.base
        m = Augmented(base.with_params(sel.base_values), [e for e in self.ws.effects if e.name in sel.selected])
        return m.with_params({n: v for n, v in sel.values.items() if n in m.param_names})
