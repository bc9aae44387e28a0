"""Prediction from a fit file: Froude scaling, IMO criteria, intervals, the command line."""

import json
import math

import numpy as np
import pytest

import diffship
from diffship import manoeuvres as M
from diffship.errors import DataError
from diffship.fit import FitResult
from diffship.fitfile import save_fit
from diffship.models import Nomoto1
from diffship.predict import overshoot_limits, parse_manoeuvre, predict
from diffship.predict.__main__ import main as predict_main

K, T, L, U, LAM = 0.25, 6.0, 4.0, 1.2, 16.0  # model scale: gain [1/s], time constant [s], length [m], speed [m/s]


def _fit_file(path, cov=True):
    model = Nomoto1(K=K, T1=T, delta0=0.0)
    free = ("K", "T1")
    res = FitResult(method="output_error", model=model, params=model.param_values(), stderr={"K": 0.005, "T1": 0.12},
                    free=free, converged=True, status="converged", iterations=1, cost=0.0, fit_seconds=0.0,
                    compile_seconds=0.0, channels=("psi", "r"),
                    covariance=np.diag([0.005**2, 0.12**2]) if cov else None)
    return save_fit(res, path)


def test_overshoot_limits_msc137():
    assert overshoot_limits(5.0) == (10.0, 25.0)
    assert overshoot_limits(20.0) == (15.0, 32.5)
    assert overshoot_limits(30.0) == (20.0, 40.0)


def test_parse_manoeuvre_both_side_conventions():
    assert parse_manoeuvre("zigzag:10/10") == parse_manoeuvre("zigzag:10:starboard") == parse_manoeuvre("zz:10/10:+1")
    p = parse_manoeuvre("turning:35:port")
    assert p.kind == "turning_circle" and p.side == -1.0 and p == parse_manoeuvre("turning:35:-1")
    assert parse_manoeuvre("pullout").rudder_deg == 20.0
    for bad in ("spiral:5", "zigzag:ten", "turning:35/5", "turning:60", "turning:.", "zigzag:10/0"):
        with pytest.raises(DataError, match="--manoeuvre"):
            parse_manoeuvre(bad)
    # a negative angle is not a side; a bad side is named with the whole item
    with pytest.raises(DataError, match=r"'turning:-35': a negative angle is not allowed.*turning:35:port"):
        parse_manoeuvre("turning:-35")
    with pytest.raises(DataError, match=r"'zigzag:-10/10': a negative angle.*zigzag:10/10:port"):
        parse_manoeuvre("zigzag:-10/10")
    with pytest.raises(DataError, match=r"--manoeuvre 'turning:35:up': side 'up'"):
        parse_manoeuvre("turning:35:up")


def test_a_criterion_without_limit_prints_no_number():
    from diffship.predict.criteria import check_criteria

    rows = [c.row() for c in check_criteria({"zigzag_10_10": {"first_overshoot": 8.0}}, None)]
    assert not any("nan" in r for r in rows), rows
    assert any("need L and V" in r and "—" in r for r in rows)


def _kinematic_track(run, speed):
    from scipy.integrate import cumulative_trapezoid

    psi = np.asarray(run["psi"])
    x = cumulative_trapezoid(speed * np.cos(psi), run.time, initial=0.0)
    y = cumulative_trapezoid(speed * np.sin(psi), run.time, initial=0.0)
    return diffship.data.Run(run.name, run.time, {**run.channels, "x0": x, "y0": y}, run.metadata, check_units=False)


