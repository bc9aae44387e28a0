"""The Hausman test that decides whether measured positions join the output-error fit (diffship.fit.positions).

The property tests use a linear Gaussian model where the answer is known: y = Xθ + e observed on two channels, the
"default" fit uses the first channel, the "positions" fit both. Where the second channel follows the same θ, the test
keeps it about 1 − α of the time; where the second channel is biased (a drift the model does not have), it rejects.
"""

import math

import numpy as np
import pytest

from diffship.fit.positions import ALPHA, MAX_WIDENING, SCREEN, PositionsTest, hausman, misfit


def _fits(rng, n=200, bias=0.0, sigma=(1.0, 0.7)):
    """Weighted least squares of y = Xθ + e on channel 1 alone, and on channels 1 and 2 (channel 2 shifted by
    ``bias``·t: a drift the linear model lacks)."""
    theta = np.array([1.0, -0.5, 0.25])
    t = np.linspace(0.0, 1.0, n)
    X1 = np.column_stack([np.ones(n), t, np.sin(6 * t)])
    X2 = np.column_stack([np.ones(n), t ** 2, np.cos(4 * t)])
    y1 = X1 @ theta + sigma[0] * rng.standard_normal(n)
    y2 = X2 @ theta + bias * t + sigma[1] * rng.standard_normal(n)
    A1 = X1 / sigma[0]
    A = np.vstack([A1, X2 / sigma[1]])
    b = np.concatenate([y1 / sigma[0], y2 / sigma[1]])
    Vd, Vp = np.linalg.inv(A1.T @ A1), np.linalg.inv(A.T @ A)
    return Vd @ A1.T @ (y1 / sigma[0]), Vd, Vp @ A.T @ b, Vp


def test_keeps_consistent_positions_at_the_stated_level():
    rng = np.random.default_rng(0)
    tests = [hausman(["a", "b", "c"], *_fits(rng)) for _ in range(400)]
    kept = np.mean([t.kept for t in tests])
    assert all(t.dof == 3 for t in tests)
    # 400 draws: the rejection rate's standard error is 1.1 %
    assert abs((1 - kept) - ALPHA) < 0.035, kept
    # under H0 the statistic is chi-square with 3 degrees of freedom: mean 3
    assert abs(np.mean([t.statistic for t in tests]) - 3.0) < 0.4


def test_rejects_positions_that_drift_where_the_model_misses():
    rng = np.random.default_rng(1)
    tests = [hausman(["a", "b", "c"], *_fits(rng, bias=1.5)) for _ in range(100)]
    assert np.mean([not t.kept for t in tests]) > 0.95
    t = tests[0]
    assert "disagrees" in t.describe() and "--channels" in t.describe()
    assert t.worst is not None and t.worst[1] > 2


def test_positions_that_widen_an_interval_are_left_out():
    # the same estimate, but with the positions one combination (a + b) is twice as uncertain: they would cost
    # precision for nothing (the noise weighting has read their drift as noise)
    rng = np.random.default_rng(3)
    td, Vd, _, _ = _fits(rng)
    u = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    a = Vd @ u
    Vp = Vd + np.outer(a, a) / (u @ a)  # whitened by V_d: I + a unit rank one → variance ratio 2 along u
    t = hausman(["a", "b", "c"], td, Vd, td, Vp)
    assert t.widening == pytest.approx(2.0) and not t.kept and "more certain" in t.describe()
    # a little narrower in every other direction: the test runs, and the widening decides
    t = hausman(["a", "b", "c"], td, Vd, td, 0.9 * Vd + 0.5 * np.outer(a, a) / (u @ a))
    assert math.isfinite(t.statistic) and t.widening > MAX_WIDENING and not t.kept and "less certain" in t.describe()
    assert hausman(["a", "b", "c"], td, Vd, td, 0.9 * Vd).widening == pytest.approx(0.9)


def test_an_infinite_standard_error_is_said_not_tested():
    rng = np.random.default_rng(2)
    td, Vd, tp, Vp = _fits(rng)
    Vd = Vd.copy()
    Vd[0, 0] = math.inf
    t = hausman(["a", "b", "c"], td, Vd, tp, Vp)
    assert not t.kept and math.isnan(t.statistic) and "infinite" in t.describe()


def test_misfit_reads_the_noise_from_second_differences():
    # a smooth manoeuvre (a heading turning through 2π: unwrapped) plus white noise of 0.01: a fit that follows it to
    # the noise has a ratio near 1, one that misses it by 0.1 RMS near 10
    from diffship.data import Run

    rng = np.random.default_rng(4)
    t = np.arange(0.0, 120.0, 0.1)
    def noisy(y):
        return y + 0.01 * rng.standard_normal(t.size)

    runs = [Run(f"r{i}", t, {"psi": np.angle(np.exp(1j * noisy(0.06 * t + 0.3 * np.sin(t / 7)))),
                             "u": noisy(2.0 + 0.2 * np.tanh(t - 60))}) for i in range(2)]
    r = misfit(runs, {"psi": 0.01, "u": 0.1}, angles=("psi",))
    assert r["psi"] == pytest.approx(1.0, abs=0.1) and r["u"] == pytest.approx(10.0, rel=0.1)
    assert r["u"] > SCREEN > r["psi"]


