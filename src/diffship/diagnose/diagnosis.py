"""The :func:`diagnose` entry point and its typed result :class:`Diagnosis`.

``diagnose`` sequences the steps: base fit (output error on the training runs, unless given)
→ noise floor (:func:`~.where.noise_floor`) → screen of the applicable effects
(:class:`~.screen.Workspace`) → the no-effect reference refit and the refits of the best
candidates, side by side (:func:`~.screen.parallel`) → **where** on the validation runs
(:mod:`.where`) → judgements and the greedy path, on the validation runs only (:mod:`.which`,
:mod:`.shrink`) → ranking and verdicts (:mod:`.verdict`).

**Effort.** The base fit and every refit stop a crawl early (``DiagnoseOptions.stall``: the cost
falls by less than 0.1 % over 10 Levenberg–Marquardt steps while the Gauss–Newton model still
promises more; the base fit then says "stopped early: the cost stalled", not converged). Measured
on the USV current case (3 + 2 runs of 240 s, ``benchmarks/diagnose_current_case.py``): the base fit's whole-run solve 91 steps
instead of 4 × 200, the wrong candidates' refits 42 steps instead of up to 600, the result the same
(``benchmarks/results/diagnose_current_case.md``). ``timings`` gives ``refits`` (the reference
and the single candidates together) and ``where`` (the analysis alone). The workspace's programs
compile while the base fit runs (:func:`prefetch_workspace`), and the refits' compiled solve also
gives the screen's and the covariances' Jacobians: on that case a cold whole process went from 133
to 82–93 s on two cores.
"""

from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Callable, Sequence

import numpy as np

from ..data import Run
from ..compiled import Prefetch, prefetch
from ..errors import DataError, FitError
from ..fit import FitResult, OutputErrorOptions, fit_output_error
from ..fit.feedback import loop_evidence
from ..fit.problem import default_channels
from ..metrics import Evaluation, evaluate
from ..models import AbstractModel
from ..params import ParamSpec
from ..simulate import simulation_request
from ..usability import verdict as fit_verdict
from ..models.effects import POSSIBLE_ONLY, Augmented, applicability, is_ship3, library
from .options import DiagnoseOptions
from .screen import ScreenResult, Workspace
from .shrink import PathStep, Validation, rmse_per_channel
from .start import StartRule
from .variation import TimeVariation, time_variation
from .verdict import RankedEffect, in_base, in_base_line, rank, verdict_lines
from .consistency import DataFinding, corrected, correction_note, data_checks, in_data_line
from .floors import physical_position_floor
from .periodic import periodic_residual, training_period
from .sea_state import SeaState, sea_state
from .where import GapBudget, GapGate, WhereAnalysis, gap_budget, noise_estimates, structural_gate, where_analysis
from .which import Search, refit_order

__all__ = ["diagnose", "Diagnosis", "diagnosis_channels", "prefetch_workspace", "workspace_programs"]

SHRINK_DEFINITION = ("(S(E_before) - S(E_after)) / S(E_before) with S(E) = sqrt(max(E^2 - 1, 0)): share of the "
                     "structural (above-noise, RMS) validation error closed by the selected effects")