def test_full_scale_equals_a_full_scale_simulation(tmp_path):
    """λ-scaled model-scale prediction = direct simulation of the Froude-scaled ship (K/√λ, T√λ, U√λ,
    IMO's 2.32°/s helm): lengths × λ, times × √λ, overshoots equal."""
    pred = predict(_fit_file(tmp_path / "f.json"), ["turning:35", "zigzag:10/10"], speed=U, length=L, scale=LAM,
                   samples=0)
    assert pred.condition.helm_rate_deg_s == pytest.approx(65 / 28 * 4.0)
    s = math.sqrt(LAM)
    full = Nomoto1(K=K / s, T1=T * s, delta0=0.0)
    dt = pred.condition.dt * s
    tc = _kinematic_track(M.turning_circle(full, {}, rudder_deg=35.0, duration=pred.manoeuvres[0].run.duration * s,
                                           dt=dt, t_execute=dt, rudder_rate_deg_s=65 / 28), U * s)
    tm = M.turning_metrics(tc, length=L * LAM)
    got = pred.manoeuvres[0].full_scale
    assert got["tactical_diameter"] == pytest.approx(tm.tactical_diameter, rel=2e-3)
    assert got["advance"] == pytest.approx(tm.advance, rel=2e-3)
    assert got["time_to_90"] == pytest.approx(tm.time_to_90, rel=2e-3)
    zz = M.zigzag_metrics(M.zigzag(full, {}, rudder_deg=10.0, duration=pred.manoeuvres[1].run.duration * s, dt=dt,
                                   t_execute=dt, rudder_rate_deg_s=65 / 28))
    got = pred.manoeuvres[1].full_scale
    assert got["first_overshoot"] == pytest.approx(zz.first_overshoot, abs=0.02)
    assert got["initial_turning_time"] == pytest.approx(zz.initial_turning_time, rel=2e-3)
    # criteria at full scale: L/V = √λ L/U
    assert pred.condition.l_over_v_full == pytest.approx(s * L / U)
    c = {cr.text.split(" (")[0]: cr for cr in pred.criteria}
    lim1, _ = overshoot_limits(s * L / U)
    assert c["10/10 zigzag: first overshoot"].limit == pytest.approx(lim1)
    assert c["10/10 zigzag: first overshoot"].passed == (zz.first_overshoot <= lim1)


def test_intervals_from_covariance_and_none_without(tmp_path):
    with_cov = predict(_fit_file(tmp_path / "a.json"), ["zigzag:10/10"], speed=U, length=L, helm_rate_deg_s=9.0,
                       samples=30)
    m = with_cov.manoeuvres[0]
    lo, hi = m.intervals["first_overshoot"]
    assert lo < m.metrics["first_overshoot"] < hi and hi - lo > 0.01 and m.samples_used == 30
    assert "N(θ̂, Σ)" in with_cov.interval_method
    no_cov = predict(_fit_file(tmp_path / "b.json", cov=False), ["zigzag:10/10"], speed=U, length=L,
                     helm_rate_deg_s=9.0)
    assert no_cov.manoeuvres[0].intervals == {} and "no intervals" in no_cov.interval_method


