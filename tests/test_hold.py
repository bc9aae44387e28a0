"""A held input on a new time grid (:mod:`diffship.hold`) and ``Run.resample`` of held inputs."""

import numpy as np
import pytest

from diffship.data import Run
from diffship.hold import held_means


def test_held_means_carry_the_held_signals_impulse_over_each_new_interval():
    t = np.arange(0.0, 2.0, 0.1)
    u = (t >= 0.5).astype(float)  # a command stepped at 0.5 s, held between samples
    grid = np.array([0.0, 0.25, 0.45, 0.7, 1.9])
    means = held_means(t, u, grid, 2.0)
    # [0, 0.25): 0; [0.25, 0.45): 0; [0.45, 0.7): 0.2 of 0.25 after the step; [0.7, 1.9): 1; [1.9, 2.0): 1
    assert means == pytest.approx([0.0, 0.0, 0.8, 1.0, 1.0])
    # the same impulse as the held signal over the grid's span
    assert np.sum(means[:-1] * np.diff(grid)) == pytest.approx(np.sum(u[(t >= 0.0) & (t < 1.9)] * 0.1))


def test_resampling_a_held_command_keeps_its_timing_and_other_channels_interpolate():
    dt = 0.05
    t = np.arange(0.0, 20.0, dt)
    cmd = np.where(t >= 1.0, 1.0, 0.0)
    run = Run("r", t, {"psi": 0.01 * t, "r": np.full(t.size, 0.01), "n": cmd})
    held, linear = run.resample(0.3, held=("n",)), run.resample(0.3)
    i = int(np.searchsorted(held.time, 1.0)) - 1  # the interval [0.9, 1.2) holds the step for 0.2 of its 0.3 s
    assert held.time[i] == pytest.approx(0.9)
    assert held["n"][i] == pytest.approx(2 / 3) and linear["n"][i] == pytest.approx(0.0)
    assert np.array_equal(held["psi"], linear["psi"])
    assert np.array_equal(run["n"], cmd)  # the run given is not changed
