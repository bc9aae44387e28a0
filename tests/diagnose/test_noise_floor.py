"""The noise floor holds for coloured noise: filtered/AR(1) sensor noise is not
under-estimated by the second-difference (white-noise) estimator, and the estimate says which
method it used."""

import numpy as np
import pytest

import diffship  # noqa: F401
from diffship.data import Run
from diffship.diagnose.where import COLOURED, WHITE, noise_estimates, noise_floor


def _ar1(rng, phi, sigma, n):
    e = rng.normal(0.0, sigma * np.sqrt(1 - phi ** 2), n)
    x = np.empty(n)
    x[0] = rng.normal(0.0, sigma)
    for i in range(1, n):
        x[i] = phi * x[i - 1] + e[i]
    return x


def _runs(phi, seed=0):
    """Smooth manoeuvre-like signals (periods 20–30 s) at 10 Hz plus AR(1) noise of known σ."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 60.0, 0.1)
    return [Run(f"r{i}", t, {"psi": 0.3 * np.sin(2 * np.pi * t / 30 + i) + _ar1(rng, phi, 0.005, t.size),
                             "r": 0.05 * np.sin(2 * np.pi * t / 20 + i) + _ar1(rng, phi, 0.003, t.size)})
            for i in range(4)]


@pytest.mark.parametrize("phi", [0.8, 0.9])
def test_coloured_noise_floor_is_the_noise_std(phi):
    est = noise_estimates(_runs(phi), ["psi", "r"])
    for c, sigma in (("psi", 0.005), ("r", 0.003)):
        assert est[c].sigma == pytest.approx(sigma, rel=0.3), (c, est[c])
        assert est[c].method == COLOURED
        assert est[c].rho == pytest.approx(phi, abs=0.1)
        # the white-noise estimator under-reads coloured noise by (6 − 8φ + 2φ²)/6 in variance
        assert est[c].white_sigma < 0.5 * sigma
    assert noise_floor(_runs(phi), ["psi", "r"])["r"] == pytest.approx(0.003, rel=0.3)


def test_white_noise_floor_unchanged():
    est = noise_estimates(_runs(0.0), ["psi", "r"])
    for c, sigma in (("psi", 0.005), ("r", 0.003)):
        assert est[c].method == WHITE
        assert est[c].sigma == pytest.approx(sigma, rel=0.1)
        assert est[c].sigma == est[c].white_sigma
