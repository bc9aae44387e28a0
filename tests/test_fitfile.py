"""The fit file (diffship.fit/1): written by a fit, read back by load_fit and Model.from_fit."""

import hashlib
import json
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest

import diffship
from diffship.errors import DataError, ModelError
from diffship.fit import fit_output_error
from diffship.fitfile import SCHEMA, save_fit
from diffship.integrators import RK4
from diffship.models import Nomoto1, Nomoto2
from diffship.simulate import initial_state, model_inputs, simulate
from diffship.synthetic import nomoto_runs


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    d = tmp_path_factory.mktemp("fitfile")
    truth = Nomoto1(K=0.2, T1=8.0, delta0=0.01)
    paths = []
    for r in nomoto_runs(truth, n_runs=2, duration=40.0, dt=0.2, noise="realistic"):
        p = d / f"{r.name}.csv"
        r.to_dataframe().to_csv(p, index=False)
        paths.append(p)
    runs = diffship.data.load_runs(paths)
    from diffship.fit import OutputErrorOptions

    res = fit_output_error(Nomoto1(), runs, options=OutputErrorOptions(integrator=RK4()))
    path = save_fit(res, d / "fit.json", runs)
    return res, runs, paths, path


def test_round_trip_keeps_values_covariance_integrator_and_provenance(fitted):
    res, runs, paths, path = fitted
    doc = json.loads(path.read_text())
    assert doc["schema"] == SCHEMA and doc["model"]["registry"] == "nomoto1"
    fit = diffship.load_fit(path)
    assert fit.params == res.params and fit.free == res.free
    assert fit.fixed == {n: v for n, v in res.params.items() if n not in res.free}
    np.testing.assert_array_equal(fit.covariance, res.covariance)
    assert fit.covariance_names == res.free and fit.has_covariance
    assert isinstance(fit.integrator, RK4) and fit.units["T1"] == "s"
    for p, d, run in zip(paths, fit.data, runs):
        assert d["sha256"] == hashlib.sha256(p.read_bytes()).hexdigest()
        assert d["samples"] == run.n == 201 and d["dt"] == pytest.approx(0.2)
    assert fit.operating_point["delta"] == pytest.approx(float(np.mean([r["delta"][:6].mean() for r in runs])))
    assert set(fit.initial_states) == {r.name for r in runs}
    # the loaded model simulates exactly like the fitted one
    run = runs[0]
    args = (jnp.asarray(run.time), jnp.asarray(model_inputs(res.model, run)), jnp.asarray(initial_state(res.model, run)))
    a = simulate(res.model, *args, RK4()).ys
    b = simulate(fit.model, *args, fit.integrator).ys
    np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert abs(fit.params["T1"] - 8.0) < 4 * fit.stderr["T1"] + 0.05 * 8.0


def test_from_fit_on_the_model_class(fitted):
    res, _, _, path = fitted
    m = Nomoto1.from_fit(path)
    assert m.param_values() == pytest.approx(res.params)
    with pytest.raises(ModelError, match="nomoto1.*not 'nomoto2'|holds a fit of model 'nomoto1'"):
        Nomoto2.from_fit(path)
    doc = json.loads(Path(path).read_text())  # a value taken out or spoilt: named, never the model's default
    del doc["params"]["T1"]
    (Path(path).parent / "no_T1.json").write_text(json.dumps(doc))
    with pytest.raises(DataError, match="no_T1.json: parameter.s. T1 of model nomoto1 missing"):
        Nomoto1.from_fit(Path(path).parent / "no_T1.json")
    doc["params"]["T1"] = "abc"
    (Path(path).parent / "bad_T1.json").write_text(json.dumps(doc))
    with pytest.raises(DataError, match="bad_T1.json: parameter T1 = 'abc' is not a finite number"):
        Nomoto1.from_fit(Path(path).parent / "bad_T1.json")


def test_bad_files_are_named(tmp_path):
    report = tmp_path / "report.json"
    report.write_text(json.dumps({"model": "nomoto1", "methods": {}}))
    with pytest.raises(DataError, match="report.json.*--json report"):
        diffship.load_fit(report)
    with pytest.raises(DataError, match="nope.json: fit file not found"):
        diffship.load_fit(tmp_path / "nope.json")
    (tmp_path / "x.json").write_text("{not json")
    with pytest.raises(DataError, match="x.json: not a readable JSON"):
        diffship.load_fit(tmp_path / "x.json")


