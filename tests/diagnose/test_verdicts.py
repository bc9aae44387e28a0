"""Verdicts say what they know: the nearest miss, a partial explanation, a possible effect under
the gate — and the rule that flags a possible effect (no simulation: the judgement on given scores)."""

import math
from types import SimpleNamespace

import numpy as np

import diffship  # noqa: F401
from diffship.diagnose import DiagnoseOptions, make_effect
from diffship.diagnose.screen import RefitResult
from diffship.diagnose.verdict import RankedEffect, verdict_lines
from diffship.diagnose.which import Search
from diffship.models import Nomoto1

WHERE = SimpleNamespace(per_channel={"psi": {"share": 0.7}, "r": {"share": 0.3}}, per_phase={"transient": {"E": 2.0}})
GAP = SimpleNamespace(share_struct=0.8)


def _row(effect, gain, shrink, E, why=None, verdict="rejected", conf=None):
    return RankedEffect(effect=effect, family="actuator", params={"T_act": 1.1}, stderr={"T_act": 0.02},
                        validation_gain=gain, shrink=shrink, validation_E=E, verdict=verdict, confidence=conf,
                        runs_improved="1/2", why=why, separating_manoeuvre="steps at two amplitudes")


def test_nothing_accepted_names_the_nearest_miss():
    ranking = (_row("input_delay", 0.05, 0.07, 1.97, why="improves fewer than half of the validation runs"),
               _row("actuator_lag", 0.07, 0.09, 1.93, why="improves fewer than half of the validation runs"),
               _row("damping_rr", -0.4, -0.5, 2.9, why="validation gain -40 %"))
    which = verdict_lines(WHERE, GAP, ranking, (), 2.07, 2.07, 0.0, 1.1)[1]
    assert "unexplained" in which
    assert "nearest miss: actuator_lag" in which  # the largest validation gain, not the first row
    assert "7.0 %" in which and "shrink 0.09" in which and "fewer than half" in which and "1/2" in which
    # nothing lowers the validation error: said so, no nearest miss invented
    worse = (_row("damping_rr", -0.4, -0.5, 2.9, why="validation gain -40 %"),)
    which = verdict_lines(WHERE, GAP, worse, (), 2.07, 2.07, 0.0, 1.1)[1]
    assert "nearest miss" not in which and "no candidate lowers" in which


def test_partial_explanation_is_stated_with_its_share():
    ranking = (_row("actuator_lag", 0.3, 0.44, 1.5, verdict="attributed", conf="high"),)
    which = verdict_lines(WHERE, GAP, ranking, ("actuator_lag",), 2.07, 1.5, 0.44, 1.1)[1]
    assert "Partial" in which and "44 %" in which and "1.50" in which
    full = verdict_lines(WHERE, GAP, ranking, ("actuator_lag",), 2.07, 1.02, 0.97, 1.1)[1]
    assert "Partial" not in full


def test_a_path_stopped_at_its_cap_names_what_also_passed_instead_of_calling_the_rest_unexplained():
    """On the KVLCC2 logs with a 0.5-s rudder clock offset, damping_vr and damping_rv took the two
    steps the path allows and input_delay passed at step 2 behind them (+8.6 %): the verdict said
    the rest was unexplained by the library. It now says what passed and how to test it."""
    ranking = (_row("damping_vr", 0.5, 0.5, 51.2, verdict="attributed", conf="medium"),
               _row("damping_rv", 0.24, 0.24, 78.4, verdict="attributed (greedy step 2)"))
    which = verdict_lines(WHERE, GAP, ranking, ("damping_vr", "damping_rv"), 102.6, 44.5, 0.57, 1.12,
                          waiting=(("input_delay", 0.086),), greedy_steps=2)[1]
    assert "Partial" in which and "57 %" in which
    assert "input_delay (+8.6 % validation gain) also passed at step 2" in which
    assert "cap of 2 effect(s)" in which and "--greedy-steps" in which
    assert "unexplained" not in which
    # nothing waiting: the former wording
    plain = verdict_lines(WHERE, GAP, ranking, ("damping_vr", "damping_rv"), 102.6, 44.5, 0.57, 1.12)[1]
    assert "the rest is unexplained" in plain and "cap" not in plain


def test_possible_effect_under_the_gate_is_low_confidence_with_the_settling_experiment():
    ranking = (_row("input_delay", 0.06, 0.9, 1.01, verdict="possible effect (low confidence)"),)
    which = verdict_lines(WHERE, GAP, ranking, (), 1.07, 1.07, 0.0, 1.1, possible=("input_delay",))[1]
    assert "possible effect (low confidence): input_delay" in which
    assert "not attributed" in which and "above the gate" in which and "steps at two amplitudes" in which
    plain = verdict_lines(WHERE, GAP, ranking, (), 1.07, 1.07, 0.0, 1.1)[1]
    assert "no structural gap detected" in plain and "possible" not in plain


def _search(E0, e_runs0):
    eff = make_effect(Nomoto1(), "actuator_lag")
    ws = SimpleNamespace(effects=[eff])
    base = SimpleNamespace(E=E0, E_runs=e_runs0)
    return Search(ws, None, base, DiagnoseOptions(), lambda s: None)


