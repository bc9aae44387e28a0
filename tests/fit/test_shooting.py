"""Multiple shooting ends at the single-shooting optimum when the model is right (the stage
alone, without the single-shooting polish), on noise-free and noisy data; options and errors."""

import numpy as np
import pytest

from diffship.errors import FitError
from diffship.fit import OutputErrorOptions, fit_output_error
from diffship.fit.shooting import ShootingOptions, fit_multiple_shooting, parse_shooting
from diffship.models import Nomoto1
from diffship.synthetic import nomoto_runs

TRUTH = dict(K=0.2, T1=8.0, delta0=0.01)
OPTS = OutputErrorOptions(estimate_x0=("psi", "r"), reference_priors=False)


def _spec():
    return Nomoto1().spec().with_values({"K": 0.1, "T1": 12.0, "delta0": 0.0})


def _pair(noise, seed, polish=False):
    runs = nomoto_runs(Nomoto1(**TRUTH), 2, 60.0, 0.1, noise=noise, seed=seed)
    ss = fit_output_error(Nomoto1(), runs, spec=_spec(), options=OPTS)
    ms = fit_multiple_shooting(Nomoto1(), runs, spec=_spec(), options=OPTS,
                               shooting=ShootingOptions(segment_s=10.0, polish=polish))
    return ss, ms


def test_multiple_shooting_stage_recovers_the_truth_without_noise():
    ss, ms = _pair("none", 3)
    assert ms.converged, ms.status
    for n, v in TRUTH.items():
        assert abs(ms.params[n] / v - 1) < 1e-6, (n, ms.params[n])
    st = ms.info["shooting"]
    assert st["segments_per_run"] == 7 and st["stages"][-1]["max_defect"] < 1e-8


def test_multiple_shooting_stage_ends_at_the_single_shooting_optimum_on_noisy_data():
    ss, ms = _pair("realistic", 4)
    assert ms.converged and ss.converged
    for n in TRUTH:
        # the continuity penalty ends at 1e4: within a small fraction of a standard error
        assert abs(ms.params[n] - ss.params[n]) < 0.1 * ss.stderr[n], (n, ms.params[n], ss.params[n], ss.stderr[n])
        # its own standard errors (constrained by the defect rows) are those of single shooting
        assert abs(ms.stderr[n] / ss.stderr[n] - 1) < 0.15, (n, ms.stderr[n], ss.stderr[n])
    assert ms.info["shooting"]["stages"][-1]["max_defect"] < 1e-3


def test_polish_gives_the_single_shooting_fit():
    ss, ms = _pair("realistic", 4, polish=True)
    for n in TRUTH:
        assert abs(ms.params[n] - ss.params[n]) < 1e-3 * ss.stderr[n]
    assert ms.info["shooting"]["polish"] and ms.iterations > ss.iterations


def test_parse_shooting_and_errors():
    assert parse_shooting("single") is None
    assert parse_shooting("multiple").segment_s == 20.0
    assert parse_shooting("multiple:7.5").segment_s == 7.5
    for bad in ("double", "multiple:abc", "multiple:-3"):
        with pytest.raises(FitError, match="--shooting|segment length"):
            parse_shooting(bad)
    with pytest.raises(FitError, match="penalties"):
        ShootingOptions(penalties=(1.0, np.nan))
    with pytest.raises(FitError, match="stage_ftol"):
        ShootingOptions(stage_ftol=np.nan)


def test_cli_multiple_shooting(tmp_path, capsys):
    from diffship.fit.cli import main

    paths = []
    for run in nomoto_runs(Nomoto1(**TRUTH), 2, 60.0, 0.1, noise="realistic", seed=4):
        p = tmp_path / f"{run.name}.csv"
        run.to_dataframe().to_csv(p, index=False)
        paths.append(str(p))
    out = tmp_path / "ms"
    assert main([*paths, "--model", "nomoto1", "--method", "output-error", "--shooting", "multiple:10",
                 "--init", "K=0.1", "T1=12", "--quiet", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "multiple shooting: 7 segments of 100 samples" in text
    assert (out / "fit.png").exists() and (out / "fit.json").exists()
    assert main([*paths, "--model", "nomoto1", "--shooting", "triple", "--quiet"]) == 2
    assert "--shooting 'triple'" in capsys.readouterr().err


def test_cli_multiple_shooting_goes_on_when_equation_error_is_not_available(tmp_path, capsys, monkeypatch):
    """The default method (both) with --shooting multiple: equation error failing (as on a model without its
    form, MMG) is said, and multiple-shooting output error still runs (it exited 2 with the baseline's error)."""
    import diffship.fit.both as both
    from diffship.errors import ModelError
    from diffship.fit.cli import main

    def unavailable(model, *a, **k):
        raise ModelError(f"model {model.name} has no equation-error form; use output error")

    monkeypatch.setattr(both, "fit_equation_error", unavailable)
    paths = []
    for run in nomoto_runs(Nomoto1(**TRUTH), 2, 60.0, 0.1, noise="realistic", seed=4):
        p = tmp_path / f"{run.name}.csv"
        run.to_dataframe().to_csv(p, index=False)
        paths.append(str(p))
    assert main([*paths, "--model", "nomoto1", "--shooting", "multiple:10", "--init", "K=0.1", "T1=12",
                 "--out", str(tmp_path / "ms")]) == 0
    captured = capsys.readouterr()
    assert "equation error not available: model nomoto1 has no equation-error form" in captured.err + captured.out
    assert "multiple shooting: 7 segments of 100 samples" in captured.out


@pytest.mark.slow  # CI time budget: run with python -m pytest -m slow
def test_block_jacobian_is_the_jacobian():
    """The per-segment (block) Jacobian equals forward-mode differentiation of the whole residual."""
    import dataclasses

    import jax
    import jax.numpy as jnp

    from diffship.fit.shooting import shooting_problem

    runs = nomoto_runs(Nomoto1(**TRUTH), 2, 30.0, 0.1, noise="realistic", seed=4)
    kernel, data, _, info = shooting_problem(Nomoto1(), runs, _spec(), None, OPTS, 10.0)
    rng = np.random.default_rng(0)
    z = jnp.asarray(np.concatenate([_spec().to_z(_spec().values()), 0.3 * rng.normal(size=info["n_segment_unknowns"])]))
    data = data.replace(weight=jnp.asarray(10.0))
    dense = dataclasses.replace(kernel, block_jacobian=False)
    J_block = np.asarray(jax.jacfwd(kernel.residuals)(z, data))
    J_dense = np.asarray(jax.jacfwd(dense.residuals)(z, data))
    assert kernel.block_jacobian and J_block.shape == J_dense.shape == (data.ys.size + 2 * 3 * 2, z.size)
    assert np.abs(J_block - J_dense).max() <= 1e-10 * np.abs(J_dense).max()
    assert np.array_equal(np.asarray(kernel.residuals(z, data)), np.asarray(dense.residuals(z, data)))
    # with prior rows (one per free parameter) appended
    n_p = len(_spec().free_names)
    data = data.replace(prior_mean=jnp.asarray([0.2, 8.0, 0.0]), prior_w=jnp.asarray([10.0, 0.5, 0.0]))
    J_block = np.asarray(jax.jacfwd(kernel.residuals)(z, data))
    J_dense = np.asarray(jax.jacfwd(dense.residuals)(z, data))
    assert J_block.shape[0] == data.ys.size + 12 + n_p and np.any(J_block[-n_p:] != 0)
    assert np.abs(J_block - J_dense).max() <= 1e-10 * np.abs(J_dense).max()