def test_parameter_values_are_checked_on_load(fitted, tmp_path):
    """A fit file without values, with a value that is not a finite number or without a parameter of its
    model stops with one line naming the file and the parameter (no model defaults filled in)."""
    doc = json.loads(fitted[3].read_text())

    def bad(name, **change):
        f = tmp_path / f"{name}.json"
        f.write_text(json.dumps({**doc, **change}))
        return f

    cases = [(bad("noparams", params=None), r"noparams.json: no parameter values"),
             (bad("str", params={**doc["params"], "K": "abc"}), r"str.json: parameter K = 'abc' is not a finite"),
             (bad("nan", params={**doc["params"], "T1": float("nan")}), r"nan.json: parameter T1 = nan"),
             (bad("noT1", params={k: v for k, v in doc["params"].items() if k != "T1"}),
              r"noT1.json: parameter\(s\) T1 of model nomoto1 missing"),
             (bad("relabelled", model={**doc["model"], "name": "nomoto2", "registry": "nomoto2"}),
              r"relabelled.json: parameter\(s\) T2, T3 of model nomoto2 missing"),
             (bad("cov", covariance={"names": ["K"], "matrix": "x"}), r"cov.json: 'covariance' must be null")]
    for path, message in cases:
        with pytest.raises(DataError, match=message):
            diffship.load_fit(path)


def test_priors_are_carried(fitted, tmp_path):
    import dataclasses

    res, runs, _, _ = fitted
    priors = {"T1": {"mean": 8.0, "sd": 2.0, "source": "sea trial"}}
    res2 = dataclasses.replace(res, info={**res.info, "priors": priors})
    fit = diffship.load_fit(save_fit(res2, tmp_path / "p.json", runs))
    assert fit.priors == priors


def test_structure_is_checked_on_load(tmp_path):
    """A water-jet USV fit is not silently loaded into the force-input Fossen 3-DOF of the same name."""
    from diffship.fit import FitResult
    from diffship.models import Fossen3, WaterJet, usv_standard

    jet = usv_standard(actuator=WaterJet())
    res = FitResult(method="output_error", model=jet, params=jet.param_values(), stderr={}, free=(), converged=True,
                    status="converged", iterations=0, cost=0.0, fit_seconds=0.0, compile_seconds=0.0)
    path = save_fit(res, tmp_path / "jet.json")
    assert json.loads(path.read_text())["model"]["registry"] == "fossen3_waterjet"
    assert diffship.load_fit(path).model.input_names == jet.input_names
    with pytest.raises(ModelError, match="inputs"):
        Fossen3.from_fit(path)
    with pytest.raises(DataError, match="inputs"):
        diffship.load_fit(path, model=Fossen3())


def test_a_fit_file_of_a_command_that_stopped_without_a_fit_is_refused_with_its_error(tmp_path):
    """Where a command stopped without a fit (every start diverged) it writes a fit file that says so: usable false,
    the verdict FAILED and the error, which load_fit and Model.from_fit refuse, naming the error."""
    from diffship.fitfile import stopped_document

    path = tmp_path / "fit.json"
    path.write_text(json.dumps(stopped_document("model nomoto1 diverges from every start", "nomoto1")))
    doc = json.loads(path.read_text())
    assert doc["schema"] == SCHEMA and doc["usable"] is False and doc["verdict"]["label"] == "FAILED"
    with pytest.raises(DataError, match="holds no fit: .*diverges from every start"):
        diffship.load_fit(path)
    with pytest.raises(ModelError, match="holds no fit: .*diverges from every start"):
        Nomoto1.from_fit(path)


def test_a_parameter_on_its_bound_is_a_warning_of_the_fit_file(fitted, tmp_path):
    from diffship.fitfile import fit_warnings

    res, runs, _, _ = fitted
    verdict = {"label": "usable", "usable": True, "reasons": [], "runs": [], "unidentified": [],
               "on_bound": ["T1 = 1e-06 is on its bound 0: the data push it past what the model allows"]}
    path = save_fit(res, tmp_path / "fit.json", runs, extra={"usable": True, "verdict": verdict})
    warnings = fit_warnings(diffship.load_fit(path))
    assert any(w.startswith("warning: parameter on its bound: T1 = 1e-06") for w in warnings), warnings
