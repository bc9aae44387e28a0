"""Free-decay identification (seed 003): direct curve fits and the output-error path."""

import numpy as np
import pytest

from diffship.decay import decay_run, fit_first_order_decay, fit_second_order_decay
from diffship.errors import DataError
from diffship.fit import OutputErrorOptions, fit_equation_error, fit_output_error
from diffship.models import MODELS, Decay1, Decay2

# surge decay of a 1.2 t craft (incl. added mass) with D = 150 kg/s: time constant 8 s
M_SURGE, D_SURGE = 1200.0, 150.0
# roll decay: I = 3 kg m² (incl. added), k = 40 N m/rad, ζ = 0.08
I_ROLL, K_ROLL, ZETA = 3.0, 40.0, 0.08
B_ROLL = 2 * ZETA * np.sqrt(K_ROLL * I_ROLL)


@pytest.fixture(scope="module")
def surge_decay():
    # 2.0 m/s released; GNSS-grade velocity noise 0.02 m/s
    return decay_run(Decay1(m=M_SURGE, D=D_SURGE), 30.0, 0.1, [2.0], noise=0.02, seed=1)


@pytest.fixture(scope="module")
def roll_decay():
    # 0.3 rad heel released; attitude noise 0.005 rad (0.3°)
    run = decay_run(Decay2(I=I_ROLL, k=K_ROLL, b=B_ROLL), 20.0, 0.05, [0.3, 0.0], noise=0.005, seed=2)
    return run.__class__(run.name, run.time, {"angle": run["angle"], "tau": run["tau"]}, {})  # angle only


def test_registered():
    assert MODELS["decay1"] is Decay1 and MODELS["decay2"] is Decay2


@pytest.mark.parametrize("method, tol", [("curve_fit", 0.02), ("loglinear", 0.04)])
def test_first_order_curve_fit(surge_decay, method, tol):
    """u = u0·exp(−(D/m)t): D within 2 % (nonlinear LS) / 4 % (log-linear, noisier at small u)."""
    f = fit_first_order_decay(surge_decay.time, surge_decay["velocity"], M_SURGE, method=method)
    assert f.damping == pytest.approx(D_SURGE, rel=tol)
    assert f.x0 == pytest.approx(2.0, rel=0.02)
    assert f.time_constant == pytest.approx(M_SURGE / D_SURGE, rel=tol)
    assert abs(f.damping - D_SURGE) < 4 * f.damping_stderr + 1e-9  # the stated uncertainty is honest


def test_first_order_loglinear_rejects_sign_change():
    t = np.linspace(0, 10, 50)
    with pytest.raises(DataError):
        fit_first_order_decay(t, np.cos(t), method="loglinear", floor=0.0)


def test_second_order_curve_fit(roll_decay):
    """Damped oscillation: ζ within 3 %, ω_n within 0.5 %, b = 2ζω_n I within 3 %; the implied
    inertia k/ω_n² recovers I."""
    f = fit_second_order_decay(roll_decay.time, roll_decay["angle"], inertia=I_ROLL, stiffness=K_ROLL)
    assert f.zeta == pytest.approx(ZETA, rel=0.03)
    assert f.omega_n == pytest.approx(np.sqrt(K_ROLL / I_ROLL), rel=0.005)
    assert f.damping_from_inertia == pytest.approx(B_ROLL, rel=0.03)
    assert f.damping_from_stiffness == pytest.approx(B_ROLL, rel=0.03)
    assert f.implied_inertia == pytest.approx(I_ROLL, rel=0.01)
    assert f.period == pytest.approx(2 * np.pi / (np.sqrt(K_ROLL / I_ROLL) * np.sqrt(1 - ZETA**2)), rel=0.005)


def test_output_error_decay1_matches_curve_fit(surge_decay):
    oe = fit_output_error(Decay1(m=M_SURGE, D=50.0), [surge_decay], options=OutputErrorOptions(estimate_x0=("velocity",)))
    assert oe.converged
    assert oe.params["D"] == pytest.approx(D_SURGE, rel=0.02)
    cf = fit_first_order_decay(surge_decay.time, surge_decay["velocity"], M_SURGE)
    # the same least-squares problem: the two estimates agree to well within their uncertainty
    assert abs(oe.params["D"] - cf.damping) < 0.1 * cf.damping_stderr + 1e-6 * D_SURGE


def test_output_error_decay2_beats_equation_error(roll_decay):
    """Output error recovers b within 3 %; the equation-error regression on twice-differentiated noisy
    angles is biased low by more (filter attenuation of φ̈)."""
    start = Decay2(I=I_ROLL, k=K_ROLL, b=0.5)
    oe = fit_output_error(start, [roll_decay])
    assert oe.converged
    assert oe.params["b"] == pytest.approx(B_ROLL, rel=0.03)
    ee = fit_equation_error(start, [roll_decay])
    assert abs(ee.params["b"] / B_ROLL - 1) > abs(oe.params["b"] / B_ROLL - 1)


