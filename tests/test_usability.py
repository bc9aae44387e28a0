"""Verdicts: a run the model does not follow is named with its channel and onset; a parameter
the data do not determine is named with the cause; a fit is FAILED only when nothing is followed."""

import dataclasses
import math

import numpy as np

from diffship.data import Run
from diffship.fit.result import FitResult
from diffship.metrics import evaluate
from diffship.models import Nomoto1
from diffship.synthetic import nomoto_runs
from diffship.usability import run_problems, unidentified, verdict


def _result(model, params=None, stderr=None, free=("K", "T1")):
    p = dict(model.param_values()) | dict(params or {})
    return FitResult("output_error", model, p, dict(stderr or {n: 0.01 for n in free}), tuple(free), True,
                     "converged", 10, 1.0, 0.1, 0.0, channels=("psi", "r"))


def _drifting(run: Run, t_from: float, rate_deg_s: float) -> Run:
    """The run with its measured heading drifting away (an unmodelled disturbance) after ``t_from``."""
    psi = np.asarray(run["psi"]) + np.radians(rate_deg_s) * np.clip(run.time - t_from, 0.0, None)
    return run.with_channels(psi=psi)


def test_one_training_run_not_followed_is_named_and_the_fit_stays_usable():
    truth = Nomoto1(K=0.2, T1=8.0, delta0=0.01)
    runs = nomoto_runs(truth, n_runs=3, duration=60.0, dt=0.1, seed=4)
    train = [runs[0], _drifting(runs[1], 30.0, 2.0)]
    val = [runs[2]]
    res = _result(truth)
    ev_t, ev_v = evaluate(truth, train), evaluate(truth, val)
    probs = run_problems(ev_t, train, ["psi"])
    assert [p.run for p in probs] == [runs[1].name] and probs[0].channel == "psi"
    assert 24.0 < probs[0].from_s < 36.0, probs[0]  # the drift starts at 30 s (noise: a few seconds early)
    v = verdict(res, ev_t, train, ev_v, val)
    assert v.usable and v.label == "usable" and "1 of 2 training runs not followed" in v.reasons[0]
    assert "from t = " in v.lines()[-1]
    # every training run drifting and no held-out run followed: FAILED
    bad = [_drifting(r, 10.0, 4.0) for r in runs[:2]]
    v2 = verdict(res, evaluate(truth, bad), bad)
    assert not v2.usable and v2.label == "FAILED" and "every training run" in v2.reasons[0]


def test_unidentified_parameter_named_with_its_cause():
    """Xu with SE ≫ value on runs whose surge speed hardly varies: the cause in words."""
    t = np.arange(0.0, 60.0, 0.1)
    run = Run("const_thrust", t, {"u": 2.0 + 0.001 * np.sin(t), "v": 0.2 * np.sin(0.3 * t),
                                 "r": 0.05 * np.sin(0.2 * t), "psi": np.cumsum(0.05 * np.sin(0.2 * t)) * 0.1})
    out = unidentified({"Xu": -2e-6, "Nr": -1.0}, {"Xu": 6459.0, "Nr": 0.1}, ("Xu", "Nr"), [run])
    assert len(out) == 1 and out[0].startswith("Xu")
    assert "surge speed hardly varies" in out[0] and "fix Xu" in out[0], out[0]
    out = unidentified({"Nr": -1.0}, {"Nr": math.inf}, ("Nr",), [run])
    assert "Nr" in out[0] and "hardly varies" not in out[0]


