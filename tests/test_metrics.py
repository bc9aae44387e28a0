"""The initial-state rule of the metrics: the true model scores at the sensor noise."""

import numpy as np

from diffship.metrics import evaluate, start_state
from diffship.models import Nomoto1
from diffship.simulate import initial_state
from diffship.synthetic import NOISE, nomoto_runs


def test_true_model_scores_at_the_sensor_noise():
    """Six noisy runs of a known Nomoto model: simulated by the true model from the start estimated on the
    first 3 s, the heading RMSE is the heading noise (within 10 %); from the filtered first sample it was
    about four times the noise (the start error in r grows into a heading offset T·δr)."""
    truth = Nomoto1(K=0.2, T1=8.0, delta0=0.01)
    runs = nomoto_runs(truth, n_runs=6, duration=60.0, dt=0.1, noise="realistic", seed=1)
    sigma = NOISE["realistic"]["psi"]
    ev = evaluate(truth, runs)
    assert abs(ev.rmse["psi"] / sigma - 1.0) < 0.1, np.degrees(ev.rmse["psi"])
    old = evaluate(truth, runs, [initial_state(truth, r) for r in runs])
    assert old.rmse["psi"] > 1.5 * sigma  # the former rule (0.5° noise: 1.95°)
    x = start_state(truth, runs[0])
    assert x.shape == (len(truth.state_names),) and np.all(np.isfinite(x))
