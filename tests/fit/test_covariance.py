"""The one covariance: rank-deficient directions give infinite standard errors, never zeros."""

import numpy as np

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