def test_a_fit_that_does_not_predict_its_held_out_runs_is_not_usable():
    """Held-out runs fitted less than half as well as the training runs (here a heading that drifts away on the
    held-out run only): FAILED, with the channel, both fit percentages and the run named."""
    truth = Nomoto1(K=0.2, T1=8.0, delta0=0.01)
    runs = nomoto_runs(truth, n_runs=3, duration=60.0, dt=0.1, seed=4)
    train, val = runs[:2], [_drifting(runs[2], 5.0, 3.0)]
    ev_t, ev_v = evaluate(truth, train), evaluate(truth, val)
    v = verdict(_result(truth), ev_t, train, ev_v, val)
    assert not v.usable and v.label == "FAILED", v
    assert "does not predict its held-out runs: psi fit" in v.reasons[0] and runs[2].name in v.reasons[0], v.reasons
    # the same held-out run without the drift: usable
    assert verdict(_result(truth), ev_t, train, evaluate(truth, runs[2:]), runs[2:]).usable


def test_a_missed_held_out_manoeuvre_of_a_trained_type_makes_the_fit_not_usable():
    from types import SimpleNamespace as NS

    truth = Nomoto1(K=0.2, T1=8.0, delta0=0.01)
    runs = nomoto_runs(truth, n_runs=2, duration=60.0, dt=0.1, seed=4)
    ev = evaluate(truth, runs)
    zz = NS(kind="zigzag", label="zigzag 10/10")
    miss = NS(name="first_overshoot", unit="deg", measured=9.7, predicted=6.1, interval=(5.5, 6.7), flagged=True,
              outside_tolerance=True)
    ok = NS(name="first_overshoot", unit="deg", measured=9.7, predicted=9.5, interval=(9.0, 10.0), flagged=False,
            outside_tolerance=False)
    checks = NS(train_types=(zz,), checks=(NS(run="zz_held", type=zz, metrics=(miss,)),))
    v = verdict(_result(truth), ev, runs[:1], ev, runs[1:], manoeuvres=checks)
    assert not v.usable and "zz_held first_overshoot predicted 6.1 deg, measured 9.7 deg" in v.reasons[0], v.reasons
    fine = NS(train_types=(zz,), checks=(NS(run="zz_held", type=zz, metrics=(ok,)),))
    assert verdict(_result(truth), ev, runs[:1], ev, runs[1:], manoeuvres=fine).usable
    # a manoeuvre type not trained on is validation of extrapolation, not of the fit's own type: not this rule
    turn = NS(kind="turning_circle", label="turning circle 35°")
    other = NS(train_types=(zz,), checks=(NS(run="turn", type=turn, metrics=(miss,)),))
    assert verdict(_result(truth), ev, runs[:1], ev, runs[1:], manoeuvres=other).usable


def test_a_failed_verdict_still_names_unidentified_parameters_and_parameters_on_a_bound():
    """A FAILED verdict whose first reason is the simulation still lists, for a program reading the JSON, a
    parameter the data do not determine (SE ≫ value) and one the fit left on its bound (its identifiability); a
    usable fit with a parameter on its bound says so in its lines and its JSON."""
    truth = Nomoto1(K=0.2, T1=8.0, delta0=0.01)
    runs = nomoto_runs(truth, n_runs=2, duration=60.0, dt=0.1, seed=4)
    bound = {"identifiability": {"on_bound": [{"name": "T1", "value": 1e-6, "bound": 0.0}]}}
    res = dataclasses.replace(_result(truth, stderr={"K": 0.01, "T1": 500.0}), info=bound)
    bad = [_drifting(r, 10.0, 4.0) for r in runs]
    v = verdict(res, evaluate(truth, bad), bad)
    assert not v.usable and "every training run" in v.reasons[0], v
    doc = v.as_json()
    assert [w.split(" = ")[0] for w in doc["unidentified"]] == ["T1"], doc
    assert doc["on_bound"] and doc["on_bound"][0].startswith("T1 = 1e-06 is on its bound 0"), doc
    ok = verdict(dataclasses.replace(_result(truth), info=bound), evaluate(truth, runs), runs)
    assert ok.usable and ok.as_json()["on_bound"] and any("on its bound: T1" in x for x in ok.lines()), ok.lines()
    assert verdict(_result(truth), evaluate(truth, runs), runs).as_json()["on_bound"] == []
