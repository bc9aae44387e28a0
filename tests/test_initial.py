"""The one initial-state rule (:mod:`diffship.initial`): sensor noise from the data, the prior of a run's
start, and the start estimated with the model held."""

import math

import numpy as np

from diffship.data import Run
from diffship.initial import channel_noise, correlation_time_of, estimate_starts, noise_floor, start_prior
from diffship.models import Nomoto1
from diffship.synthetic import nomoto_runs


def test_noise_floor_reads_white_noise_beside_a_smooth_manoeuvre():
    t = np.arange(0.0, 200.0, 0.1)
    clean = 0.3 * np.sin(0.2 * t) + np.where(t > 100, 0.05 * (t - 100), 0.0)  # a turn and a corner
    rng = np.random.default_rng(3)
    for sd in (0.001, 0.01):
        assert abs(noise_floor(clean + rng.normal(0, sd, t.size)) / sd - 1) < 0.08
    ys = np.stack([clean, clean], axis=-1)[None]
    assert np.all(channel_noise(ys, np.ones((1, t.size), bool)) > 0)  # noise-free: floored above zero


def test_the_prior_is_centred_on_the_raw_first_sample_with_the_sensor_noise():
    model = Nomoto1()
    ys = np.zeros((2, 100, 2))
    ys[:, 0, 0] = [0.01, -0.02]  # first heading samples
    x0 = np.zeros((2, 2))
    noise = np.array([0.005, 0.001])
    p = start_prior(model, ("psi", "r"), ys, np.ones((2, 100), bool), x0, ("psi", "r"), np.array([0.1, 0.01]), noise)
    assert np.allclose(p.mean[:, 0], [0.1, -0.2]) and np.allclose(p.mean[:, 1], 0.0)
    assert np.allclose(p.weight, [[20.0, 10.0], [20.0, 10.0]])
    free = start_prior(model, ("psi",), ys[..., :1], np.ones((2, 100), bool), x0, ("psi", "r"), np.array([0.1, 0.01]),
                       noise[:1])
    assert np.all(free.weight[:, 1] == 0) and math.isnan(free.sigma[1])  # r not measured: free
    assert "r unmeasured, free" in free.describe()


def test_the_true_model_recovers_the_start_and_a_wrong_one_cannot_buy_it_away():
    """Held-out rule: with the true model the estimated start is closer to the true one than the noisy first
    sample; a model with the wrong gain (twice the truth), whose residuals drift, stays within a few noise
    levels of the logged start instead of moving it to hide its error."""
    truth = Nomoto1(K=0.2, T1=8.0, delta0=0.01)
    runs = nomoto_runs(truth, n_runs=2, duration=60.0, dt=0.1, noise="realistic", seed=4)
    x_true = np.zeros(2)
    x = estimate_starts(truth, runs, ("psi", "r"))
    for run, xi in zip(runs, x):
        raw = np.array([run["psi"][0], run["r"][0]])
        assert np.linalg.norm((xi - x_true) / [0.5e-2, 0.2e-2]) < np.linalg.norm((raw - x_true) / [0.5e-2, 0.2e-2])
    wrong = truth.with_params({"K": 0.4})
    xw = estimate_starts(wrong, runs, ("psi", "r"))
    sig = np.radians([0.5, 0.2])
    for run, xi in zip(runs, xw):
        raw = np.array([run["psi"][0], run["r"][0]])
        assert np.all(np.abs(xi - raw) < 4 * sig), (xi - raw) / sig
    assert not np.shares_memory(runs[0]["psi"], x[0])


def test_a_run_is_never_changed_in_place():
    run = nomoto_runs(Nomoto1(K=0.2, T1=8.0), n_runs=1, duration=20.0, noise="realistic", seed=1)[0]
    before = {c: np.array(run[c]) for c in run.channel_names}
    estimate_starts(Nomoto1(K=0.2, T1=8.0), [run], ("psi", "r"))
    assert all(np.array_equal(before[c], run[c]) for c in before)
    assert isinstance(run, Run)


def test_run_sets_of_one_length_share_one_program_and_the_same_starts(monkeypatch):
    """The runs are independent problems: solved in chunks of two, the starts are those of one solve over every run
    (to the bit), and three runs, two runs or one of the same length ask for the same compiled program."""
    import diffship.initial as initial
    from diffship.compiled import _key

    model = Nomoto1(K=0.2, T1=8.0)
    runs = nomoto_runs(model, n_runs=3, duration=40.0, dt=0.1, noise="realistic", seed=2)
    chunked = estimate_starts(model, runs, ("psi", "r"))
    keys = {_key(*initial.start_request(model, runs[:k], ("psi", "r"))[0]) for k in (1, 2, 3)}
    assert len(keys) == 1
    monkeypatch.setattr(initial, "RUNS_PER_SOLVE", 3)  # one solve over the three runs
    whole = estimate_starts(model, runs, ("psi", "r"))
    assert np.array_equal(np.stack(chunked), np.stack(whole))
    assert not np.allclose(chunked[0], chunked[2])  # three different runs, three different starts


def test_correlation_time_is_the_integrated_autocorrelation_of_the_pooled_runs():
    """An AR(1) series x_t = φ x_{t-1} + e_t has the integrated autocorrelation time (1 + φ)/(1 − φ) samples (3 at
    φ = 0.5); white noise has 1. The FFT sum equals the lag-by-lag sums of its definition."""
    rng = np.random.default_rng(3)

    def ar1(n, phi):
        x, e = np.zeros(n), rng.normal(size=n)
        for t in range(1, n):
            x[t] = phi * x[t - 1] + e[t]
        return x

    runs = [ar1(20000, 0.5), ar1(15000, 0.5)]
    assert abs(correlation_time_of(runs) - 3.0) < 0.15
    assert correlation_time_of([rng.normal(size=20000)]) < 1.1
    short = [ar1(n, 0.8) for n in (400, 333)]
    K = min(400, 333 // 4)
    num = sum(np.array([(x - x.mean())[:-k] @ (x - x.mean())[k:] for k in range(1, K + 1)]) for x in short)
    rho = num / sum(float((x - x.mean()) @ (x - x.mean())) for x in short)
    neg = np.flatnonzero(rho < 0)
    direct = 1.0 + 2.0 * float(np.sum(rho[: neg[0]] if neg.size else rho))
    assert math.isclose(correlation_time_of(short), max(1.0, direct), rel_tol=1e-12)
