"""What a report suggests when no fit is usable (:mod:`diffship.fit.hints`)."""

from __future__ import annotations

import math

import pytest

from diffship.fit.hints import MAX_STEPS, NextStep, held_reference_coefficients, next_step, next_steps
from diffship.models import Nomoto1
from diffship.models.mmg import kvlcc2_mmg
from diffship.usability import RunProblem


def test_held_reference_coefficients_are_the_fixed_ones_with_a_reference_value():
    model = kvlcc2_mmg()
    spec = model.spec()
    held = held_reference_coefficients(model, spec)
    assert held and set(held) <= set(spec.fixed_names)
    assert "Yvvv" in held and "Nvvv" in held  # hull coefficients the default free set leaves at the reference
    assert not set(held) & set(spec.free_names)
    # freeing them all leaves nothing to suggest
    assert held_reference_coefficients(model, spec.free(held)) == []
    # another vessel's particulars: the reference set is no prior for it, so nothing is suggested
    other = spec.fix({"m": 2.0 * spec.values()["m"]})
    assert held_reference_coefficients(model, other) == []


def test_next_steps_name_the_options_and_why():
    model = kvlcc2_mmg()
    spec = model.spec()
    late = RunProblem("Z_35_05", "psi", -20.5, 65.8, "training")
    early = RunProblem("Z_20_05", "psi", -5.0, math.nan, "training")  # not followed from the start: no horizon helps
    held_out = RunProblem("Z_10_10_P", "psi", -5.0, 30.0, "validation")
    steps = next_steps(model, spec, [late, early, held_out], horizon=None, priors=True, free_hydrodynamic=False)
    assert len(steps) == 2
    assert str(steps[0]).startswith("--free-hydrodynamic: ") and "Yvvv" in str(steps[0])
    assert str(steps[1]).startswith("--horizon 60: ") and "Z_35_05" in str(steps[1]) and "t = 66 s" in str(steps[1])
    assert (steps[0].option, steps[0].value, steps[1].option, steps[1].value) == (
        "--free-hydrodynamic", None, "--horizon", 60.0)
    # already given: not suggested again; --no-prior: no reference prior to hold them
    assert next_steps(model, spec, [late], horizon=60.0, priors=True, free_hydrodynamic=True) == []
    assert next_steps(model, spec, [], horizon=None, priors=False, free_hydrodynamic=False) == []
    # a longer horizon than the run is followed for is shortened
    assert str(next_steps(model, spec, [late], horizon=100.0, priors=True,
                          free_hydrodynamic=True)[0]).startswith("--horizon 60: ")


def test_the_command_takes_each_option_once_and_stops_after_max_steps():
    free = NextStep("--free-hydrodynamic", None, "held coefficients")
    h60, h40 = NextStep("--horizon", 60.0, "not followed from 66 s"), NextStep("--horizon", 40.0, "from 45 s")
    assert next_step([free, h60], ()) == free
    assert next_step([h60], (free,)) == h60
    # a horizon once: a second, shorter one is reported, not taken (a run would otherwise be cut ever shorter)
    assert next_step([h40], (free, h60)) is None and next_step([h40], (h60,)) is None
    assert next_step([], ()) is None
    # an option the user gave is named, not taken
    assert next_step([h60], (), given=("--horizon",)) is None and next_step([free, h60], (), ("--horizon",)) == free
    assert MAX_STEPS == 2 and next_step([h60], (free, free)) is None


def test_a_model_without_a_reference_set_suggests_no_freeing():
    model = Nomoto1()
    assert held_reference_coefficients(model, model.spec()) == []


def _stuck_rudder_runs(d):
    """Three Nomoto runs; the second's rudder log stuck at 15° from t = 60 s (the ship went on steering)."""
    import numpy as np

    from diffship.data import Run
    from diffship.synthetic import nomoto_runs

    paths = []
    for i, r in enumerate(nomoto_runs(n_runs=3, duration=120.0, dt=0.2, seed=3)):
        ch = {c: np.asarray(v).copy() for c, v in r.channels.items()}
        if i == 1:
            ch["delta"][np.asarray(r.time) >= 60.0] = math.radians(15.0)
        p = d / f"{r.name}.csv"
        Run(r.name, r.time, ch, {}, check_units=False).to_dataframe().to_csv(p, index=False)
        paths.append(str(p))
    return paths


