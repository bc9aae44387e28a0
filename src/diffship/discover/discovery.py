r"""Structure discovery: which library terms a vessel's equations need, fitted by output error.

:func:`discover` runs, in order:

1. the **base fit** — the base model by output error through the one driver (:func:`diffship.fit.fit`), initial states
   estimated within their noise, stopped when its cost stalls (finished only if the base is selected); beside it, on
   the core its solves leave, the equation-error screen runs and the all-terms programs compile (``term_programs``);
2. the **screens** — greedy forward selection over the term library on the output-error Jacobian at the
   base fit (:mod:`.oescreen`: simulated regressors, no errors in variables), and equation error on
   smoothed derivatives with block-bootstrap frequencies (:mod:`.screen`); they propose candidate
   structures: the output-error path's prefixes first, then the equation-error path's prefixes and its
   terms nested by frequency;
3. the **refit** of the base and every candidate by output error on one **workspace**: the base with every library
   term, compiled once, a structure switched on by data (:func:`.oescreen.term_workspace`); each from the lowest-cost
   of its linearised refit's point at the base fit (:class:`.oescreen.Linearisation`), fractions of that step and the
   screen values, side by side (one thread per core). Each stops when its cost stalls (a wrong structure crawls; its
   stalled cost bounds its criterion from above) or after :data:`FIRST_PASS_STEPS`; the ``n_finish`` best by that
   bound are finished, and the base where its cost could decide (no stalled cost under :data:`BASE_FINISH` of it);
4. the **ranking** by BIC (or AIC) on the output residuals of each refit (simulated from its own fitted
   initial states: what it minimised) with effective sample sizes (:mod:`.rank`); every structure is simulated with
   the all-terms model (the others at zero), so one compiled simulation serves them all,
   and each term's **inclusion probability**: the fraction of a paired block bootstrap of the training
   samples in which a structure containing it wins the ranking (:func:`.rank.selection_frequency`;
   the screen's own bootstrap frequencies are reported beside it but decide nothing: the
   equation-error regression is biased by noise in its regressors and derivatives, errors in
   variables, so a term can be kept by every resample of it and still be spurious);
4a. the **polish** (:mod:`.polish`): from the best-ranked structure with terms (when it beats the base's criterion
   by :data:`MARGIN`), removals, swaps within an equation and additions, every move refitted on the same workspace
   from that structure's optimum, while a move lowers the criterion. The screens linearise at the base fit, which
   the missing terms bias, and there a near-collinear stand-in can look better than the true term. The structure
   the polish ends at is ranked with the others;
5. the **selection**: the best-ranked structure whose terms all have inclusion probability at least
   0.5, that beats the base's criterion by at least :data:`MARGIN` (Kass & Raftery, JASA 90, 1995:
   a BIC difference below 2 is "not worth more than a bare mention"), and, with held-out runs, that
   predicts them better than the base model (mean over runs and channels of the RMSE relative to the
   base's below 1); else the base model alone. Terms that appear in a better-ranked structure or win
   some resamples but fail these tests are reported as **possible**, with their inclusion probability;
5a. the selected structure's **final fit** through the driver (:func:`diffship.fit.fit`) from its workspace optimum
   alone: the user's priors and the covariance; it is reported, saved and bootstrapped. The ranking stands on the
   workspace refits: one estimator, the same problem for every structure (without parameter priors);
6. **warnings**: pairs of free parameters whose estimates correlate beyond 0.95 in the selected fit
   (terms that trade off);
7. **equivalent explanations**: the structures whose criterion is within :data:`MARGIN` of the selected one's
   (the training runs do not decide between them), reported beside it with the probe manoeuvre whose predicted
   responses differ most (:mod:`.separate`): the experiment that would tell them apart.

The discovered model is :func:`diffship.models.terms.with_terms` of the base: an ordinary model that a
fit file saves and :func:`diffship.load_fit` rebuilds.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..data import Run
from ..compiled import prefetch
from ..diagnose.screen import parallel
from ..errors import DiffshipError
from ..fit import FitResult, OutputError, fit
from ..fit.driver import fit_priors
from ..fit.problem import default_channels
from ..fit.status import RESULTS
from ..metrics import Evaluation, evaluate
from ..models import AbstractModel
from ..models.terms import library_terms, term_class, with_terms
from ..params import ParamSpec
from ..preprocess import Filter
from .rank import criteria, effective_samples, residuals, selection_frequency
from .oescreen import STALL, OEScreen, lowest_start, oe_screen, term_programs, term_workspace
from .polish import Polish, bic, effective_count, polish
from .screen import Screen, screen
from .scaling import force_levels, term_scales, term_spec
from .separate import Separation, separating_manoeuvre

__all__ = ["Candidate", "Discovery", "discover", "term_spec", "term_scales", "TRADEOFF", "MARGIN", "MIN_INCLUSION", "MAX_EQUIVALENT"]

#: |correlation| between two estimates above which they are said to trade off.
TRADEOFF = 0.95
#: The least criterion improvement over the base for which terms are added (module docstring).
MARGIN = 2.0
#: The least inclusion probability of a selected term.
MIN_INCLUSION = 0.5
#: The most equivalent explanations reported beside the selected structure.
MAX_EQUIVALENT = 3
#: The step caps of the structures' and the base's first, stalled pass (a cost that bounds the criterion from above;
#: the best are finished, the base where it could decide: a term crawled 240 steps, 20 s on one core, the surge
#: truth's base 120 steps, 16 s, to its cost after 40).
FIRST_PASS_STEPS, BASE_FIRST_PASS = 120, 40
#: The base's workspace refit is finished only when the lowest stalled cost of a structure is at least this share of
#: the base's (below it, no crawl of the base could bring it level with the best structure).
BASE_FINISH = 0.8


@dataclasses.dataclass(frozen=True)
class Candidate:
    """One refitted structure: its terms, output-error fit, criteria and metrics.

    ``result`` is the workspace refit the ranking compared, except for the base (the driver's base fit) and the selected
    structure (its final fit through the driver). ``train`` is the training runs simulated from the fit's own initial
    states, for the base and the selected by the metrics' start rule; ``validation`` the held-out runs by that rule.
    """

    terms: tuple[str, ...]
    result: FitResult
    train: Evaluation
    validation: Evaluation | None
    criteria: dict[str, float]
    n_params: int
    held_out: float  # mean held-out RMSE relative to the base's (nan without held-out runs)
    wins: float = math.nan  # fraction of the bootstrap resamples in which it ranks first


@dataclasses.dataclass(frozen=True)
class Discovery:
    """The result of :func:`discover`: candidates ranked best first by the criterion, the selected one
    (:attr:`selected`, by the rule of the module docstring) and the base.

    Attributes:
        inclusion: ``{term: inclusion probability}`` of every refitted term (output-error bootstrap).
        possible: terms not selected that a better-ranked structure has or that win some resamples.
        reasons: ``{structure label: why it was not selected}`` for structures ranked above the selected.
    """

    base: Candidate
    candidates: tuple[Candidate, ...]
    screen: Screen
    criterion: str
    n_eff: dict[str, float]
    confirmed: bool | None
    possible: tuple[str, ...]
    tradeoffs: tuple[tuple[str, str, float], ...]
    seconds: float
    inclusion: dict[str, float] = dataclasses.field(default_factory=dict)
    chosen: int = 0
    reasons: dict[str, str] = dataclasses.field(default_factory=dict)
    n_boot: int = 0
    oe_screen: OEScreen | None = None
    equivalent: tuple[Candidate, ...] = ()
    separation: Separation | None = None
    polish: Polish | None = None

    @property
    def selected(self) -> Candidate:
        return self.candidates[self.chosen]

    @property
    def weak(self) -> tuple[str, ...]:
        """Former name of :attr:`possible`."""
        return self.possible

    @property
    def model(self) -> AbstractModel:
        return self.selected.result.model


def _score(ev: Evaluation | None, ref: Evaluation | None) -> float:
    """Mean over held-out runs and channels of the RMSE relative to ``ref``'s."""
    if ev is None or ref is None:
        return math.nan
    ratios = [ev.per_run[r]["rmse"][c] / max(ref.per_run[r]["rmse"][c], 1e-12)
              for r in ev.per_run for c in ev.per_run[r]["rmse"] if c in ref.per_run.get(r, {}).get("rmse", {})]
    return float(np.mean(ratios)) if ratios else math.nan


def discover(base: AbstractModel, train: Sequence[Run], validate: Sequence[Run] = (), *,
             spec: ParamSpec | None = None, library: str | Sequence[str] = "symmetric", max_terms: int = 4,
             max_candidates: int = 6, criterion: str = "bic", options: OutputError = OutputError(),
             flt: Filter = Filter(), n_boot: int = 30, n_boot_rank: int = 200, block_s: float = 5.0, seed: int = 0,
             oe_first: bool = True, x0: str = "estimate", n_starts: int = 1, polish_rounds: int = 6,
             n_finish: int = 2, progress: Callable[[str], None] | None = None) -> Discovery:
    """Discover the library terms ``base`` needs on ``train`` (module docstring).

    Args:
        base: a 3-DOF model (:mod:`diffship.models.terms`) with its fixed values set.
        train: training runs.
        validate: held-out runs.
        spec: the base model's free/fixed parameters (default ``base.spec()``).
        library: a library name or term names/expressions (:func:`~diffship.models.terms.library_terms`).
        max_terms: the most terms a candidate has (≥ 1); max_candidates: the most structures refitted.
        criterion: ``"bic"`` or ``"aic"``.
        options: the output-error estimator (priors, integrator, ...; ``positions`` off: structures are ranked on the
            default channels). n_boot: resamples of the equation-error screen; n_boot_rank: of the ranking (inclusion
            probabilities); block_s: the bootstrap block length [s] (residuals are coloured).
        x0: ``"estimate"`` (default): every fit estimates each run's initial state of the fitted channels'
            states within their noise (:attr:`~diffship.fit.OutputError.x0_prior`), unless ``options``
            names states already; ``"data"``: the base and final fits take the filtered first samples (the workspace refits
            estimate them within their noise, as always). Initial-state errors of slow
            modes (the USV's sway decays in ~27 s) last for much of a run, and candidate terms absorb
            part of them: measured on the benchmark truth, the true structure refitted from the data's
            initial states had Xudot −276 ± 25 kg (truth −400) and a fast-run heading error 1.9× the
            noise; with estimated initial states −390 ± 16 kg and 1.02×.
        oe_first: run the output-error screen (:mod:`.oescreen`) and refit its path's structures first,
            then the equation-error screen's; ``False``: the equation-error screen alone.
        n_starts: starts of the base fit (the driver's multi-start; ``--starts N``; no candidates drawn beyond
            them: ``OutputError.adaptive``); the structures start from their linearised refits at the base optimum.
        polish_rounds: the most rounds of the polish (:mod:`.polish`) from the best-ranked structure with terms,
            when it beats the base by the margin; 0: none.
        n_finish: the stalled refits finished, by their criterion bound: of the candidate structures, and of each
            polish round's moves (two: one wave on two cores).
    """
    say = progress or (lambda s: None)
    t0 = time.perf_counter()
    if int(max_terms) < 1:
        raise DiffshipError(f"--max-terms {max_terms}: give at least 1 term")
    if criterion not in ("bic", "aic"):
        raise DiffshipError(f"criterion {criterion!r}: use bic or aic")
    if x0 not in ("estimate", "data"):
        raise DiffshipError(f"x0 {x0!r}: use estimate or data")
    terms = library_terms(library)
    spec = spec or base.spec()
    options = dataclasses.replace(options, ee_start=False, positions="off")
    if x0 == "data":  # the first samples taken as exact starts (the default is the one rule, diffship.initial)
        options = dataclasses.replace(options, estimate_x0=())
    # every structure under the base's priors (a model with terms has no reference set of its own)
    priors, _ = fit_priors(base, spec, options)
    term_options = dataclasses.replace(options, priors=priors if len(priors) else None, reference_priors=False)
    phi_scales = term_scales(train, terms, force_levels(train, base))
    say(f"base fit: {base.name} by output error on {len(train)} run(s); beside it, the equation-error screen of "
        f"{len(terms)} library terms and the compiling of the all-terms programs...")
    # the base fit's solves keep about one core busy: the equation-error screen (the start model's, not the fit's)
    # and the compiling of every program the discovery runs after the fit use the other (a cold discovery of 4 runs
    # compiled for 40 s after its base fit)
    try:
        pre = prefetch(term_programs(base, spec, train, validate, terms, default_channels(base, train),
                                     options.integrator, phi_scales))
    except Exception:  # noqa: BLE001 - only a head start: the workspace built after the fit says what fails
        pre = None
    with ThreadPoolExecutor(1) as pool:
        ee = pool.submit(screen, base, train, spec, terms, max_terms=max_terms, n_boot=n_boot, seed=seed)
        try:
            # the base lacks the terms looked for: more draws only cost time, and it stops when its cost stalls (it
            # crawls: 233 whole-run steps moved its cost by 0.3 %, no value by 0.1 %); a selected base is finished
            res0 = fit(base, train, dataclasses.replace(options, adaptive=False, stall=options.stall or STALL,
                                                        stall_ends_fit=options.stall is None),
                       spec=spec, n_starts=n_starts, progress=say)
        except BaseException:
            if pre is not None:
                pre.cancel()
            raise
        sc = ee.result()
    say(f"screen: equation error, forward selection, {n_boot} bootstrap resamples: path "
        + (", ".join(sc.path[max(sc.path)]) if sc.path else "empty"))
    oe = None
    say(f"workspace: the base with all {len(terms)} library terms, one compiled program for the output-error screen, "
        "every candidate's refit and the polish...")
    ws = term_workspace(res0, spec, train, terms, phi_scales=phi_scales)
    if oe_first:
        say(f"screen: {len(terms)} library terms on the output-error Jacobian at the base fit...")
        try:
            oe = oe_screen(res0, spec, train, terms, max_terms=max_terms, workspace=ws)
            say("  forward path: " + ", ".join(f"{t} (T = {T:.1f})" for t, T in zip(oe.path, oe.statistic)))
        except DiffshipError as exc:
            say(f"  output-error screen failed: {exc}")
    proposed = (oe.candidates(max_terms) if oe else []) + sc.candidates(max_terms)
    # each structure once, its terms in the library's order
    structures = [c for c in dict.fromkeys(tuple(t for t in terms if t in p) for p in proposed) if c]
    structures = structures[: max(max_candidates - 1, 0)]
    chans = tuple(res0.channels)

    def as_result(cand: tuple[str, ...], rf) -> FitResult:
        """A workspace refit (:class:`~diffship.diagnose.screen.RefitResult`) as the fit of ``base`` with ``cand``."""
        vals = {t: float(rf.values[t]) for t in cand}
        return FitResult("output_error", with_terms(base.with_params(rf.base_values), cand, vals),
                         {**rf.base_values, **vals}, {t: float(rf.stderr[t]) for t in cand},
                         tuple(spec.free_names) + tuple(cand), bool(rf.converged), "", rf.iterations, rf.train_cost,
                         rf.seconds, 0.0, channels=chans, channel_scales=dict(res0.channel_scales),
                         noise_std=dict(res0.noise_std), initial_states=tuple(rf.initial_states),
                         run_names=res0.run_names, integrator=res0.integrator, info={"refit": "workspace"},
                         result=RESULTS.successful if rf.converged else RESULTS.nonlinear_max_steps_reached)

    def refit_all(jobs) -> list:
        """Refit ``(structure, starts, finish)`` jobs on the workspace side by side (:func:`parallel`), each from the
        lowest-cost of its starts (:func:`.oescreen.lowest_start`; the terms at zero where that blows up); the refits
        in the order given (``None`` where one failed or ended non-finite)."""
        def one(job):
            cand, options, finish = job
            start, base_start, x0 = lowest_start(ws, cand, options)
            starts = [start, {t: 0.0 for t in cand}] if cand and not finish else [start] if cand else [{}]
            return ws.refit(list(cand), starts, progress=say, finish=finish, base_start=base_start, x0_start=x0,
                            step_cap=None if finish is not False else FIRST_PASS_STEPS if cand else BASE_FIRST_PASS)

        out = []
        for (cand, *_), rf in zip(jobs, parallel(one, jobs)):
            if isinstance(rf, Exception):
                say(f"  refit {' + '.join(cand) or '(base)'} failed: {rf}")
            out.append(rf if not isinstance(rf, Exception) and rf.ok and math.isfinite(rf.train_cost) else None)
        return out

    say(f"refit by output error on the workspace: the base and {len(structures)} structure(s), side by side...")
    # every structure first with the stall rule (a wrong structure crawls; its stalled cost bounds its criterion from
    # above), from the lowest-cost of its linearised refit's point at the base fit (:class:`.oescreen.Linearisation`:
    # the Gauss–Newton step moves the base parameters and initial states with the terms; on the four-term truth 22–29
    # steps to convergence, from the base with the terms at the screens' values 41–101 stalled ones), fractions of that
    # step and the screens' values; the n_finish best by the bound are then finished (a structure whose bound is beaten
    # cannot win), and the base beside them where its cost could decide
    lin0 = oe.linearisation if oe else None
    jobs = [((), [({}, None, None)], False)] + [
        (cand, ([lin0.start(cand, a) for a in (1.0, 0.5, 0.25, 0.125)] if lin0 is not None else [])
         + [({t: oe.values[t] if oe and t in oe.values else sc.coefficients[t] for t in cand}, None, None)], False)
        for cand in structures]
    got = dict(zip([j[0] for j in jobs], refit_all(jobs)))
    if got[()] is None:
        raise DiffshipError(f"discover: the workspace refit of the base model {base.name} failed")
    lowest = min((c for c, rf in got.items() if rf is not None), key=lambda c: got[c].train_cost)
    n_eff0 = effective_count(ws, lowest, got[lowest].values, got[lowest].base_values)
    bound = sorted((bic(rf.train_cost, len(c), ws.train["batch"].n_residuals, n_eff0), c)
                   for c, rf in got.items() if c and rf is not None)
    # the base is finished only where its cost could decide: a structure whose stalled cost is 20 % under the base's
    # beats it whatever the base's crawl still gains (on the surge truth the base's finish took 151 steps and 17 s,
    # on the critical path behind a candidate's, and lowered its cost by under 10⁻⁶; a stalled structure's fell 2–3 %)
    base_decides = got[lowest].train_cost >= BASE_FINISH * got[()].train_cost
    finish = [(c, [(dict(got[c].values), dict(got[c].base_values), None)], True) for c in
              [c for _, c in bound[:max(int(n_finish), 0)]] + ([()] if base_decides else []) if not got[c].converged]
    if finish:
        say("  finishing the best by their criterion bound: "
            + "; ".join(" + ".join(c) or "the base" for c, *_ in finish))
        for (c, *_), rf in zip(finish, refit_all(finish)):
            if rf is not None and rf.train_cost <= got[c].train_cost:
                got[c] = rf
    fits: list[tuple[tuple[str, ...], FitResult]] = []
    refits: dict[frozenset, object] = {}  # structure -> its workspace refit
    for cand, rf in got.items():
        if rf is not None:
            fits.append((cand, as_result(cand, rf)))
            refits[frozenset(cand)] = rf
    # every structure is simulated with the all-terms model (the others at zero): one compiled simulation serves all
    full = with_terms(base, terms)

    simulated: dict[int, tuple] = {}  # id(fit) -> (training, held-out, residuals): each fit simulated once

    def scored(res: FitResult) -> AbstractModel:
        return full.with_params({**{n: res.params[n] for n in base.param_names},
                                 **{t: res.params.get(t, 0.0) for t in terms}})

    def simulate(res: FitResult) -> tuple:
        """The training runs simulated from the fit's own initial states (what it minimised: the criteria are
        computed on it; from the metrics' start rule, a structure could win by how well its coefficients happen to
        suit that rule: on plain fossen3 data, three terms within one standard error of zero "improved" the BIC by
        23), the held-out runs by the metrics' start rule, and the training residuals."""
        if id(res) not in simulated:
            m = scored(res)
            own = (evaluate(m, train, [np.asarray(x)[:len(base.state_names)] for x in res.initial_states], flt=flt,
                            integrator=res.integrator) if len(res.initial_states) == len(train) else
                   evaluate(m, train, flt=flt, integrator=res.integrator, fitted=res.channels,
                            scales=res.channel_scales))
            vev = evaluate(m, validate, flt=flt, integrator=res.integrator, fitted=res.channels,
                           scales=res.channel_scales) if validate else None
            simulated[id(res)] = (own, vev, residuals(m.output_names, m.angle_outputs, own, train, chans))
        return simulated[id(res)]

    def judged(res: FitResult, runs: Sequence[Run]) -> Evaluation:
        """``runs`` by the metrics' start rule with the fit's model (what the report shows and its fit file reproduces)
        as the all-terms model, the other terms at zero: the same vector field, in the programs compiled ahead."""
        return evaluate(scored(res), runs, flt=flt, integrator=res.integrator, fitted=res.channels,
                        scales=res.channel_scales)

    def rank(fits):
        """Criteria, inclusion probabilities and the selection rule over ``fits`` (module docstring)."""
        say("ranking: simulating every candidate on the training and held-out runs...")
        todo = list({id(res): res for _, res in fits if id(res) not in simulated}.values())
        for res, got in zip(todo, parallel(simulate, todo)):  # side by side; each fills its own entry
            if isinstance(got, Exception):
                raise got
        evs = [(cand, res, *simulate(res)[:2]) for cand, res in fits]
        resid = [simulate(res)[2] for _, res in fits]
        total = [sum(float(np.sum(np.concatenate(p) ** 2)) / max(res0.noise_std.get(c, 1.0), 1e-12) ** 2
                     for c, p in rr.items() if p) for rr in resid]
        n_eff = effective_samples(resid[int(np.argmin(total))])
        val0 = evs[0][3]
        cands = []
        for (cand, res, ev, vev), rr in zip(evs, resid):
            k = len(res.free)
            crit = criteria(rr, n_eff, k)
            if not ev.ok:
                crit = {**crit, "aic": math.inf, "bic": math.inf}
            cands.append(Candidate(cand, res, ev, vev, crit, k, _score(vev, val0)))
        say(f"inclusion probabilities: {n_boot_rank} paired block-bootstrap resamples of the ranking...")
        ok = [i for i, c in enumerate(cands) if math.isfinite(c.criteria[criterion])]
        freq = np.zeros(len(cands))
        if ok:
            dt = float(np.median(np.diff(train[0].time))) if train and train[0].n > 1 else 0.1
            freq[ok] = selection_frequency([resid[i] for i in ok], n_eff, [cands[i].n_params for i in ok],
                                           [len(cands[i].terms) for i in ok], criterion, n_boot=n_boot_rank,
                                           block=max(1, int(round(block_s / dt))), seed=seed)
        cands = [dataclasses.replace(c, wins=float(f)) for c, f in zip(cands, freq)]
        refitted = [t for c in cands for t in c.terms]
        inclusion = {t: float(sum(c.wins for c in cands if t in c.terms)) for t in dict.fromkeys(refitted)}
        ranked = sorted(cands, key=lambda c: (c.criteria[criterion], len(c.terms)))
        base_crit = cands[0].criteria[criterion]
        reasons: dict[str, str] = {}
        chosen = next(i for i, c in enumerate(ranked) if not c.terms)
        for i, c in enumerate(ranked):
            if not c.terms:
                break
            why = []
            if not c.criteria[criterion] <= base_crit - MARGIN:
                why.append(f"{criterion.upper()} {c.criteria[criterion] - base_crit:+.1f} from the base's "
                           f"(needs ≤ −{MARGIN:g})")
            low = [t for t in c.terms if inclusion.get(t, 0.0) < MIN_INCLUSION]
            if low:
                why.append("inclusion probability " + ", ".join(f"{t} {inclusion.get(t, 0.0):.2f}" for t in low)
                           + f" < {MIN_INCLUSION:g}")
            if validate and not c.held_out < 1.0:
                why.append(f"held-out RMSE {c.held_out:.3f} of the base's (needs < 1)")
            if not why:
                chosen = i
                break
            reasons[" + ".join(c.terms)] = "; ".join(why)
        return cands, ranked, chosen, reasons, inclusion, n_eff

    cands, ranked, chosen, reasons, inclusion, n_eff = rank(fits)
    # the polish: removals, swaps and additions from the best structure with terms, every move refitted on the
    # output-error cost (:mod:`.polish`) on the same workspace; the structure it ends at is ranked with the rest
    polished = None
    top = next((c for c in ranked if c.terms and math.isfinite(c.criteria[criterion])), None)
    if top is not None and not top.criteria[criterion] <= cands[0].criteria[criterion] - MARGIN:
        top = None  # no structure with terms beats the base: nothing to polish (a null case costs no more)
    # the selected structure's final fit through the driver: one start, already converged on the whole runs, so no
    # warm-up (it would fit the first part of the runs and move away from it) and no drawn starts (the refits
    # searched; 8 s of a cold discovery); its programs compile while the polish goes on, for each structure it reaches
    final_options = dataclasses.replace(term_options, warmup=0.0, adaptive=False)
    ahead: list = []

    def final_problem(cand: tuple[str, ...], params: dict[str, float]) -> tuple[AbstractModel, ParamSpec]:
        model = with_terms(base.with_params({n: params[n] for n in base.param_names}), cand)
        return model, term_spec(model, spec.with_values({n: params[n] for n in spec.free_names}), train,
                                force_levels(train, base))

    def compile_ahead(cand: tuple[str, ...], params: dict[str, float]) -> None:
        for p in ahead:
            p.cancel()
        try:
            model, cspec = final_problem(cand, params)
            ahead.append(prefetch(final_options.programs(model, train, cspec,
                                                         priors=fit_priors(model, cspec, final_options)[0]), 0.0))
        except Exception:  # noqa: BLE001 - only a head start: the final fit compiles what is missing and says why
            pass
    if polish_rounds and top is not None:
        say(f"polish: removals, swaps and additions from {' + '.join(top.terms)}, every move refitted...")
        try:
            polished = polish(res0, spec, train, terms, top.terms, max_terms=max_terms, max_rounds=polish_rounds,
                              start_values={t: top.result.params[t] for t in top.terms},
                              start_base={n: top.result.params[n] for n in res0.params}, workspace=ws,
                              start_refit=refits.get(frozenset(top.terms)), n_finish=n_finish, progress=say,
                              on_move=lambda S, vals, base_vals: compile_ahead(S, {**res0.params, **base_vals}))
        except DiffshipError as exc:
            say(f"  polish failed: {exc}")
    if polished is not None and frozenset(polished.selected) not in {frozenset(c) for c, _ in fits}:
        fits.append((polished.selected, as_result(polished.selected, polished.result)))
        cands, ranked, chosen, reasons, inclusion, n_eff = rank(fits)
    # the selected structure through the driver, from its workspace optimum: what is reported, saved and bootstrapped
    # (the user's priors, the covariance); the ranking stands on the workspace refits, the same
    # problem for every structure
    base_c = next(c for c in cands if not c.terms)
    base_c = dataclasses.replace(base_c, result=res0, train=judged(res0, train),
                                 validation=judged(res0, validate) if validate else None)
    best = ranked[chosen] if ranked[chosen].terms else base_c
    if not best.terms and res0.result == RESULTS.cost_stalled and options.stall is None:
        # the base is the answer: its stalled solve is finished from where it stopped (no warm-up, no draws)
        say(f"refit by output error through the driver: {base.name} (selected; its base fit had stalled)")
        res0 = fit(base, train, dataclasses.replace(options, warmup=0.0, adaptive=False), spec=spec,
                   starts={"the base fit": {n: res0.params[n] for n in spec.free_names}}, n_starts=1, progress=say,
                   throw=False)
        base_c = dataclasses.replace(base_c, result=res0, train=judged(res0, train),
                                     validation=judged(res0, validate) if validate else None)
        best = base_c
    if best.terms:
        start = {**{n: best.result.params[n] for n in spec.free_names}, **{t: best.result.params[t] for t in best.terms}}
        say(f"refit by output error through the driver: {' + '.join(best.terms)} (the selected structure)")
        model, cspec = final_problem(best.terms, best.result.params)
        try:
            res = fit(model, train, final_options, spec=cspec, starts={"the workspace optimum": start}, n_starts=1,
                      progress=say, throw=False)
        except DiffshipError as exc:
            raise DiffshipError(f"discover: the selected structure {' + '.join(best.terms)} failed in the driver: "
                                f"{exc}") from exc
        vev = judged(res, validate) if validate else None
        best = dataclasses.replace(best, result=res, train=judged(res, train), validation=vev,
                                   held_out=_score(vev, base_c.validation))
    for p in ahead:
        p.cancel()
    ranked = [best if i == chosen else (base_c if not c.terms else c) for i, c in enumerate(ranked)]
    cands = [base_c if not c.terms else c for c in cands]
    confirmed = None if not validate else bool(best.held_out <= 1.0 + 1e-9)
    possible = tuple(t for t in dict.fromkeys(
        [t for c in ranked[:chosen] for t in c.terms] + [t for t, p in inclusion.items() if p > 0])
        if t not in best.terms)
    trade = []
    cov, free = best.result.covariance, best.result.free
    if cov is not None and np.all(np.isfinite(cov)):
        sd = np.sqrt(np.maximum(np.diag(cov), 1e-300))
        corr = cov / np.outer(sd, sd)
        for i in range(len(free)):
            for j in range(i + 1, len(free)):
                if abs(corr[i, j]) > TRADEOFF and (free[i] in best.terms or free[j] in best.terms):
                    trade.append((free[i], free[j], float(corr[i, j])))
    # equivalent explanations: structures within the margin of the selected one's criterion (the data do not decide
    # between them), and the probe manoeuvre whose predictions differ most (:mod:`.separate`)
    equivalent = tuple(c for c in ranked if c is not best and math.isfinite(c.criteria[criterion])
                       and abs(c.criteria[criterion] - best.criteria[criterion]) < MARGIN)[:MAX_EQUIVALENT]
    separation = None
    if equivalent:
        say("equivalent explanations: " + "; ".join(" + ".join(c.terms) or "(base)" for c in equivalent)
            + f" within {criterion.upper()} {MARGIN:g} of the selected; simulating the probe manoeuvres...")
        try:
            separation = separating_manoeuvre([best.result] + [c.result for c in equivalent],
                                              list(train) + list(validate))
        except DiffshipError as exc:
            say(f"  the probe manoeuvres failed: {exc}")
    return Discovery(base=cands[0], candidates=tuple(ranked), screen=sc, criterion=criterion, n_eff=n_eff,
                     confirmed=confirmed, possible=possible, tradeoffs=tuple(trade),
                     seconds=time.perf_counter() - t0, inclusion=inclusion, chosen=chosen, reasons=reasons,
                     n_boot=n_boot_rank, oe_screen=oe, equivalent=equivalent, separation=separation,
                     polish=polished)