@dataclasses.dataclass(frozen=True, eq=False)
class Diagnosis:
    """Everything :func:`diagnose` found (``to_dict()`` gives the JSON).

    E values are validation errors normalised by the per-channel ``noise_floor`` (1 = noise);
    ``noise_estimate`` says per channel which estimate gave it (white second differences, the
    coloured-noise structure-function fit, or given by the user) with its fitted correlation.
    ``shrink`` is the share of the structural gap S = √(E_before² − 1) that the
    ``selected`` effects close (:mod:`.shrink`); ``path`` the greedy steps; ``ranking`` every candidate with its verdict;
    ``verdict`` the where / which / how-far summary; ``skipped`` the effects that do not apply,
    with the reason; ``final_model`` the base with the selected effects (and refitted base
    parameters); ``eval_before`` / ``eval_after`` the validation evaluations of the base and
    final models on ``val_runs``; ``reference`` which base model the candidates were judged against
    (the base refitted by the refit procedure with no effect, when that lowers its training cost);
    ``possible`` effects under the gap gate (low confidence, not selected); ``partial`` whether a
    structural gap (E ≥ the gate) remains after the selected effects; ``gate`` the gap gate used
    (from the sample counts unless ``DiagnoseOptions.gap_gate`` fixes it; :func:`~.where.structural_gate`);
    ``start`` the held-out start rule (:mod:`.start`) and the start the base and final models used
    (offsets from the logged state in noise floors, the bounds that were active); ``notes`` what
    the diagnosis changed in the base fit (a model's own rudder offset held at 0);
    ``time_variation`` the check of the first selected effect for a change along the run
    (:mod:`.variation`; a possible one adds a fourth verdict line and its name to ``possible``;
    ``None`` when the effect has no varying form or already leaves the held-out runs under the
    gap gate); ``in_base`` the library effects the base model carries as a parameter of its own,
    estimated by the base fit or held at a given non-zero value (:func:`~.verdict.in_base`; a
    rudder zero error is MMG's ``delta0``), with a verdict line for the estimated ones whose 95 %
    interval excludes 0 and the held ones; ``waiting`` the effects that also passed at the greedy
    path's last step when the path stopped at its cap with a structural gap left, ``(name,
    validation gain)`` (:attr:`~.which.Selection.waiting`: a further step, ``greedy_steps``, may
    attribute one); ``in_data`` the data-consistency checks (:mod:`.consistency`: the heading
    against the track and over-ground u, v; the yaw rate against the heading; the time the motion
    follows the logged rudder), each with its estimate, interval and whether it is a finding
    (then a verdict line "In the data"); ``sea_state`` the check for a stochastic narrow-band disturbance
    (:mod:`.sea_state`; a verdict line "Sea state"), ``None`` when it did not run; ``base_verdict`` the base fit's
    verdict (:mod:`diffship.usability`, as JSON; a base fit that is not plainly usable is also in ``notes``).
    """

    model_name: str
    channels: tuple[str, ...]
    noise_floor: dict[str, float]
    noise_estimate: dict[str, dict]
    where: WhereAnalysis
    gap: GapBudget
    screen: tuple[ScreenResult, ...]
    ranking: tuple[RankedEffect, ...]
    selected: tuple[str, ...]
    path: tuple[PathStep, ...]
    rmse_before: dict[str, float]
    rmse_after: dict[str, float]
    E_before: float
    E_after: float
    shrink: float
    verdict: tuple[str, ...]
    base_fit: FitResult
    final_model: Augmented
    eval_before: Evaluation
    eval_after: Evaluation
    skipped: dict[str, str]
    timings: dict[str, float]
    val_runs: tuple[Run, ...] = ()
    reference: str = ""
    possible: tuple[str, ...] = ()
    partial: bool = False
    gate: GapGate | None = None
    start: dict | None = None
    notes: tuple[str, ...] = ()
    time_variation: TimeVariation | None = None
    in_base: dict = dataclasses.field(default_factory=dict)
    waiting: tuple[tuple[str, float], ...] = ()
    in_data: dict[str, DataFinding] = dataclasses.field(default_factory=dict)
    sea_state: SeaState | None = None
    base_verdict: dict | None = None

    @property
    def gap_gate(self) -> float:
        """The gap gate used (E ≥ it: a structural gap)."""
        return self.gate.value if self.gate is not None else float("nan")

    @property
    def shrink_total_error(self) -> float:
        """Fraction of the whole validation error removed, (E_before − E_after) / E_before."""
        return (self.E_before - self.E_after) / self.E_before if self.E_before > 0 else 0.0

    def to_dict(self) -> dict:
        return {
            "model": self.model_name,
            "channels": list(self.channels),
            "verdict": list(self.verdict),
            "where": self.where.to_dict(),
            "gap_budget": self.gap.to_dict(),
            "screen": [dataclasses.asdict(s) for s in self.screen],
            "ranking": [r.to_dict() for r in self.ranking],
            "selected": list(self.selected),
            "possible": list(self.possible),
            "partial": self.partial,
            "waiting": [{"effect": n, "validation_gain": g} for n, g in self.waiting],
            "path": [p.to_dict() for p in self.path],
            "validation_rmse_before": self.rmse_before,
            "validation_rmse_after": self.rmse_after,
            "validation_E_before": self.E_before,
            "validation_E_after": self.E_after,
            "noise_floor": self.noise_floor,
            "noise_estimate": self.noise_estimate,
            "shrink": self.shrink,
            "shrink_definition": SHRINK_DEFINITION,
            "shrink_total_error": self.shrink_total_error,
            "base_params": self.base_fit.params,
            "base_starts": self.base_fit.starts.as_json() if self.base_fit.starts is not None else None,
            "final_params": self.final_model.param_values(),
            "not_applicable": self.skipped,
            "reference": self.reference,
            "gap_gate": dataclasses.asdict(self.gate) if self.gate is not None else None,
            "start": self.start,
            "notes": list(self.notes),
            "time_variation": self.time_variation.to_dict() if self.time_variation else None,
            "in_base": self.in_base,
            "in_data": {k: f.to_dict() for k, f in self.in_data.items()},
            "sea_state": ({**self.sea_state.to_dict(), "estimates": self.sea_state.compare(
                self.base_fit.params, self.base_fit.stderr)} if self.sea_state is not None else None),
            "timings_s": self.timings,
            "base_verdict": self.base_verdict,
        }