@pytest.mark.slow  # CI time budget: run with python -m pytest -m slow
def test_the_fit_command_refits_a_fit_that_is_not_usable_with_the_option_its_report_names(tmp_path, capsys):
    """A training run the model follows only up to a time: the first fit is not usable; the command refits the
    part it follows (``--horizon``) and says so on the screen, in the report and the JSON; ``--as-given``
    keeps the first fit and names the option instead."""
    import json

    from diffship.fit.cli import main as fit_main

    a, b, v = _stuck_rudder_runs(tmp_path)
    common = [a, b, "--validate", v, "--model", "nomoto1", "--method", "output-error", "--quiet"]
    assert fit_main([*common, "--as-given", "--out", str(tmp_path / "given")]) == 1
    given = json.loads((tmp_path / "given" / "report.json").read_text())["methods"]["output_error"]
    assert given["usable"] is False and given["next_steps"][0].startswith("--horizon ")
    assert "steps_taken" not in given
    # a horizon the user gave is an override: it is named, not shortened
    assert fit_main([*common, "--horizon", "115", "--out", str(tmp_path / "h")]) == 1
    h = json.loads((tmp_path / "h" / "report.json").read_text())["methods"]["output_error"]
    assert "steps_taken" not in h and h["next_steps"][0].startswith("--horizon ")
    capsys.readouterr()
    code = fit_main([*common, "--out", str(tmp_path / "auto")])
    out = capsys.readouterr().out
    rep = json.loads((tmp_path / "auto" / "report.json").read_text())["methods"]["output_error"]
    assert code == 0 and rep["usable"] is True, out
    assert [s.split(":")[0] for s in rep["steps_taken"]] == [given["next_steps"][0].split(":")[0]]
    assert "options chosen after a fit that was not usable" in out and "zigzag_1" in out
    # the part it follows: the held-out run is predicted better than by the fit of the whole logs
    assert rep["validation"]["fit_percent"]["psi"] > given["validation"]["fit_percent"]["psi"] + 10.0


@pytest.mark.slow  # about 6 minutes on 2 cores: three fits, one of 33 coefficients
def test_the_plain_kvlcc2_command_reaches_the_study(tmp_path):
    """The HSVA KVLCC2 zigzags with no option but the model, the vessel and the rudder sign: the command takes
    ``--free-hydrodynamic`` and ``--horizon 60`` itself, the fit is usable, its held-out first overshoots are
    within 1° of HSVA's, and the 35° turn's tactical diameters within 5 % of the measured 3.1–3.3 L."""
    import json

    from diffship.data import shared_data_dir
    from diffship.fit.cli import main as fit_main
    from diffship.predict.__main__ import main as predict_main

    root = shared_data_dir()
    if root is None:
        pytest.skip("needs ../shared/data (the KVLCC2 model tests; DIFFSHIP_SHARED_DATA), absent here")
    f = [str(root / "kvlcc2_hsva" / f"HSVA_CPMC_KVLCC2_{n}.csv") for n in ("Z_10_05", "Z_20_05", "Z_35_05",
                                                                         "Z_20_10_S", "Z_10_10_P", "Z_20_10_P")]
    out = tmp_path / "fit"
    assert fit_main([*f[:4], "--validate", *f[4:], "--model", "mmg", "--vessel", "kvlcc2_model", "--rudder-sign",
                     "port", "--out", str(out), "--quiet"]) == 0
    rep = json.loads((out / "report.json").read_text())["methods"]["output_error"]
    assert [s.split(":")[0] for s in rep["steps_taken"]] == ["--free-hydrodynamic", "--horizon 60"]
    for h in rep["cross_manoeuvre"]["heldout"]:
        assert abs(h["metrics"]["first_overshoot"]["error"]) < 1.0, h
    assert predict_main([str(out / "fit.json"), "--manoeuvre", "turning:35", "turning:35:port", "--rudder-sign",
                         "port", "--out", str(tmp_path / "pred"), "--quiet"]) == 0
    pred = json.loads((tmp_path / "pred" / "prediction.json").read_text())
    td = [m["model_scale"]["tactical_diameter_L"] for m in pred["manoeuvres"] if m["kind"] == "turning_circle"]
    assert len(td) == 2 and all(3.1 * 0.95 <= v <= 3.3 * 1.05 for v in td), td
