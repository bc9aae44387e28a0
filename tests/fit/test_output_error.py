"""Output error: parameter recovery (noise-free and noisy), honesty of standard errors,
and the comparison with the equation-error baseline on the same data."""

import numpy as np
import pytest

from diffship.fit import fit_both, fit_equation_error, fit_output_error
from diffship.metrics import evaluate
from diffship.models import Fossen3, Nomoto1, Nomoto2
from diffship.preprocess import Filter
from diffship.synthetic import nomoto_runs, usv_runs, usv_truth

TRUTH = usv_truth()
TV = TRUTH.param_values()
FREE = Fossen3().spec().free_names


def _start_spec(factor_even=0.5, factor_odd=1.5):
    start = {n: TV[n] * (factor_odd if i % 2 else factor_even) for i, n in enumerate(FREE)}
    return Fossen3().spec().with_values(start)


def _rel(res, truth):
    return {n: abs(res.params[n] - truth[n]) / abs(truth[n]) for n in res.free}


@pytest.fixture(scope="module")
def usv_clean():
    return usv_runs(3, 60.0, 0.1, noise="none", seed=1)


@pytest.fixture(scope="module")
def usv_noisy():
    return usv_runs(3, 60.0, 0.1, noise="realistic", seed=2)


def test_fossen3_noise_free_recovery_from_50_percent_start(usv_clean):
    res = fit_output_error(Fossen3(), usv_clean, spec=_start_spec(), estimate_x0=("psi", "u", "v", "r"))
    assert res.converged, res.status
    rel = _rel(res, TV)
    assert max(rel.values()) < 1e-4, rel


def test_fossen3_noisy_within_three_standard_errors(usv_noisy):
    res = fit_output_error(Fossen3(), usv_noisy, spec=_start_spec(1.5, 0.5), estimate_x0=("psi", "u", "v", "r"))
    assert res.converged, res.status
    z = {n: (res.params[n] - TV[n]) / res.stderr[n] for n in res.free}
    assert max(abs(v) for v in z.values()) < 3.0, z
    # the residual noise estimate matches the simulated sensor noise (honest weighting)
    assert res.noise_std["u"] == pytest.approx(0.05, rel=0.15)
    assert res.noise_std["r"] == pytest.approx(0.2 * np.pi / 180, rel=0.15)


def test_output_error_beats_equation_error_on_noisy_data(usv_noisy):
    out = fit_both(Fossen3(), usv_noisy, flt=Filter("butter", cutoff=0.5))
    oe, ee = out["output_error"], out["equation_error"]
    err_oe = np.sqrt(np.mean(np.square(list(_rel(oe, TV).values()))))
    err_ee = np.sqrt(np.mean(np.square(list(_rel(ee, TV).values()))))
    assert err_oe < 0.25 * err_ee, (err_oe, err_ee)
    val = usv_runs(1, 60.0, 0.1, noise="realistic", seed=3)
    ev_oe, ev_ee = evaluate(oe.model, val), evaluate(ee.model, val)
    assert ev_oe.rmse["r"] < ev_ee.rmse["r"] and ev_oe.rmse["u"] < ev_ee.rmse["u"]


@pytest.mark.parametrize(
    "truth, cls",
    [(Nomoto1(K=0.2, T1=8.0, delta0=0.01), Nomoto1), (Nomoto2(K=0.2, T1=8.0, T2=1.0, T3=0.5, delta0=0.01), Nomoto2)],
)
def test_nomoto_noise_free_recovery(truth, cls):
    runs = nomoto_runs(truth, n_runs=2, duration=60.0, dt=0.1, noise="none")
    ee = fit_equation_error(cls(), runs, flt=Filter("none"))
    start = {n: v * 1.3 for n, v in truth.param_values().items()}
    res = fit_output_error(cls().with_params(start), runs, starts=[ee.params], estimate_x0=cls().states_for_channels(("psi", "r")))
    assert res.converged, res.status
    rel = {n: abs(res.params[n] - v) / abs(v) for n, v in truth.param_values().items() if n in res.free}
    assert max(rel.values()) < 1e-4, rel
