"""The one covariance: rank-deficient directions give infinite standard errors, never zeros."""

import numpy as np
import pytest

from diffship.fit.covariance import covariance, relabelled


def test_full_rank_matches_the_normal_equations():
    rng = np.random.default_rng(0)
    J = rng.normal(size=(200, 3))
    r = rng.normal(size=200)
    c = covariance(J, r)
    s2 = r @ r / 197
    np.testing.assert_allclose(c.matrix, s2 * np.linalg.inv(J.T @ J), rtol=1e-10)
    assert c.full_rank and c.rank == 3


def test_a_parameter_without_influence_has_an_infinite_standard_error():
    """A column of zeros (a parameter the residuals do not depend on) must not get σ = 0 as a
    pseudo-inverse would give; a pair of identical columns makes both unidentifiable."""
    rng = np.random.default_rng(1)
    J = rng.normal(size=(100, 4))
    J[:, 2] = 0.0
    c = covariance(J, rng.normal(size=100))
    assert np.isinf(c.matrix[2, 2]) and c.unidentifiable == (2,)
    assert np.all(np.isfinite(np.diag(c.matrix)[[0, 1, 3]]))
    J[:, 2] = J[:, 1]
    c = covariance(J, rng.normal(size=100))
    assert set(c.unidentifiable) == {1, 2} and np.isinf(c.matrix[1, 1]) and np.isinf(c.matrix[2, 2])


def test_relabelled_swaps_rows_and_columns():
    cov = np.array([[1.0, 0.1], [0.1, 4.0]])
    out = relabelled(cov, {"T1": 1.0, "T2": 5.0}, {"T1": 5.0, "T2": 1.0}, ("T1", "T2"))
    np.testing.assert_array_equal(out, [[4.0, 0.1], [0.1, 1.0]])


# -- coloured residuals: the sandwich (HAC) against a known answer -------------------------------
def _ar1(rng, n, phi, sigma_e=1.0):
    e = rng.normal(0.0, sigma_e, n)
    u = np.empty(n)
    u[0] = e[0] / np.sqrt(1 - phi**2)
    for k in range(1, n):
        u[k] = phi * u[k - 1] + e[k]
    return u


def _regression(n=2000):
    t = np.arange(n) / n
    return np.stack([np.ones(n), np.sin(2 * np.pi * 3 * t), t - 0.5], 1)


def _true_cov(X, phi, sigma_e=1.0):
    """Exact Cov(β̂_OLS) = (XᵀX)⁻¹ XᵀΣX (XᵀX)⁻¹ with Σ_ij = σ²/(1−φ²)·φ^|i−j| (AR(1))."""
    n = X.shape[0]
    k = np.arange(n)
    S = sigma_e**2 / (1 - phi**2) * phi ** np.abs(k[:, None] - k[None, :])
    A = np.linalg.inv(X.T @ X)
    return A @ X.T @ S @ X @ A


def test_hac_matches_the_closed_form_variance_under_ar1_noise():
    """OLS with AR(1) noise (φ = 0.8): the white σ̂²(XᵀX)⁻¹ understates the intercept's variance
    by about (1+φ)/(1−φ) = 9; HAC recovers the exact variance within 30 % (mean over 8 seeds), and
    the residuals are flagged coloured so that ``auto`` picks HAC."""
    X = _regression()
    phi = 0.8
    true = np.sqrt(np.diag(_true_cov(X, phi)))
    ratios_hac, ratios_white = [], []
    for seed in range(8):
        rng = np.random.default_rng(seed)
        y = X @ np.array([1.0, 0.5, -2.0]) + _ar1(rng, X.shape[0], phi)
        beta = np.linalg.lstsq(X, y, rcond=None)[0]
        r = X @ beta - y
        mask = np.ones((1, X.shape[0]), bool)
        hac = covariance(X, r, kind="auto", mask=mask)
        white = covariance(X, r)
        assert hac.kind == "hac" and not hac.whiteness.white and hac.whiteness.lag1[0, 0] > 0.7
        ratios_hac.append(np.sqrt(np.diag(hac.matrix)) / true)
        ratios_white.append(np.sqrt(np.diag(white.matrix)) / true)
    ratios_hac, ratios_white = np.mean(ratios_hac, 0), np.mean(ratios_white, 0)
    np.testing.assert_allclose(ratios_hac, 1.0, atol=0.3)
    assert ratios_white[0] < 0.45  # white: about 1/3 of the true standard error of the intercept


