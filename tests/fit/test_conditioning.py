"""Conditioning chosen from the data and the model (:mod:`diffship.fit.conditioning`)."""

import numpy as np
import pytest

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


def _lag(u, dt, T=1.5, K=2.0, y0=0.0):
    """A first-order lag ẏ = (K u − y)/T, exact under inputs held over each step of ``dt`` (one per sample)."""
    a = np.exp(-np.asarray(dt) / T)
    y = [y0]
    for i in range(len(u) - 1):
        y.append(a[i] * y[-1] + (1 - a[i]) * K * u[i])
    return np.array(y)


def test_held_inputs_are_averaged_over_the_interval_each_averaged_sample_holds_them():
    """A command held at 20 Hz and averaged to 5 Hz: under the zero-order hold the averaged command stands for the
    interval from its sample to the next (a step at 0.5 s fills 87.5 % of [0.475, 0.675)), not for its block (50 %),
    and a lag driven by the averaged command, held, follows the one driven at 20 Hz; from the block means it lags
    by (k − 1)/2 samples."""
    dt, k = 0.05, 4
    t = np.arange(0.0, 30.0, dt)
    rng = np.random.default_rng(1)
    step = (t >= 0.5).astype(float)
    cmd = np.repeat(rng.uniform(-1, 1, t.size // 10), 10)[:t.size]  # a set-point changed every 0.5 s
    run = Run("r", t, {"psi": np.zeros(t.size), "r": np.zeros(t.size), "delta": 0.1 * step, "n": cmd})
    held, blocks = block_average(run, k, ("delta", "n"), "zero"), block_average(run, k)
    assert held["delta"][2] == pytest.approx(0.1 * 0.875) and blocks["delta"][2] == pytest.approx(0.1 * 0.5)
    assert np.array_equal(held["psi"], blocks["psi"]) and np.array_equal(held.time, blocks.time)
    truth = np.interp(held.time, t, _lag(cmd, np.diff(t, append=t[-1] + dt)))
    y0 = truth[0]
    err_held = np.abs(_lag(held["n"], np.diff(held.time, append=held.time[-1] + k * dt), y0=y0) - truth).max()
    err_blocks = np.abs(_lag(blocks["n"], np.diff(blocks.time, append=blocks.time[-1] + k * dt), y0=y0) - truth).max()
    assert err_held < 0.3 * err_blocks, (err_held, err_blocks)
