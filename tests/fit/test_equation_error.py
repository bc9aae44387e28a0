import numpy as np
import pytest

from diffship.data import Run
from diffship.errors import DataError, ModelError
from diffship.fit import fit_equation_error
from diffship.fit.equation_error import equation_data
from diffship.models import Fossen3, Nomoto1, Nomoto2, kvlcc2_mmg
from diffship.preprocess import Filter
from diffship.synthetic import nomoto_runs, usv_runs, usv_truth


def _rel(a, b, names):
    return {n: abs(a[n] / b[n] - 1) if b[n] else abs(a[n]) for n in names}


def test_nomoto1_equation_error_noise_free():
    truth = Nomoto1(K=0.2, T1=8.0, delta0=0.01)
    runs = nomoto_runs(truth, n_runs=2, duration=60.0, dt=0.05, noise="none")
    res = fit_equation_error(Nomoto1(), runs, flt=Filter("none"))
    for n, v in truth.param_values().items():
        assert res.params[n] == pytest.approx(v, rel=2e-3), n


def test_nomoto1_yaw_rate_from_heading_when_r_is_not_measured():
    """``EQUATION_RATE_OF = {"r": "psi"}``: without an r channel, r is the derivative of the heading."""
    truth = Nomoto1(K=0.2, T1=8.0, delta0=0.01)
    runs = nomoto_runs(truth, n_runs=2, duration=60.0, dt=0.05, noise="none")
    no_r = [Run(r.name, r.time, {"psi": r["psi"], "delta": r["delta"]}, {}) for r in runs]
    z_r = equation_data(Nomoto1(), runs[0], Filter("none")).z[:, 0]
    z_psi = equation_data(Nomoto1(), no_r[0], Filter("none")).z[:, 0]
    assert np.max(np.abs(z_psi - z_r)[1:-1]) < 1e-3 * np.max(np.abs(z_r))
    res = fit_equation_error(Nomoto1(), no_r, flt=Filter("none"))
    assert max(_rel(res.params, truth.param_values(), ("K", "T1", "delta0")).values()) < 0.01
    with pytest.raises(DataError, match="psi"):
        fit_equation_error(Nomoto1(), [Run("x", runs[0].time, {"delta": runs[0]["delta"]}, {})])


def test_nomoto2_regression_start_falls_back_to_first_order():
    """Second-order regression coefficients that give no real positive time constants: the
    first-order regression is used with T2 = T1/10 (a pure map, no data needed)."""
    m = Nomoto2()
    first = {"a": -0.125, "b": 0.025, "c": 0.00025}  # T1 = 8, K = 0.2, δ0 = 0.01
    good = m.from_regression({"second_order": {"a": -0.125, "b": -1.125, "c": 0.025, "d": 0.00025, "g": 0.0125},
                              "first_order": first})
    assert good == pytest.approx({"K": 0.2, "T1": 8.0, "T2": 1.0, "delta0": 0.01, "T3": 0.5})
    bad = m.from_regression({"second_order": {"a": 0.1, "b": 0.0, "c": 1.0, "d": 0.0, "g": 0.0}, "first_order": first})
    assert bad == pytest.approx({"K": 0.2, "T1": 8.0, "T2": 0.8, "delta0": 0.01})
    assert m.from_regression({"second_order": {"a": 0.1, "b": 0.0, "c": 1.0, "d": 0.0, "g": 0.0},
                              "first_order": {"a": 0.1, "b": 1.0, "c": 0.0}}) is None


def test_fossen3_inverse_dynamics_is_linear_least_squares():
    """From the Fossen3 defaults (seed-002 damping, no added mass): every free parameter of the test
    truth is 30–50 % (added masses: entirely) away from its start."""
    truth = usv_truth()
    start = Fossen3()
    assert min(_rel(start.param_values(), truth.param_values(), start.spec().free_names).values()) > 0.24
    runs = usv_runs(2, 60.0, 0.05, noise="none", seed=4)
    res = fit_equation_error(start, runs, flt=Filter("savgol", window=0.5))
    rel = _rel(res.params, truth.param_values(), res.free)
    assert max(rel.values()) < 0.02, rel  # only derivative discretisation error remains
    assert res.converged and res.iterations <= 6


def test_equation_error_needs_velocities():
    run = usv_runs(1, 30.0, 0.1, noise="none")[0]
    no_v = run.to_dataframe().drop(columns=["v"])

    with pytest.raises(DataError, match="v"):
        fit_equation_error(Fossen3(), [Run.from_dataframe(no_v, name="no_v")])
    assert np.isfinite(run["u"]).all()


def test_model_without_equation_error_form_is_refused_first():
    """MMG declares no equations: a ModelError naming the model, before any data are looked at."""
    empty = Run("empty", np.arange(10.0), {"x": np.zeros(10)}, {})
    with pytest.raises(ModelError, match="mmg has no equation-error form; use output error"):
        fit_equation_error(kvlcc2_mmg(), [empty])
    with pytest.raises(ModelError, match="no equation-error form"):
        equation_data(kvlcc2_mmg(), empty)