def test_command_line_writes_table_figure_json(tmp_path, capsys):
    path = _fit_file(tmp_path / "f.json")
    code = predict_main([str(path), "--manoeuvre", "turning:35", "zigzag:10/10:port", "--speed", str(U), "--length",
                         str(L), "--scale", str(LAM), "--samples", "0", "--out", str(tmp_path / "p"), "--quiet"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "tactical diameter" in out and "[L]" not in out and " m " in out and "deg" in out
    assert "5.2.1" in out and ("pass" in out or "FAIL" in out)
    doc = json.loads((tmp_path / "p" / "prediction.json").read_text())
    assert doc["condition"]["scale"] == LAM and doc["manoeuvres"][1]["side"] == -1.0
    assert (tmp_path / "p" / "prediction.png").stat().st_size > 10_000


def test_a_failed_fit_is_said_in_the_prediction_json_for_a_program(tmp_path, capsys):
    """A fit file labelled FAILED: the warning was only a note's text in prediction.json; ``fit`` now says it."""
    path = _fit_file(tmp_path / "f.json")
    doc = json.loads(path.read_text())
    doc.update(usable=False, verdict={"label": "FAILED", "usable": False, "reasons": ["it does not predict its "
                                      "held-out runs"], "runs": [], "unidentified": [], "on_bound": []})
    path.write_text(json.dumps(doc))
    code = predict_main([str(path), "--manoeuvre", "zigzag:10/10", "--speed", str(U), "--length", str(L), "--scale",
                         str(LAM), "--samples", "0", "--no-compare", "--out", str(tmp_path / "p"), "--quiet"])
    assert code == 0 and "WARNING: this fit is labelled FAILED" in capsys.readouterr().err
    pred = json.loads((tmp_path / "p" / "prediction.json").read_text())
    assert pred["fit"] == {"usable": False, "converged": True, "verdict": "FAILED"}, pred["fit"]


def test_command_line_errors_are_one_line(tmp_path, capsys):
    path = _fit_file(tmp_path / "f.json")
    assert predict_main([str(path), "--manoeuvre", "spiral", "--speed", "1"]) == 2
    assert capsys.readouterr().err.startswith("error: --manoeuvre 'spiral'")
    # a model-scale ship without a helm rate or a scale: no silent full-scale rate
    assert predict_main([str(path), "--speed", "1", "--length", "4"]) == 2
    assert "--helm-rate" in capsys.readouterr().err
    assert predict_main([str(tmp_path / "missing.json")]) == 2
    assert "fit file not found" in capsys.readouterr().err
    # checked before anything is flown: --out a file, a rudder or a missing input held constant
    (tmp_path / "a_file").write_text("")
    for out in ("a_file", "a_file/sub"):
        assert predict_main([str(path), "--speed", "1", "--out", str(tmp_path / out)]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"error: --out {tmp_path / out}: ") and "is a file, not a folder" in err, err
    assert predict_main([str(path), "--speed", "1", "--input", "delta=0.1"]) == 2
    assert capsys.readouterr().err.startswith("error: --input delta: the rudder angle is set by each manoeuvre")
    assert predict_main([str(path), "--speed", "1", "--input", "n=3"]) == 2
    assert capsys.readouterr().err.startswith("error: --input n: model nomoto1 has no input 'n'")
    assert predict_main([str(path), "--rps", "3"]) == 2
    assert capsys.readouterr().err.startswith("error: --rps: model nomoto1 has no propeller-rate input n")
    with pytest.raises(SystemExit) as exc:
        predict_main([str(path), "--samples", "-5"])
    assert exc.value.code == 2 and "--samples: '-5': must be 0 or more" in capsys.readouterr().err


def test_a_measured_run_that_cannot_be_flown_stops_before_anything_is_predicted(tmp_path, capsys):
    """``--measured`` runs are read and checked first: one without the model's input stops with its columns named,
    and nothing is flown or printed before."""
    path = _fit_file(tmp_path / "f.json")
    doc = json.loads(path.read_text())
    path.write_text(json.dumps({**doc, "training_manoeuvres": []}))
    t = np.arange(0.0, 20.0, 0.1)
    (tmp_path / "m.csv").write_text("time,psi,r\n" + "".join(f"{x:.1f},{0.01 * x:.4f},0.01\n" for x in t))
    assert predict_main([str(path), "--speed", "1", "--length", "4", "--helm-rate", "5",
                         "--measured", str(tmp_path / "m.csv")]) == 2
    cap = capsys.readouterr()
    assert cap.err.startswith(f"error: --measured {tmp_path / 'm.csv'}: no delta (its columns: psi, r)"), cap.err
    assert cap.out == ""


def test_readme_sspa_fit_predicts_its_own_zigzag_from_what_was_measured(tmp_path, capsys):
    """The README's fit (``python -m diffship.fit --out DIR``: nomoto2 on the bundled SSPA 20/20 zigzag),
    then ``python -m diffship.predict DIR/fit.json --manoeuvre zigzag:20/20`` with no helm rate and no speed:
    the fit file carries the rudder rate the record shows (≈ 20°/s, where IMO's 2.32°/s gave a 45° first
    overshoot), the switch delay and the speed over ground; the first table flies the training zigzag
    again beside its measured metrics, and the predicted first overshoot lies within 3° of the measured."""
    from diffship.data import example_runs
    from diffship.fit.cli import main as fit_main
    from diffship.predict.__main__ import main as predict_main
    from diffship.predict.cross import classify_run, run_metrics

    run = example_runs("sspa_zigzag")[0]
    measured = run_metrics(run, classify_run(run))["first_overshoot"]  # 19.3° (50 Hz record)
    assert fit_main(["--out", str(tmp_path / "fit"), "--quiet"]) == 0
    doc = json.loads((tmp_path / "fit" / "fit.json").read_text())
    assert 15.0 < doc["helm_rate"]["deg_s"] < 30.0 and doc["usable"] is True
    assert doc["training_manoeuvres"][0]["measured"]["first_overshoot"] == pytest.approx(measured, abs=0.5)
    capsys.readouterr()
    assert predict_main([str(tmp_path / "fit" / "fit.json"), "--manoeuvre", "zigzag:20/20", "--samples", "0"]) == 0
    out = capsys.readouterr().out
    compare = out.split("diffship prediction")[0]
    assert "training manoeuvres flown again" in compare and "sspa_zigzag" in compare
    row = next(ln for ln in compare.splitlines() if "first_overshoot" in ln).split()
    assert abs(float(row[-2]) - measured) < 3.0, row  # the training zigzag flown again
    first = next(ln for ln in out.split("diffship prediction")[1].splitlines() if "first overshoot" in ln)
    assert abs(float(first.split()[3]) - measured) < 3.0, first
    assert "measured in the training runs" in out
