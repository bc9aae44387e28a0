"""Bootstrap intervals (:mod:`diffship.fit.bootstrap`) on a small Nomoto problem: they lie around the
truth, agree with the covariance intervals on white measurement noise, and shrink with more data."""

import numpy as np
import pytest

from diffship.errors import FitError
from diffship.fit import OutputErrorOptions, fit_output_error
from diffship.fit.bootstrap import block_length, bootstrap_fit
from diffship.models import Nomoto1
from diffship.synthetic import nomoto_runs

TRUTH = Nomoto1(K=0.2, T1=8.0, delta0=0.01)
OPTIONS = OutputErrorOptions(reference_priors=False, estimate_x0=("psi", "r"))


def _boot(duration, n=16, method="blocks", seed=0):
    runs = nomoto_runs(TRUTH, n_runs=2, duration=duration, dt=0.2, noise="realistic", seed=seed)
    res = fit_output_error(Nomoto1(), runs, options=OPTIONS)
    assert res.converged, res.status
    return res, bootstrap_fit(res, runs, spec=Nomoto1().spec(), options=OPTIONS, n=n, method=method, seed=seed)


@pytest.fixture(scope="module")
def short():
    return _boot(60.0)


def test_intervals_are_near_the_truth_and_match_the_covariance(short):
    res, boot = short
    assert boot.n_ok == boot.n == 16
    truth = np.array([TRUTH.param_values()[n] for n in boot.names])
    # the truth within 3 bootstrap standard deviations (95 % coverage itself: benchmarks/bootstrap_coverage.py)
    assert np.all(np.abs(boot.estimate - truth) < 3 * boot.stderr), (boot.estimate, boot.stderr)
    assert np.all(boot.lo <= boot.estimate) and np.all(boot.estimate <= boot.hi)
    # white sensor noise: bootstrap and Gauss–Newton standard errors agree within a factor 2
    ratio = boot.stderr / boot.cov_stderr
    assert np.all((ratio > 0.5) & (ratio < 2.0)), ratio
    text, doc = boot.text(), boot.as_json()
    assert "percentile" in text and "covariance" in text and "K" in text
    assert doc["n_converged"] == 16 and doc["params"]["K"]["lo"] < 0.2 < doc["params"]["K"]["hi"]


def test_the_fit_records_how_it_was_made_and_the_bootstrap_reads_it(short):
    """A FitResult carries its spec and estimator: ``bootstrap_fit(result, runs)`` needs nothing else
    (the discover CLI's --bootstrap relies on it) and gives the same intervals as the explicit call."""
    res, boot = short
    assert res.spec is not None and res.spec.free_names == res.free
    assert res.estimator is not None and res.estimator.describe() == res.info["estimator"]
    # the reported solve time is every start's first solve plus the rest from the best (not the last pass alone)
    parts = res.info["solve_seconds"]
    assert parts["first_solves"] > 0 and res.fit_seconds == pytest.approx(parts["first_solves"] + parts["from_the_best"])
    runs = nomoto_runs(TRUTH, n_runs=2, duration=60.0, dt=0.2, noise="realistic", seed=0)
    again = bootstrap_fit(res, runs, n=16, seed=0)
    np.testing.assert_allclose(again.lo, boot.lo, rtol=1e-9)
    np.testing.assert_allclose(again.hi, boot.hi, rtol=1e-9)


@pytest.mark.slow  # CI time budget (a 240-s fit and its bootstrap): python -m pytest -m slow
def test_intervals_shrink_with_more_data(short):
    _, a = short
    _, b = _boot(240.0)
    # four times the data: on average clearly smaller bootstrap spreads (1/sqrt(4) for white noise; K gains
    # less from repeated zigzags: measured 0.70 for K, 0.61 for T1, 0.17 for delta0), none larger
    ratio = b.stderr / a.stderr
    assert np.all(ratio < 1.1) and np.mean(ratio) < 0.7, ratio
    assert np.mean((b.hi - b.lo) / (a.hi - a.lo)) < 0.75


def test_runs_bootstrap_needs_two_runs_and_block_length_follows_the_correlation():
    runs = nomoto_runs(TRUTH, n_runs=1, duration=40.0, dt=0.2, noise="realistic", seed=0)
    res = fit_output_error(Nomoto1(), runs, options=OPTIONS)
    with pytest.raises(FitError, match="two runs"):
        bootstrap_fit(res, runs, spec=Nomoto1().spec(), options=OPTIONS, n=4, method="runs")
    rng = np.random.default_rng(0)
    white = rng.normal(size=(1, 2000, 1))
    ar = np.zeros_like(white)
    for k in range(1, 2000):  # AR(1) with ρ = 0.9: integrated time (1 + ρ)/(1 − ρ) = 19 samples
        ar[0, k] = 0.9 * ar[0, k - 1] + white[0, k]
    mask = np.ones((1, 2000), bool)
    assert block_length(white, mask) <= 3
    assert 25 <= block_length(ar, mask) <= 60


def test_cli_bootstrap_text_json_and_bad_count(tmp_path, capsys):
    import json

    from diffship.fit.cli import main as fit_main

    paths = []
    for r in nomoto_runs(TRUTH, n_runs=2, duration=40.0, dt=0.2, noise="realistic", seed=4):
        p = tmp_path / f"{r.name}.csv"
        r.to_dataframe().to_csv(p, index=False)
        paths.append(str(p))
    js = tmp_path / "fit.json"
    code = fit_main(paths + ["--model", "nomoto1", "--method", "output-error", "--x0", "estimate", "--bootstrap", "8",
                             "--json", str(js), "--quiet"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "bootstrap (moving blocks" in out and "percentile" in out
    doc = json.loads(js.read_text())["methods"]["output_error"]
    boot = doc["bootstrap"]
    assert boot["n"] == 8 and boot["n_converged"] == 8
    for name, p in boot["params"].items():
        assert p["lo"] < p["hi"] and p["estimate"] == pytest.approx(doc["params"][name], rel=1e-9), name
        assert p["stderr"] > 0 and p["cov_stderr"] == pytest.approx(doc["stderr"][name], rel=1e-9)
    with pytest.raises(SystemExit) as exc:  # refused before any fit, as argparse refuses (status 2)
        fit_main(paths + ["--model", "nomoto1", "--method", "output-error", "--bootstrap", "1", "--quiet"])
    assert exc.value.code == 2 and "--bootstrap needs at least 2 resamples, got 1" in capsys.readouterr().err
    assert fit_main(paths + ["--model", "nomoto1", "--method", "equation-error", "--bootstrap", "4", "--quiet"]) == 2
    assert "--bootstrap: refits single-shooting output error" in capsys.readouterr().err
