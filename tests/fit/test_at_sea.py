"""An autopilot in narrow-band waves (independent truth, benchmarks/independent/autopilot_waves.py): prediction
error with the wave disturbance recovers the dynamics and the wave; the output-error fit's errors show the loop
closed; the k-step-ahead predictions of the filter gain from the wave model."""

import sys
from pathlib import Path

import numpy as np
import pytest

from diffship.data import Run
from diffship.fit import fit_output_error, fit_prediction_error
from diffship.fit.ahead import ahead
from diffship.fit.feedback import loop_evidence
from diffship.fit.prediction_error import PredictionErrorOptions
from diffship.metrics import evaluate
from diffship.models import Nomoto1

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from benchmarks.independent.autopilot_waves import autopilot_runs  # noqa: E402


@pytest.fixture(scope="module")
def sea():
    g = autopilot_runs(1, n_runs=3, duration=500.0)
    runs = [Run(x["name"], x["time"], x["channels"], {"source": "independent"}) for x in g]
    return runs[:2], runs[2:], g[0]["truth"]


@pytest.fixture(scope="module")
def wave_fit(sea):
    return fit_prediction_error(Nomoto1(), sea[0], channels=("psi", "r"), noise=PredictionErrorOptions(disturbance="wave"))


def test_prediction_error_with_the_wave_recovers_the_dynamics_and_the_wave(sea, wave_fit):
    tv, res = sea[2], wave_fit
    for n in ("K", "T1"):
        assert abs(res.params[n] - tv[n]) < 3 * res.stderr[n], (n, res.params[n], res.stderr[n])
    assert abs(res.info["wave_period"] / tv["wave_period"] - 1) < 0.1
    assert abs(res.info["process_sd"]["r"] / tv["wave_sd"] - 1) < 0.3
    assert "narrow-band wave" in " ".join(res.messages)


def test_output_error_on_autopilot_data_says_the_loop_is_closed(sea):
    train, _, _ = sea
    res = fit_output_error(Nomoto1(), train, channels=("psi", "r"))
    ev = evaluate(res.model, train, channels=("psi", "r"), fitted=res.channels, scales=res.channel_scales)
    loop = loop_evidence(res.model, train, ev.simulated, ("psi", "r"))
    assert loop["closed"] and "biased" in loop["text"]
    assert any(t["input"] == "delta" and t["closed"] for t in loop["tests"])


def test_the_wave_model_predicts_the_held_out_run_better_one_sample_ahead(sea, wave_fit):
    res, val = wave_fit, sea[1]
    with_w, without = ahead(res, val, None, True), ahead(res, val, None, False)
    assert with_w.rmse["r"] < 0.8 * without.rmse["r"]
    # one sample ahead, the yaw-rate error is close to the rate gyro's noise (0.05 °/s) plus one sample of wave
    assert with_w.rmse["r"] < 3 * np.deg2rad(0.05)
    assert with_w.horizon.startswith("one-sample-ahead")
