"""Conditioning chosen from the data and the model (:mod:`diffship.fit.conditioning`)."""

import numpy as np

from diffship.data import Run
from diffship.fit.conditioning import block_average, fastest_time_constant, thinning
from diffship.models import Nomoto1, get_model
from diffship.vessel import load_vessel


def _run(dt, duration=60.0, seed=0):
    t = np.arange(0.0, duration, dt)
    rng = np.random.default_rng(seed)
    delta = np.radians(10.0) * np.sign(np.sin(2 * np.pi * t / 30.0))
    return Run("r", t, {"psi": 0.3 * np.sin(0.2 * t) + rng.normal(0, 0.01, t.size), "r": 0.06 * np.cos(0.2 * t),
                        "delta": delta, "u": np.full(t.size, 1.18), "v": np.zeros(t.size), "n": np.full(t.size, 10.2)})


def test_block_average_keeps_the_signal_and_lowers_the_noise_without_changing_the_run():
    run = _run(0.05)
    before = np.array(run["psi"])
    avg = block_average(run, 4)
    assert avg.n == run.n // 4 and np.allclose(np.diff(avg.time), 0.2)
    assert np.array_equal(run["psi"], before)  # the run given is not changed
    # the noise of a 4-sample mean is half the sample noise; the slow signal is kept
    assert np.std(np.diff(avg["psi"], 2)) < 0.7 * np.std(np.diff(run["psi"], 2))
    assert np.allclose(avg["r"], 0.06 * np.cos(0.2 * avg.time), atol=2e-4)


def test_a_known_vessel_logged_far_faster_than_its_dynamics_is_thinned_and_a_generic_model_is_not():
    mmg = get_model("mmg").with_vessel(load_vessel("kvlcc2_model"))
    runs = [_run(0.05)]
    T = fastest_time_constant(mmg, runs)
    assert 1.0 < T < 5.0, T  # the KVLCC2 model's sway-yaw mode at 1.18 m/s, about 2 s
    th = thinning(mmg, runs)
    assert th.factor == 4 and "20 Hz → 5 Hz" in th.text, th.text
    assert thinning(mmg, [_run(0.2)]).factor == 1  # already at the model's rate
    generic = thinning(Nomoto1(), runs, known=False)
    assert generic.factor == 1 and "not a known vessel's" in generic.text