def diagnosis_channels(model: AbstractModel, runs: Sequence[Run]) -> tuple[str, ...]:
    """The fit's default channels plus the positions where the model predicts them and every run
    has them: sensor and kinematic effects (heading bias, current) show mainly in the GNSS
    track, so a diagnosis without positions cannot see them (the fit's own default leaves
    positions out for robustness of fits from poor starts)."""
    chans = default_channels(model, runs)
    pos = tuple(c for c in ("x0", "y0") if c in model.output_names and c not in chans and all(r.has(c) for r in runs))
    return tuple(c for c in model.output_names if c in chans or c in pos)


def own_twin(model: AbstractModel, effect: str) -> str | None:
    """The model's own parameter that *is* the library's candidate ``effect``
    (:meth:`~diffship.models.AbstractModel.effect_twins`: a Nomoto model's ``delta0`` is the
    ``rudder_offset`` candidate, δ + δ_off), or ``None``. On 3-DOF ships the candidate is ``constant_force``, a
    sway force and yaw moment fixed to the hull: another effect than their ``delta0``."""
    par = model.effect_twins().get(effect)
    return None if par is None or is_ship3(model) else par


def candidate_effects(model: AbstractModel, train, o: DiagnoseOptions, free: Sequence[str],
                      values: dict[str, float] | None = None, starts=None) -> tuple[list, dict[str, str]]:
    """The library's effects for a base model fitted with the free parameters ``free``, and
    ``{name: reason}`` for those skipped: a candidate whose :func:`own_twin` the base fit estimates
    (a Nomoto model's rudder offset ``delta0``; its value from ``values`` when known) is the same
    effect, and no candidate."""
    effs, skipped = library(model, train, o.effect_names, starts=starts)
    for name in [e.name for e in effs]:
        par = own_twin(model, name)
        if par is not None and par in free:
            effs = [e for e in effs if e.name != name]
            v = (values or {}).get(par)
            unit = next((p.unit for p in model.spec().params if p.name == par), "")
            skipped[name] = (f"the given base fit estimated the model's own {par}"
                             + (f" = {v:.4g} {unit}".rstrip() if v is not None else "") + " (the same effect)")
    return effs, skipped


def split_varying(effs: Sequence) -> tuple[list, dict]:
    """The candidates the workspace screens and refits, and the varying forms
    (:data:`~diffship.models.effects.POSSIBLE_ONLY`: a changing current or lag) by name. A varying
    form is never screened nor refitted as a candidate: only :mod:`.variation` refits it, for the
    effect selected first, and only when that leaves a structural gap; it gets a workspace of its
    own then. Kept out of the all-effects workspace, every refit's simulation carries two effects
    fewer (the USV current case, with and without them in alternation, on 2 CPU cores: diagnosis
    125 → 110 s, CPU 230 → 199 s, ``benchmarks/results/diagnose_current_case.md``)."""
    return ([e for e in effs if e.name not in POSSIBLE_ONLY],
            {e.name: e for e in effs if e.name in POSSIBLE_ONLY})


