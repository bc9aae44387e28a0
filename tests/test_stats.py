"""Goodness-of-fit statistics, bootstrap intervals and input time-delay estimation (seed 002)."""

import numpy as np
import pytest

from diffship import stats
from diffship.decay import decay_run
from diffship.errors import DataError, FitError
from diffship.fit import fit_equation_error
from diffship.models import Decay1, Nomoto1
from diffship.preprocess import Filter
from diffship.fit.delay import delay_input, estimate_input_delay

rng = np.random.default_rng(3)


def _poly_data(n=200, sigma=0.3):
    x = np.linspace(-2, 2, n)
    y = 1.0 - 0.5 * x + 0.8 * x**2 + rng.normal(0, sigma, n)
    return x, y


def _polyfit(x, y, deg):
    return np.polyval(np.polyfit(x, y, deg), x)


def test_r2_and_adjusted_r2_by_hand():
    x, y = _poly_data()
    yhat = _polyfit(x, y, 2)
    rss, tss = np.sum((y - yhat) ** 2), np.sum((y - y.mean()) ** 2)
    assert stats.r2(y, yhat) == pytest.approx(1 - rss / tss)
    n, k = y.size, 2  # two regressors besides the intercept
    assert stats.adjusted_r2(y, yhat, k) == pytest.approx(1 - (rss / (n - k - 1)) / (tss / (n - 1)))
    assert stats.adjusted_r2(y, yhat, k) < stats.r2(y, yhat)
    assert stats.rmse(y, yhat) == pytest.approx(np.sqrt(rss / n))
    with pytest.raises(DataError):
        stats.adjusted_r2(y[:3], yhat[:3], 5)


def test_mallows_cp_selects_true_order_and_is_near_p():
    """Over polynomial degrees 0..6, Cp (σ̂² from the largest model) is smallest at the true degree 2,
    and for the true model Cp ≈ p (= 3 coefficients) within its sampling spread."""
    x, y = _poly_data(n=400)
    n = y.size
    full = _polyfit(x, y, 6)
    sigma2 = np.sum((y - full) ** 2) / (n - 7)
    cps = [stats.mallows_cp(y, _polyfit(x, y, d), d + 1, sigma2) for d in range(7)]
    cps_mse = [stats.mallows_cp(y, _polyfit(x, y, d), d + 1, sigma2, form="mse") for d in range(7)]
    assert int(np.argmin(cps)) == 2 and int(np.argmin(cps_mse)) == 2
    assert abs(cps[2] - 3) < 6  # E[Cp] = p; sd ≈ √(2(n−p)) σ-units / n … a few units here
    assert cps[1] > 50  # the underfitted line is heavily penalised
    gof = stats.goodness_of_fit(y, _polyfit(x, y, 2), 3, sigma2)
    assert gof["cp"] == pytest.approx(cps[2]) and gof["aic"] < stats.aic(y, _polyfit(x, y, 1), 2)


def test_bootstrap_mean_abs_ci_coverage():
    """Percentile interval of the mean |residual| covers σ√(2/π) in about 95 % of repeated datasets."""
    sigma, hits, reps = 0.5, 0, 120
    for k in range(reps):
        e = rng.normal(0, sigma, 150)
        mean, lo, hi = stats.bootstrap_mean_abs_ci(e, n_boot=800, seed=k)
        assert lo < mean < hi
        hits += lo <= sigma * np.sqrt(2 / np.pi) <= hi
    assert 0.88 <= hits / reps <= 0.99


def test_block_bootstrap_widens_interval_for_correlated_residuals():
    e = np.convolve(rng.normal(size=2000), np.ones(20) / 20, mode="same")  # strongly autocorrelated
    _, lo1, hi1 = stats.bootstrap_mean_abs_ci(e, n_boot=1000, block=1)
    _, lo2, hi2 = stats.bootstrap_mean_abs_ci(e, n_boot=1000, block=40)
    assert (hi2 - lo2) > 2 * (hi1 - lo1)


FIXED = Filter("butter", cutoff=0.5)  # 10 % of Nyquist at 10 Hz: the property below is about one filter


def test_bootstrap_equation_error_matches_monte_carlo_spread():
    """Vmapped exact-refit residual bootstrap for the (affine) decay regression m·u̇ + D·u = τ: its
    standard error is never falsely narrow (≥ 0.8×) and within 3× of the spread of D over 12 independent
    noise realisations (differentiated noise is anti-persistent, so block bootstraps err wide; see
    ``bootstrap_equation_error``), and longer blocks move it towards the Monte-Carlo value."""
    truth = Decay1(m=1200.0, D=150.0)
    estimates = []
    for seed in range(12):
        run = decay_run(truth, 30.0, 0.1, [2.0], noise=0.02, seed=seed)
        estimates.append(fit_equation_error(truth, [run], flt=FIXED).params["D"])
    mc_sd = float(np.std(estimates, ddof=1))
    run = decay_run(truth, 30.0, 0.1, [2.0], noise=0.02, seed=99)
    ee = fit_equation_error(truth, [run], flt=FIXED)
    boot = stats.bootstrap_equation_error(truth, [run], ee, n_boot=2000)
    assert boot.exact and boot.names == ("D",)
    assert 0.8 < boot.stderr["D"] / mc_sd < 3.0, (boot.stderr["D"], mc_sd)
    longer = stats.bootstrap_equation_error(truth, [run], ee, n_boot=2000, block=100)
    assert abs(np.log(longer.stderr["D"] / mc_sd)) < abs(np.log(boot.stderr["D"] / mc_sd))
    lo, hi = boot.ci["D"]
    assert lo < ee.params["D"] < hi


def test_bootstrap_refuses_nonlinear_residual():
    from diffship.synthetic import nomoto_runs

    runs = nomoto_runs(n_runs=1, duration=40.0, dt=0.2)
    model = Nomoto1(K=0.2, T1=8.0)
    ee = fit_equation_error(model, runs)
    with pytest.raises(FitError, match="not affine"):
        stats.bootstrap_equation_error(model, runs, ee, n_boot=10)


def test_input_delay_by_refit_and_xcorr():
    """The ship responds to the rudder 0.6 s after it is logged: the refit search (seed 002 §5.3.4)
    finds 0.6 s within one 0.1 s grid step (4 noisy zigzag-like runs; with 2 runs the noise moves the
    shallow minimum by up to 0.2 s); cross-correlation gives an upper bound (delay + lag)."""
    from diffship.synthetic import nomoto_runs

    true_delay = 0.6
    runs = nomoto_runs(Nomoto1(K=0.2, T1=8.0, delta0=0.0), n_runs=4, duration=60.0, dt=0.1, noise="realistic")
    # what was logged: the rudder 0.6 s *ahead* of what acted on the ship
    logged = [delay_input(r, "delta", -true_delay) for r in runs]
    est = estimate_input_delay(logged, "delta", model=Nomoto1(), max_delay=1.2, step=0.1)
    assert est.method == "refit"
    assert est.delay == pytest.approx(true_delay, abs=0.15)
    assert est.scores[int(round(true_delay / 0.1))] < est.scores[0]
    xc = estimate_input_delay(logged, "delta", "r", max_delay=5.0)
    assert xc.method == "xcorr" and xc.delay >= true_delay - 0.11
