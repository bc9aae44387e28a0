"""The disturbance processes of the prediction-error filter (diffship.fit.disturbance)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.linalg import solve_continuous_lyapunov

from diffship.fit import disturbance as dist


@pytest.mark.parametrize("kind, hyper", [("ou", (7.0, np.nan)), ("wave", (8.0, 0.08)), ("wave", (3.0, 0.5))])
def test_the_start_covariance_is_the_stationary_one_and_q_is_the_stationary_sd(kind, hyper):
    # A P + P Aᵀ + Q = 0 for the extra states' linear dynamics: its solution is extra_p0, and P[w, w] = q²
    q, h, n_q = jnp.array([0.3, 2.0]), jnp.asarray(hyper), 2
    n_w = dist.n_extra(kind, n_q)
    A = np.asarray(jax.jacfwd(lambda w: dist.extra_rates(kind, w, h, n_q))(jnp.zeros(n_w)))
    P = solve_continuous_lyapunov(A, -np.diag(np.asarray(dist.extra_noise(kind, q, h))))
    np.testing.assert_allclose(np.diag(P), np.asarray(dist.extra_p0(kind, q, h)), rtol=1e-10)
    np.testing.assert_allclose(np.diag(P)[:n_q], np.asarray(q) ** 2, rtol=1e-10)


def test_the_wave_resonates_at_its_period():
    h = jnp.array([8.0, 0.05])
    A = np.asarray(jax.jacfwd(lambda w: dist.extra_rates("wave", w, h, 1))(jnp.zeros(2)))
    lam = np.linalg.eigvals(A)
    assert abs(2 * np.pi / np.abs(lam[0]) - 8.0) < 1e-9  # natural period
    assert abs(-lam[0].real / np.abs(lam[0]) - 0.05) < 1e-9  # relative damping


def test_hyper_parameters_are_positive_and_clipped():
    h = np.asarray(dist.hyper_values("wave", jnp.array([0.0, 50.0]), jnp.array([8.0, 0.1])))
    assert h[0] == 8.0 and h[1] == pytest.approx(0.1 * np.exp(2.3))
    assert np.isnan(np.asarray(dist.hyper_values("white", jnp.zeros(0), jnp.array([np.nan, np.nan])))).all()


def test_spectral_period_finds_a_narrow_band_line_under_a_slow_steering_response():
    rng = np.random.default_rng(0)
    t = np.arange(0, 600, 0.5)
    runs = []
    for _ in range(3):
        slow = np.cumsum(rng.standard_normal(t.size)) * 0.05  # steering-like drift
        runs.append(np.stack([slow + 0.2 * np.sin(2 * np.pi * t / 9.0 + rng.uniform(0, 6)) + 0.05 * rng.standard_normal(t.size)], 1))
    assert dist.spectral_period(runs, 0.5) == pytest.approx(9.0, rel=0.03)