def test_hac_95_percent_intervals_cover_and_white_ones_do_not():
    """100 seeds of the regression above with AR(1) noise in 4 independent runs: HAC intervals cover
    the truth 88–99 % of the time, white ones far less; on white noise ``auto`` stays white."""
    X1 = _regression(500)
    X = np.concatenate([X1] * 4)
    beta0 = np.array([1.0, 0.5, -2.0])
    mask = np.ones((4, 500), bool)
    cover = {"hac": [], "white": [], "block": []}
    for seed in range(100):
        rng = np.random.default_rng(100 + seed)
        y = X @ beta0 + np.concatenate([_ar1(rng, 500, 0.6) for _ in range(4)])
        beta = np.linalg.lstsq(X, y, rcond=None)[0]
        r = X @ beta - y
        for kind in cover:
            c = covariance(X, r, kind=kind, mask=mask, n_boot=300, seed=seed)
            cover[kind].append(np.abs(beta - beta0) <= 1.96 * np.sqrt(np.diag(c.matrix)))
    rate = {k: float(np.mean(v)) for k, v in cover.items()}
    assert 0.88 <= rate["hac"] <= 0.99, rate
    assert 0.85 <= rate["block"] <= 0.99, rate
    assert rate["white"] < 0.8, rate
    rng = np.random.default_rng(5)
    r = rng.normal(size=2000)
    c = covariance(X, r, kind="auto", mask=mask)
    assert c.kind == "white" and c.whiteness.white


def test_hac_is_the_same_at_every_sample_rate():
    """One experiment logged at two rates: OLS with noise of correlation time 2 s over 100 s, at 10 Hz
    (AR(1) φ = 0.95) and at 50 Hz (φ = 0.99, beyond the prewhitening cap of 0.97). The exact standard errors are
    equal; HAC recovers both within 30 % (mean over 8 seeds). Without summing the score over blocks the 50-Hz
    one was a quarter of the truth (the cap cannot recolour an AR(1) of φ = 0.99)."""
    ratios = {}
    for hz in (10, 50):
        n = 100 * hz
        phi = float(np.exp(-1.0 / (2.0 * hz)))
        X = _regression(n)
        true = np.sqrt(np.diag(_true_cov(X, phi, np.sqrt(1 - phi**2))))
        got = []
        for seed in range(8):
            rng = np.random.default_rng(300 + seed)
            y = X @ np.array([1.0, 0.5, -2.0]) + _ar1(rng, n, phi, np.sqrt(1 - phi**2))
            beta = np.linalg.lstsq(X, y, rcond=None)[0]
            c = covariance(X, X @ beta - y, kind="hac", mask=np.ones((1, n), bool))
            got.append(np.sqrt(np.diag(c.matrix)) / true)
        ratios[hz] = np.mean(got, 0)
    np.testing.assert_allclose(ratios[10], 1.0, atol=0.3)
    np.testing.assert_allclose(ratios[50], 1.0, atol=0.3)
    np.testing.assert_allclose(ratios[50], ratios[10], rtol=0.3)


def test_rank_deficiency_stays_infinite_with_the_sandwich():
    rng = np.random.default_rng(1)
    J = rng.normal(size=(300, 3))
    J[:, 2] = 0.0
    r = _ar1(rng, 300, 0.9)
    c = covariance(J, r, kind="hac", mask=np.ones((1, 300), bool))
    assert c.kind == "hac" and np.isinf(c.matrix[2, 2]) and c.unidentifiable == (2,)
    assert np.all(np.isfinite(np.diag(c.matrix)[:2])) and np.all(np.diag(c.matrix)[:2] > 0)