# -- from the command line, without an input column, standard errors of the physical parameters --
def _csv(tmp_path, run, name, columns):
    p = tmp_path / f"{name}.csv"
    run.to_dataframe()[["time", *columns]].to_csv(p, index=False)
    return str(p)


def test_cli_decay_without_input_column_and_without_m(surge_decay, tmp_path, capsys):
    """A free-decay file with only time and velocity: no zero ``tau`` column by hand; without ``--fix m``
    the fit stops at once naming m (the rate alone is not the damping)."""
    from diffship.fit.cli import main

    path = _csv(tmp_path, surge_decay, "surge", ["velocity"])
    assert main([path, "--model", "decay1", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "needs the vessel's particulars" in err and "m (total inertia" in err
    js = tmp_path / "d.json"
    code = main([path, "--model", "decay1", "--fix", f"m={M_SURGE}", "--init", "D=50", "--method", "output-error",
                 "--json", str(js)])
    out = capsys.readouterr()
    assert code == 0, out.err
    assert "input tau absent from surge: taken as 0" in out.err
    import json

    d = json.loads(js.read_text())["methods"]["output_error"]
    assert d["params"]["D"] == pytest.approx(D_SURGE, rel=0.02)
    assert abs(d["params"]["D"] - D_SURGE) < 3 * d["stderr"]["D"]
    assert "m          = 1200" in out.out and "--fix" in out.out  # the fixed inertia is listed beside the fit


def test_cli_curve_fit_reports_physical_parameters_with_standard_errors(roll_decay, surge_decay, tmp_path, capsys):
    """``python -m diffship.decay``: the direct curve fits from files, damping (and the inertia implied by k and
    the period) with standard errors that contain the truth; without the inertia it stops with one line."""
    import re

    from diffship.decay import main

    path = _csv(tmp_path, roll_decay, "roll", ["angle"])
    code = main([path, "--model", "decay2", "--fix", f"I={I_ROLL}", f"k={K_ROLL}", "--out", str(tmp_path / "out")])
    out = capsys.readouterr().out
    assert code == 0
    b, se = (float(x) for x in re.search(r"b = 2ζω_n·I = (\S+) ± (\S+)", out).groups())
    assert b == pytest.approx(B_ROLL, rel=0.03) and abs(b - B_ROLL) < 3 * se
    ii, ise = (float(x) for x in re.search(r"k/ω_n² = (\S+) ± (\S+)", out).groups())
    assert ii == pytest.approx(I_ROLL, rel=0.01) and abs(ii - I_ROLL) < 3 * ise
    assert (tmp_path / "out" / "decay.png").stat().st_size > 5_000
    surge = _csv(tmp_path, surge_decay, "surge", ["velocity"])
    assert main([surge, "--model", "decay1"]) == 2
    assert capsys.readouterr().err.startswith("error: model decay1 needs --fix m=VALUE")
    assert main([surge, "--model", "decay1", "--fix", f"m={M_SURGE}"]) == 0
    D, Dse = (float(x) for x in re.search(r"D = rate·m = (\S+) ± ([^\s,]+)", capsys.readouterr().out).groups())
    assert D == pytest.approx(D_SURGE, rel=0.02) and abs(D - D_SURGE) < 3 * Dse


def test_second_order_standard_errors_are_honest():
    """Over 40 noise seeds the delta-method standard errors of b (from I and from k) and of the implied
    inertia cover the truth at about the nominal rate: |error| < 2 SE in at least 85 % of the seeds."""
    t = np.arange(0.0, 20.0, 0.05)
    wn, zeta = np.sqrt(K_ROLL / I_ROLL), ZETA
    wd = wn * np.sqrt(1 - zeta**2)
    clean = 0.3 * np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta * wn / wd * np.sin(wd * t))
    hits = {"bI": 0, "bk": 0, "I": 0}
    rng = np.random.default_rng(5)
    for _ in range(40):
        f = fit_second_order_decay(t, clean + rng.normal(0, 0.005, t.size), inertia=I_ROLL, stiffness=K_ROLL)
        hits["bI"] += abs(f.damping_from_inertia - B_ROLL) < 2 * f.damping_from_inertia_stderr
        hits["bk"] += abs(f.damping_from_stiffness - B_ROLL) < 2 * f.damping_from_stiffness_stderr
        hits["I"] += abs(f.implied_inertia - I_ROLL) < 2 * f.implied_inertia_stderr
    assert min(hits.values()) >= 34, hits