def _judge(search, T, se, e_runs):
    rf = RefitResult(("actuator_lag",), {"T_act": T}, {"T_act": se}, {}, 1.0, 5, 0.1, True)
    E = float(np.sqrt(np.mean(np.square(list(e_runs.values())))))
    return search.judge(rf, search.base, SimpleNamespace(E=E, E_runs=e_runs), ["actuator_lag"])


def test_possible_rule_under_the_gate():
    s = _search(1.07, {"a": 1.08, "b": 1.06})
    # closes the small gap on both runs, interval excludes the null: possible, never accepted
    j = _judge(s, 0.8, 0.05, {"a": 1.01, "b": 1.00})
    assert j.possible and not j.ok and j.runs_improved == "2/2"
    assert "no structural gap" in j.why
    # interval includes the null: not possible
    assert not _judge(s, 0.8, 0.5, {"a": 1.01, "b": 1.00}).possible
    # gain on one run only: not possible
    assert not _judge(s, 0.8, 0.05, {"a": 0.99, "b": 1.07}).possible
    # a drop within the scatter of E on no-effect data: not possible
    assert not _judge(s, 0.8, 0.05, {"a": 1.065, "b": 1.05}).possible
    # at the noise floor there is nothing to close
    s1 = _search(0.99, {"a": 0.99, "b": 0.99})
    assert not _judge(s1, 0.8, 0.05, {"a": 0.98, "b": 0.97}).possible
    # above the gate the rule is the acceptance rule, not the possible one
    s2 = _search(1.5, {"a": 1.5, "b": 1.5})
    j2 = _judge(s2, 0.8, 0.05, {"a": 1.0, "b": 1.0})
    assert j2.ok and not j2.possible and math.isclose(j2.gain, 1 - 1.0 / 1.5)


def test_a_significant_term_that_closes_the_gap_is_relevant_below_the_absolute_threshold():
    """A weak |v|v term on a small USV (N_vv = -60 ± 3, MIN_RELEVANT 100) closed the whole
    validation gap and was rejected as 'below relevance'; the rule now takes the validation gain
    (against the refitted base) as the relevance of the term."""
    from diffship.models import Fossen3

    eff = make_effect(Fossen3(), "damping_vv")
    s = Search(SimpleNamespace(effects=[eff]), None, SimpleNamespace(E=1.16, E_runs={"a": 1.17, "b": 1.15}),
               DiagnoseOptions(), lambda m: None)
    rf = RefitResult(("damping_vv",), {"Nvv": -60.5}, {"Nvv": 3.0}, {}, 1.0, 5, 0.1, True)
    j = s.judge(rf, s.base, SimpleNamespace(E=0.99, E_runs={"a": 0.99, "b": 0.99}), ["damping_vv"])
    assert abs(-60.5) < eff.MIN_RELEVANT["Nvv"]
    assert j.ok, j.why
    # the same small magnitude with no validation gain stays irrelevant
    j0 = s.judge(rf, s.base, SimpleNamespace(E=1.15, E_runs={"a": 1.16, "b": 1.14}), ["damping_vv"])
    assert not j0.ok and "below relevance" in j0.why


def test_an_effect_the_base_model_carries_is_reported_in_the_base():
    """MMG's (and Nomoto's) rudder neutral angle delta0 is a rudder zero error: where the base fit
    estimated it, the diagnosis says the effect is in the base, with its value in degrees, and
    only when its 95 % interval excludes 0; a model without such a parameter reports nothing."""
    import math
    from types import SimpleNamespace

    from diffship.diagnose.verdict import in_base, in_base_line
    from diffship.models import MMG, Fossen3

    fit = SimpleNamespace(free=("Yv", "delta0"), params={"Yv": -0.3, "delta0": math.radians(1.0)},
                          stderr={"Yv": 0.01, "delta0": math.radians(0.05)})
    twins = in_base(fit, MMG())
    assert set(twins) == {"rudder_offset"} and twins["rudder_offset"]["parameter"] == "delta0"
    assert twins["rudder_offset"]["excludes_zero"]
    line = in_base_line(twins)
    assert line.startswith("In the base: rudder_offset as the base model's own delta0 = 1 ± 0.098 ° (estimated")
    # held at a given value (a study's earlier fit): said, as held; held at 0 (by the diagnosis on a
    # Nomoto model, whose candidate then stands for it): nothing to say
    held = in_base(SimpleNamespace(free=("Yv",), params=fit.params, stderr=fit.stderr), MMG())
    assert held["rudder_offset"]["held"] and "delta0 = 1 ° (held at the given value)" in in_base_line(held)
    zero = SimpleNamespace(free=("Yv",), params={**fit.params, "delta0": 0.0}, stderr=fit.stderr)
    assert in_base(zero, MMG()) == {}
    # an interval that includes 0: in the JSON, not in the verdict
    weak = SimpleNamespace(free=("delta0",), params={"delta0": math.radians(0.05)}, stderr={"delta0": math.radians(0.1)})
    assert not in_base(weak, MMG())["rudder_offset"]["excludes_zero"] and in_base_line(in_base(weak, MMG())) is None
    assert in_base(fit, Fossen3()) == {}
