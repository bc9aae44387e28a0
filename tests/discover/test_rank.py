"""The ranking bootstrap (inclusion probabilities) and the output-error screen's forward path, on small
synthetic problems whose answer is known."""

import numpy as np

from diffship.discover.oescreen import forward_path
from diffship.discover.rank import selection_frequency


def _res(e):
    return {"r": [e[:500], e[500:]], "psi": [0.5 * e[:500], 0.5 * e[500:]]}


def test_selection_frequency_rewards_only_a_real_improvement():
    rng = np.random.default_rng(0)
    e0 = rng.normal(size=1000)
    tiny = 0.999 * e0  # one more parameter, RSS 0.2 % lower: BIC's penalty outweighs it
    real = 0.8 * e0  # RSS 36 % lower
    n_eff = {"r": 1000.0, "psi": 1000.0}
    f = selection_frequency([_res(e0), _res(tiny)], n_eff, [3, 4], [0, 1], n_boot=100, block=20)
    assert f[0] == 1.0 and f.sum() == 1.0
    f = selection_frequency([_res(e0), _res(tiny), _res(real)], n_eff, [3, 4, 4], [0, 1, 1], n_boot=100, block=20)
    assert f[2] == 1.0


def test_selection_frequency_splits_when_the_evidence_is_marginal():
    rng = np.random.default_rng(1)
    e0 = rng.normal(size=1000)
    # the candidate's improvement is concentrated in a few blocks: resamples disagree
    e1 = e0.copy()
    e1[:100] *= 0.98  # RSS 0.4 % lower: its gain (2·1000·0.004 ≈ 8) is about the penalty ln 2000 ≈ 7.6
    n_eff = {"r": 1000.0, "psi": 1000.0}
    f = selection_frequency([_res(e0), _res(e1)], n_eff, [3, 4], [0, 1], n_boot=200, block=20, seed=3)
    assert 0.1 < f[1] < 0.9


def test_forward_path_finds_the_column_beyond_the_base_span():
    rng = np.random.default_rng(2)
    m = 400
    J = rng.normal(size=(m, 3))
    G = rng.normal(size=(m, 5))
    G[:, 4] = J @ np.array([1.0, -2.0, 0.5])  # a term the base parameters mimic exactly
    r0 = -(3.0 * G[:, 2] + 0.5 * G[:, 0] + J @ np.array([0.3, 0.0, 0.0])) + 0.1 * rng.normal(size=m)
    order, T, frac, delta = forward_path(r0, J, G, 3, 0.01, 1.0)
    assert order[:2] == [2, 0] and 4 not in order[:2]
    assert T[0] > T[1] > 100 > T[2]
    assert abs(delta[0] - 3.0) < 0.05 and abs(delta[1] - 0.5) < 0.05