def test_report_and_json_say_what_was_decided():
    t = PositionsTest(("x0", "y0"), True, statistic=6.4, dof=10, p_value=0.78, worst=("Nr", 1.0), widening=0.97)
    assert "fitted" in t.describe() and "p = 0.78" in t.describe() and "--positions off" in t.describe()
    js = t.as_json()
    assert js["kept"] is True and js["dof"] == 10 and js["worst"] == {"param": "Nr", "se": 1.0}


@pytest.mark.parametrize("bad", ["always", ""])
def test_output_error_rejects_an_unknown_positions_rule(bad):
    from diffship.errors import FitError
    from diffship.fit import OutputError

    with pytest.raises(FitError, match="positions must be"):
        OutputError(positions=bad)


# -- the fit: the refit with positions kept where the model is right, left out where it misses ------------------------


@pytest.fixture(scope="module")
def usv_two_runs():
    from diffship.synthetic import usv_runs

    return usv_runs(2, 60.0, 0.1, noise="realistic", seed=5)


def _fit(runs, **kw):
    from diffship.fit import OutputError, fit
    from diffship.models import Fossen3

    return fit(Fossen3(), runs, OutputError(reference_priors=False, **kw), n_starts=1)


def test_the_default_fit_adds_positions_that_agree(usv_two_runs):
    from diffship.synthetic import usv_truth

    tv = usv_truth().param_values()
    res = _fit(usv_two_runs)
    assert res.converged, res.status
    assert {"x0", "y0"} <= set(res.channels)
    test = res.info["positions_test"]
    assert test["kept"] and test["p_value"] >= ALPHA and test["dof"] >= 1
    assert any(m.startswith("positions (x0, y0) fitted") for m in res.messages)
    z = {n: (res.params[n] - tv[n]) / res.stderr[n] for n in res.free}
    assert max(map(abs, z.values())) < 3.5, z
    # the positions narrow the intervals: every standard error at most that of the fit without them
    without = res.info["without_positions"]["stderr"]
    assert all(res.stderr[n] <= without[n] * 1.02 for n in res.free), (res.stderr, without)
    # the JSON report carries the test
    from diffship.report import to_json_dict

    doc = to_json_dict("fossen3", {"output_error": res}, {}, {})
    assert doc["methods"]["output_error"]["positions_test"]["kept"] is True


def test_positions_that_drift_where_the_model_misses_are_left_out(usv_two_runs):
    from diffship.data import Run

    # a 0.15 m/s water drift north-east seen only in the GNSS track (the model has no current): 9 m over a run
    drifted = [Run(r.name, r.time, {**r.channels, "x0": r["x0"] + 0.15 * (r.time - r.time[0]),
                                    "y0": r["y0"] + 0.15 * (r.time - r.time[0])}) for r in usv_two_runs]
    res = _fit(drifted)
    assert res.converged, res.status
    assert "x0" not in res.channels and "y0" not in res.channels
    test = res.info["positions_test"]
    # the noise weighting reads the drift as noise: the estimate hardly moves, the intervals would widen
    assert not test["kept"] and (test["p_value"] < ALPHA or test["widening"] > MAX_WIDENING), test
    assert any("not fitted" in m and "Hausman" in m for m in res.messages)


def test_positions_off_fits_without_them(usv_two_runs):
    res = _fit(usv_two_runs, positions="off")
    assert "x0" not in res.channels and "positions_test" not in res.info
    assert any(m.startswith("channels: x0, y0 in every run but not fitted") for m in res.messages)


def test_a_fit_that_misses_its_own_channels_is_not_refitted(usv_two_runs):
    from diffship.data import Run

    # an unmodelled yaw-rate oscillation (0.03 rad/s, 20 s), about eight times the gyro's noise: the model cannot
    # follow it, so the positions (which integrate such misses) are not tried
    shaken = [Run(r.name, r.time, {**r.channels, "r": r["r"] + 0.03 * np.sin(2 * np.pi * r.time / 20.0)})
              for r in usv_two_runs]
    res = _fit(shaken)
    test = res.info["positions_test"]
    assert not test["kept"] and math.isnan(test["statistic"]) and test["misfit"]["r"] > SCREEN, test
    assert "x0" not in res.channels and any("misses its own channels (r:" in m for m in res.messages)