def workspace_programs(model: AbstractModel, spec: ParamSpec, train, val, chans, o: DiagnoseOptions,
                       integrator) -> list:
    """The compiled programs the diagnosis's workspace will run (:meth:`~.screen.Workspace.programs`),
    from the base model *before* its fit: they depend on the structure only, so a workspace of the
    start model gives the fitted one's (``tests/diagnose/test_prefetch.py``). ``integrator``: the
    base fit's. Raises what building the workspace raises."""
    effs, _ = candidate_effects(model, train, o, spec.free_names)
    effs = split_varying(effs)[0]
    if not effs:
        return []
    start = spec.with_values(spec.nudged({p.name: p.value for p in spec.params})[0])  # the fit's start, inside its bounds
    ws = Workspace(model, start, effs, train, chans, {c: 1.0 for c in chans}, integrator=integrator,
                   max_iter=o.max_iter, stall=o.stall)
    # the held-out simulations of the base and of the workspace model (:class:`.shrink.Validation`)
    sims = [simulation_request(m, r, np.zeros(len(m.state_names)), integrator)
            for m in (ws.base, ws.model) for r in {r.n: r for r in val}.values()]
    return ws.programs(val) + sims


def prefetch_workspace(model: AbstractModel, spec: ParamSpec, train, val, chans, o: DiagnoseOptions,
                       integrator) -> Prefetch | None:
    """Compile :func:`workspace_programs` in the background while the base fit runs
    (:func:`diffship.compiled.prefetch`): XLA compiles on one core while the fit's solves run on
    the other, so a cold diagnosis no longer compiles them after the fit. A caller that fits the
    base model itself (``python -m diffship.diagnose``) calls it before its fit. ``None`` when no
    workspace can be built (the diagnosis then reports why itself)."""
    try:
        reqs = workspace_programs(model, spec, train, val, chans, o, integrator)
    except Exception:  # noqa: BLE001 - only a head start: the diagnosis builds the real workspace and says what fails
        return None
    return prefetch(reqs) if reqs else None


def _sea_line(base, train, ev, chans, loop) -> bool:
    """Closed loop and a periodic line in the base fit's training residuals that the steering may share (an autopilot
    answering a sea state at its period), ten cycles or more in every run (a sea state repeats; a zigzag's own
    period, which its rudder sets, comes a few times a run): the sea-state check's trigger beside an unsteered
    periodic residual."""
    if not (loop or {}).get("closed") or not ev.ok:
        return False
    res = ev.errors(train, chans, base.angle_outputs)
    return periodic_residual(train, res, None, list(res[train[0].name]), cycles=10.0) is not None


