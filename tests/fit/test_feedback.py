"""The closed-loop test (diffship.fit.feedback)."""

import numpy as np

from diffship.fit.feedback import SHARE_MIN, feedback_test


def _runs(closed: bool, seed: int = 0, n: int = 1500):
    rng = np.random.default_rng(seed)
    us, es = [], []
    for _ in range(3):
        u, e = np.zeros(n), np.zeros(n)
        d = np.convolve(rng.standard_normal(n), np.ones(8) / 8, "same")  # a coloured disturbance
        for k in range(1, n):
            # a wrong model: the error carries a filtered past input as well as the disturbance
            e[k] = 0.8 * e[k - 1] + 0.3 * u[k - 1] + d[k]
            u[k] = (0.9 * u[k - 1] + 0.3 * rng.standard_normal()) if not closed else (0.5 * u[k - 1] - 0.6 * e[k - 1]
                                                                                       + 0.1 * rng.standard_normal())
        us.append(u)
        es.append(e)
    return {"delta": us}, {"psi": es}


def test_an_input_that_reacts_to_past_errors_is_called_closed_loop():
    (t,) = feedback_test(*_runs(True), dt=0.5)
    assert t.closed and t.p_value < 1e-10 and t.partial_r2 > 0.2
    assert t.lags == 10 and t.lag_seconds == 5.0


def test_an_exogenous_input_is_open_loop_even_when_the_model_is_wrong():
    # the errors depend on past inputs (model error): the input's own past carries that, so no feedback is seen
    (t,) = feedback_test(*_runs(False), dt=0.5)
    assert not t.closed and t.partial_r2 < SHARE_MIN and t.p_value > 1e-3


def test_short_runs_and_a_constant_input_give_no_test():
    assert feedback_test({"delta": [np.zeros(5)]}, {"psi": [np.zeros(5)]}, dt=0.5) == []
    assert feedback_test({"delta": [np.ones(500)]}, {"psi": [np.random.default_rng(1).standard_normal(500)]}, dt=0.5) == []