def test_input_noise_levels_from_second_differences():
    """A rate-limited rudder (zero second differences except at its corners) with 0.08° white noise,
    and two jet forces computed from one noisy thrust (perfectly anti-correlated noise): the noise
    covariance of the measured inputs is recovered within 10 %; a noise-free input gives zero."""
    from diffship.fit.input_noise import input_noise_levels

    rng = np.random.default_rng(3)
    t = np.arange(0.0, 300.0, 0.1)
    target = 0.35 * np.sign(np.sin(2 * np.pi * t / 40.0))
    rudder = np.zeros_like(t)
    for k in range(1, t.size):
        rudder[k] = rudder[k - 1] + np.clip(target[k] - rudder[k - 1], -0.004, 0.004)
    sd = 0.08 * np.pi / 180
    thrust_noise = rng.normal(0.0, 5.0, t.size)
    us = np.stack([rudder + rng.normal(0.0, sd, t.size), 200.0 + thrust_noise, -3.82 * (200.0 + thrust_noise),
                   rudder], 1)[None]
    cov = input_noise_levels(us, np.ones((1, t.size), bool))
    np.testing.assert_allclose(np.sqrt(np.diag(cov))[:3], [sd, 5.0, 3.82 * 5.0], rtol=0.1)
    assert cov[1, 2] / np.sqrt(cov[1, 1] * cov[2, 2]) < -0.95
    assert cov[3, 3] == 0.0


def test_output_error_propagates_measured_rudder_noise():
    """Nomoto runs whose logged rudder angle carries 0.1° white noise: the output-error result says
    which covariance it used, the rudder noise it estimated (within 20 %) and the whiteness; on the
    same runs with the exact rudder no input noise is propagated and the intervals are narrower."""
    from diffship.data import Run
    from diffship.fit import fit_output_error
    from diffship.models import Nomoto1
    from diffship.synthetic import nomoto_runs

    truth = Nomoto1(K=0.2, T1=8.0, delta0=0.01)
    runs = nomoto_runs(truth, n_runs=2, duration=120.0, dt=0.1, noise="realistic", seed=1)
    rng = np.random.default_rng(0)
    sd = 0.1 * np.pi / 180
    noisy = [Run(r.name, r.time, {**{c: r[c] for c in ("psi", "r")}, "delta": r["delta"] + rng.normal(0, sd, r.time.size)},
                 {}) for r in runs]
    exact = fit_output_error(Nomoto1(), runs)
    res = fit_output_error(Nomoto1(), noisy)
    assert exact.info["input_noise"] == {} and not exact.info["covariance"].endswith("+inputs")
    assert res.info["covariance"].endswith("+inputs")
    assert res.info["input_noise"]["delta"] == pytest.approx(sd, rel=0.2)
    assert "white" in res.info["whiteness"] and any(m.startswith("covariance:") for m in res.messages)
    assert res.stderr["K"] > exact.stderr["K"]


def test_predictability_is_near_zero_for_white_residuals_and_high_for_an_oscillation():
    """The share of the residuals' variance their own past predicts (AR(4) per run and channel, pooled): about
    4/N for white noise, and that of a lightly damped oscillation (an AR(2) with poles at radius 0.95 and a period
    of 8 samples, a yaw wave sampled slowly) is 1 - σ²/var(x) = 0.91."""
    from diffship.fit.covariance import predictability

    rng = np.random.default_rng(3)
    mask = np.ones((2, 600), bool)
    white = rng.standard_normal(2 * 600 * 2)
    assert predictability(white, mask, 2) < 0.03
    a1, a2 = 2 * 0.95 * np.cos(2 * np.pi / 8), -0.95 ** 2
    x = np.zeros((2, 600, 2))
    e = rng.standard_normal(x.shape)
    for k in range(2, 600):
        x[:, k] = a1 * x[:, k - 1] + a2 * x[:, k - 2] + e[:, k]
    # the AR(2)'s variance: σ²(1 - a2)/((1 + a2)((1 - a2)² - a1²))
    var = (1 - a2) / ((1 + a2) * ((1 - a2) ** 2 - a1 ** 2))
    assert predictability(x.reshape(-1), mask, 2) == pytest.approx(1 - 1 / var, abs=0.05)
    mask[1, 300:] = False  # padded samples are left out
    assert predictability(x.reshape(-1), mask, 2) == pytest.approx(1 - 1 / var, abs=0.05)