def diagnose(
    model: AbstractModel,
    train: Sequence[Run],
    val: Sequence[Run],
    *,
    fit: FitResult | None = None,
    spec: ParamSpec | None = None,
    options: DiagnoseOptions | None = None,
    progress: Callable[[str], None] | None = None,
    checked: dict[str, DataFinding] | None = None,
) -> Diagnosis:
    """Diagnose the gap of ``model`` (the rules are in :mod:`.which` and :class:`DiagnoseOptions`).

    Args:
        model: base model (its values are the fit's start) or the fitted model when ``fit``
            is given.
        train: training runs.
        val: held-out validation runs (required: selection never uses the training fit alone).
        fit: an existing output-error fit of ``model`` on ``train`` (skips the base fit).
        spec: free/fixed parameters of the base fit.
        options: candidates, effort and acceptance rule (default: :class:`DiagnoseOptions()`).
        progress: called with one line per step.
        checked: the data checks (:func:`~.consistency.data_checks`) already made on the logs as
            logged, when ``train`` and ``val`` are those logs corrected for their findings
            (:func:`~.consistency.corrected`; ``python -m diffship.diagnose --correct-data``): they are
            reported, not made again. Without it, ``DiagnoseOptions.correct_data`` corrects the logs
            here, before the base fit (not with a given ``fit``: it was made on the logs as logged).
    """
    say = progress or (lambda s: None)
    o = options or DiagnoseOptions()
    timings = {}
    if not train:
        raise DataError("diagnose: no training runs given")
    if not val:
        raise DataError("diagnose: no validation runs given (--validate VAL.csv ...); effects are selected on "
                        "held-out runs only, never on the training fit")
    t0 = time.perf_counter()
    spec = spec or model.spec()
    notes = []
    # measurement errors settled from the logs alone, before any model (:mod:`.consistency`)
    in_data = checked if checked is not None else data_checks(train, val, min_fall=o.min_gain)
    for f in in_data.values():
        say(f"data check {f.effect}: {f.shown()} — " + ("found" if f.found else f"not a finding: {f.reason}"))
    if checked is None and o.correct_data and (note := correction_note(in_data)) is not None:
        if fit is not None:
            raise DataError("correct_data: the given base fit was made on the logs as logged; correct the logs "
                            "(diffship.diagnose.consistency.corrected) and fit them, or leave correct_data off")
        train, val = corrected(train, in_data), corrected(val, in_data)
        notes.append(note)
        say(note)
    elif checked is not None and (note := correction_note(in_data)) is not None:
        notes.append(note)
    timings["data_checks"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    # a Nomoto model's own rudder offset delta0 would absorb the rudder_offset candidate (the same
    # rudder angle offset): the base fit holds it at 0 and the candidate is the offset
    # (:mod:`..models.effects.actuator`); on 3-DOF models the candidate is constant_force, a sway force and yaw moment
    for name in o.effect_names:
        par = own_twin(model, name)
        if fit is None and par is not None and par in spec.free_names and not applicability(model, name, train):
            spec = spec.fix({par: 0.0})
            notes.append(f"the base model's own {par} is held at 0 in the base fit: the {name} candidate stands for it")
            say(notes[-1])
    if fit is None:
        say(f"fitting the base model {model.name} by output error on {len(train)} runs...")
        chans0 = o.channels or diagnosis_channels(model, train)
        oe = OutputErrorOptions(max_steps=o.fit_steps, stall=o.stall, estimate_x0=model.states_for_channels(chans0))
        pre = prefetch_workspace(model, spec, train, val, chans0, o, oe.integrator)
        try:
            fit = fit_output_error(model, train, spec=spec, channels=chans0, progress=say, options=oe)
        except BaseException:
            if pre is not None:
                pre.cancel()
            raise
    timings["base_fit"] = time.perf_counter() - t0
    base_verdict = fit_verdict(fit, None, train)  # a doubtful base fit is said in the report, not only on the screen
    said = base_verdict.lines()
    if not base_verdict.usable or len(said) > 1:  # one note: the label, then each finding
        notes.append("base fit: " + "; ".join([said[0].split(": ", 1)[-1]] + [x.strip()[2:] for x in said[1:]]))
    base = fit.model
    chans = tuple(fit.channels)
    base_spec = spec.with_values({n: fit.params[n] for n in spec.names})
    est = None
    if o.noise:
        floor = dict(o.noise)
        noise_info = {c: {"sigma": floor[c], "method": "given (DiagnoseOptions.noise)"} for c in chans}
    else:
        est = physical_position_floor(noise_estimates(list(train) + list(val), chans, base.angle_outputs), val,
                                      o.position_accuracy, o.position_drift)
        floor = {c: e.sigma for c, e in est.items()}
        noise_info = {c: dataclasses.asdict(e) for c, e in est.items()}
    # the gap gate: the null scatter of E for these sample counts (p/N: the base fit's parameters)
    n_p, n_res = len(fit.free), max(int(fit.info.get("n_residuals", 1)), 1)
    if o.gap_gate is None:
        gate = structural_gate(chans, list(train) + list(val), val, est, param_sq=n_p / n_res, z=o.gate_z)
    else:
        gate = GapGate(float(o.gap_gate), float("nan"), float("nan"), 0.0, "fixed (DiagnoseOptions.gap_gate)")
    scales = {c: max(fit.noise_std.get(c, floor[c]), floor[c]) for c in chans}

    # the base fit's training simulation, once: the wave's start period from its periodic residual (:mod:`.periodic`)
    # and the closed-loop test (an input that reacts to its errors, an autopilot, biases every output-error refit)
    t0 = time.perf_counter()
    ev0 = evaluate(base, train, fit.initial_states if len(fit.initial_states) == len(train) else None, channels=chans,
                   integrator=fit.integrator)
    period = training_period(base, train, fit.initial_states, chans, fit.integrator, scales, ev=ev0) \
        if "wave" in o.effect_names else None
    if period is not None:
        say(f"periodic training residual at {period['period_s']:.4g} s in {', '.join(period['channels'])}: "
            "the wave candidate starts there")
    loop = loop_evidence(base, train, ev0, chans) if ev0.ok else None
    if loop is not None and loop["closed"]:
        notes.append(loop["text"])
        say(notes[-1])
    timings["period"] = time.perf_counter() - t0
    # a sea state (waves of random phase: filtered, not simulated) is judged by prediction (:mod:`.sea_state`)
    sea = None
    if o.sea_state == "always" or (o.sea_state == "auto" and (period is not None or _sea_line(base, train, ev0, chans, loop))):
        t0 = time.perf_counter()
        sea = sea_state(fit, train, val, chans, say)
        say(sea.line())
        timings["sea_state"] = time.perf_counter() - t0

    # -- which: screen -----------------------------------------------------------------------
    t0, c0 = time.perf_counter(), time.process_time()
    effs, skipped = candidate_effects(base, train, o, fit.free, fit.params,
                                      starts={"wave": {"T_w": period["period_s"]}} if period else None)
    effs, varying = split_varying(effs)
    if not effs:
        raise DataError(f"no candidate effect applies to {base.name} with these runs: {skipped}")
    say(f"screening {len(effs)} candidate effects ({', '.join(e.name for e in effs)})...")
    x0_train = fit.initial_states if len(fit.initial_states) == len(train) else None
    ws = Workspace(base, base_spec, effs, train, chans, scales, x0_train=x0_train, integrator=fit.integrator,
                   max_iter=o.max_iter, stall=o.stall)
    scr, sinfo = ws.screen()
    timings["screen"] = time.perf_counter() - t0
    timings["screen_cpu"] = time.process_time() - c0  # CPU time of all threads, compilation included
    start_rule = StartRule(bound=o.start_bound)
    validation = Validation(ws, val, floor, chans, start_rule)

    # -- the reference and the single candidates: refitted side by side ------------------------
    # the reference every candidate is judged against: the base refitted by the same refit
    # procedure (same steps, continuation rounds, initial-state estimation) with no effect, so an
    # effect's validation gain is never the credit for extra iterations of the base parameters.
    # It, the held-out base score and the candidates' refits are independent: one pool of threads
    # runs them (:func:`.screen.parallel`) — the first screened candidate beside the reference first,
    # and the others only when it does not close the gap alone (:mod:`.decided`). (Candidates started
    # at the reference's solution instead of the base fit took more steps on the USV current
    # case — 87 instead of 50 for the current: the reference stops in a crawl that they continue —
    # so they start at the base fit.)
    t0 = time.perf_counter()
    say(f"gap gate {gate.value:.3f} ({gate.method})")

    def reference():
        rf = ws.refit([], [{}], progress=say, finish=True)
        return rf, (validation.refit(rf) if rf.ok and rf.train_cost < sinfo["train_cost"] else None)
    search = Search(ws, validation, None, o, say, gate=gate.value)
    def reference_score(extras):  # what candidates are judged against (as below), from the extras' results
        rf_ref, base_score = extras
        if isinstance(base_score, Exception):
            return None
        return base_score if isinstance(rf_ref, Exception) or rf_ref[1] is None else rf_ref[1]
    refits, (ref, before) = search.refit_singles(refit_order(scr, o), extra=[reference, validation.base],
                                                 reference=reference_score,
                                                 shares={s.effect: s.predicted_fraction for s in scr})
    if isinstance(before, Exception):
        raise before
    search.set_base(before)
    timings["refits"] = time.perf_counter() - t0
    null_base, reference = None, "the base fit (the no-effect refit did not lower its training cost)"
    if isinstance(ref, FitError):
        say(f"  the no-effect refit failed: {ref}")
        reference = f"the base fit (the no-effect refit failed: {ref})"
    elif isinstance(ref, Exception):
        raise ref
    elif ref[1] is not None:
        rf0 = ref[0]
        say(f"the no-effect refit lowers the training cost {sinfo['train_cost']:.6g} → {rf0.train_cost:.6g}: "
            "candidates are judged against it")
        reference = (f"the base refitted by the refit procedure, no effect (training cost {sinfo['train_cost']:.6g} "
                     f"→ {rf0.train_cost:.6g}; base fit {'converged' if fit.converged else 'stopped: ' + str(fit.status)})")
        before = ref[1]
        sinfo["train_cost"] = rf0.train_cost
        null_base = rf0.base_values
        search.set_base(before)
    t0 = time.perf_counter()
    where = where_analysis(base, val, before.evaluation, floor, chans)
    timings["where"] = time.perf_counter() - t0
    gap = gap_budget(fit, before.E)
    say(f"validation error {before.E:.3g} × noise floor; screen took {timings['screen']:.1f} s")

    # -- which: judge, select --------------------------------------------------------------------
    search.null_base = null_base
    singles = search.judge_singles(refits)
    t0 = time.perf_counter()
    sel = search.select(singles)
    timings["greedy"] = time.perf_counter() - t0
    t0 = time.perf_counter()

    def own_workspace(effect):
        """A workspace of the base and one varying form alone, with its held-out scoring."""
        w = Workspace(base, base_spec, [effect], train, chans, scales, x0_train=x0_train,
                      integrator=fit.integrator, max_iter=o.max_iter, stall=o.stall)
        return w, Validation(w, val, floor, chans, start_rule)
    tv = time_variation(search, singles, sel.selected, say,
                        varying={n: functools.partial(own_workspace, e) for n, e in varying.items()})
    timings["time_variation"] = time.perf_counter() - t0

    # -- how far and verdicts --------------------------------------------------------------------
    ranking = rank(scr, singles, ws.effects, sel.selected, sinfo["train_cost"], skipped, o, sel.confidence,
                   sel.rivals, sel.note, sel.possible, not_refitted=search.not_refitted)
    shrink = sel.shrink(before.E)
    lines = verdict_lines(where, gap, ranking, sel.selected, before.E, sel.final.E, shrink, gate.value,
                          sel.possible, o.min_shrink, waiting=sel.waiting, greedy_steps=o.greedy_steps)
    possible = sel.possible
    if tv is not None and tv.possible:
        lines = (*lines, tv.line())
        possible = (*possible, tv.varying)
    twins = in_base(fit, base)
    if (line := in_base_line(twins)) is not None:
        lines = (*lines, line)
    if (line := in_data_line(in_data)) is not None:
        lines = (*lines, line)
    if sea is not None:
        lines = (*lines, sea.line(gap_unexplained=not sel.selected and before.E >= gate.value))
    return Diagnosis(
        model_name=model.name, channels=chans, noise_floor=floor, noise_estimate=noise_info, where=where, gap=gap, screen=tuple(scr),
        ranking=ranking, selected=sel.selected, path=sel.path,
        rmse_before=rmse_per_channel(before.evaluation, chans),
        rmse_after=rmse_per_channel(sel.final.evaluation, chans),
        E_before=before.E, E_after=sel.final.E, shrink=shrink,
        verdict=lines,
        base_fit=fit, final_model=search.final_model(sel), eval_before=before.evaluation,
        eval_after=sel.final.evaluation, skipped=skipped, timings=timings, val_runs=tuple(val), reference=reference,
        possible=possible, partial=bool(sel.selected) and sel.final.E >= gate.value, gate=gate,
        start={"rule": start_rule.describe(), "bound_noise_floors": start_rule.bound,
               "base": before.start.to_dict() if before.start else None,
               "final": sel.final.start.to_dict() if sel.final.start else None},
        notes=tuple(notes), time_variation=tv, in_base=twins, waiting=sel.waiting, in_data=in_data, sea_state=sea,
        base_verdict=base_verdict.as_json(),
    )
