import numpy as np
import pytest

from diffship.data import Run
from diffship.errors import DataError, ModelError
from diffship.fit import fit_equation_error
from diffship.fit.equation_error import equation_data
from diffship.models import Fossen3, Nomoto1, Nomoto2, kvlcc2_mmg
from diffship.preprocess import Filter
from diffship.synthetic import nomoto_runs, usv_runs, usv_truth


def _rel(a, b, names):
    return {n: abs(a[n] / b[n] - 1) if b[n] else abs(a[n]) for n in names}


def test_nomoto1_equation_error_noise_free():
    truth = Nomoto1(K=0.2, T1=8.0, delta0=0.01)
    runs = nomoto_runs(truth, n_runs=2, duration=60.0, dt=0.05, noise="none")
    res = fit_equation_error(Nomoto1(), runs, flt=Filter("none"))
    for n, v in truth.param_values().items():
        assert res.params[n] == pytest.approx(v, rel=2e-3), n


def test_nomoto1_yaw_rate_from_heading_when_r_is_not_measured():
    """``EQUATION_RATE_OF = {"r": "psi"}``: without an r channel, r is the derivative of the heading."""
    truth = Nomoto1(K=0.2, T1=8.0, delta0=0.01)
    runs = nomoto_runs(truth, n_runs=2, duration=60.0, dt=0.05, noise="none")
    no_r = [Run(r.name, r.time, {"psi": r["psi"], "delta": r["delta"]}, {}) for r in runs]
    z_r = equation_data(Nomoto1(), runs[0], Filter("none")).z[:, 0]
    z_psi = equation_data(Nomoto1(), no_r[0], Filter("none")).z[:, 0]
    assert np.max(np.abs(z_psi - z_r)[1:-1]) < 1e-3 * np.max(np.abs(z_r))
    res = fit_equation_error(Nomoto1(), no_r, flt=Filter("none"))
    assert max(_rel(res.params, truth.param_values(), ("K", "T1", "delta0")).values()) < 0.01
    with pytest.raises(DataError, match="psi"):
        fit_equation_error(Nomoto1(), [Run("x", runs[0].time, {"delta": runs[0]["delta"]}, {})])


def test_nomoto2_regression_start_falls_back_to_first_order():
    """Second-order regression coefficients that give no real positive time constants: the
    first-order regression is used with T2 = T1/10 (a pure map, no data needed)."""
    m = Nomoto2()
    first = {"a": -0.125, "b": 0.025, "c": 0.00025}  # T1 = 8, K = 0.2, δ0 = 0.01
    good = m.from_regression({"second_order": {"a": -0.125, "b": -1.125, "c": 0.025, "d": 0.00025, "g": 0.0125},
                              "first_order": first})
    assert good == pytest.approx({"K": 0.2, "T1": 8.0, "T2": 1.0, "delta0": 0.01, "T3": 0.5})
    bad = m.from_regression({"second_order": {"a": 0.1, "b": 0.0, "c": 1.0, "d": 0.0, "g": 0.0}, "first_order": first})
    assert bad == pytest.approx({"K": 0.2, "T1": 8.0, "T2": 0.8, "delta0": 0.01})
    assert m.from_regression({"second_order": {"a": 0.1, "b": 0.0, "c": 1.0, "d": 0.0, "g": 0.0},
                              "first_order": {"a": 0.1, "b": 1.0, "c": 0.0}}) is None


def test_fossen3_inverse_dynamics_is_linear_least_squares():
    """From the Fossen3 defaults (seed-002 damping, no added mass): every free parameter of the test
    truth is 30–50 % (added masses: entirely) away from its start."""
    truth = usv_truth()
    start = Fossen3()
    assert min(_rel(start.param_values(), truth.param_values(), start.spec().free_names).values()) > 0.24
    runs = usv_runs(2, 60.0, 0.05, noise="none", seed=4)
    res = fit_equation_error(start, runs, flt=Filter("savgol", window=0.5))
    rel = _rel(res.params, truth.param_values(), res.free)
    assert max(rel.values()) < 0.02, rel  # only derivative discretisation error remains
    assert res.converged and res.iterations <= 6


def test_equation_error_needs_velocities():
    run = usv_runs(1, 30.0, 0.1, noise="none")[0]
    no_v = run.to_dataframe().drop(columns=["v"])

    with pytest.raises(DataError, match="v"):
        fit_equation_error(Fossen3(), [Run.from_dataframe(no_v, name="no_v")])
    assert np.isfinite(run["u"]).all()


def test_model_without_equation_error_form_is_refused_first():
    """MMG declares no equations: a ModelError naming the model, before any data are looked at."""
    empty = Run("empty", np.arange(10.0), {"x": np.zeros(10)}, {})
    with pytest.raises(ModelError, match="mmg has no equation-error form; use output error"):
        fit_equation_error(kvlcc2_mmg(), [empty])
    with pytest.raises(ModelError, match="no equation-error form"):
        equation_data(kvlcc2_mmg(), empty)


# -- the cut-off chosen from the data ------------------------------------------------------------
def test_auto_cutoff_sits_between_the_signal_and_the_noise_floor():
    """0.11 and 0.3 Hz sinusoids plus white noise at 10 Hz: the cut-off lies above the signal's
    content and below 60 % of Nyquist; more noise, lower cut-off; no noise, higher still."""
    from diffship.preprocess import auto_cutoff

    t = np.arange(0.0, 120.0, 0.1)
    y = np.sin(2 * np.pi * 0.3 * t) + 0.3 * np.sin(2 * np.pi * 0.11 * t)
    rng = np.random.default_rng(0)
    fc_low_noise = auto_cutoff(y + rng.normal(0, 0.002, t.size), 0.1)
    fc_high_noise = auto_cutoff(y + rng.normal(0, 0.05, t.size), 0.1)
    assert 0.3 < fc_high_noise < fc_low_noise < auto_cutoff(y, 0.1) <= 3.0


def test_rov_equation_error_with_the_automatic_cutoff_is_within_its_own_intervals():
    """6-DOF BlueROV2-like vehicle, 10 Hz, ROV-grade sensor noise, 18 free parameters (added masses,
    linear and quadratic damping): with the cut-off chosen from the data at least 15 of 18
    estimates lie within 3 of their own standard errors. The cut-offs are stated, and
    roll/pitch rates keep their content above the old default (10 % of Nyquist = 0.5 Hz)."""
    import sys
    from pathlib import Path

    from diffship.models import Fossen6

    sys.path.insert(0, str(Path(__file__).parents[1] / "models"))
    from _rov_data import rov_runs

    truth = Fossen6()
    tv = truth.param_values()
    runs = rov_runs(truth, n_runs=2, duration=60.0, dt=0.1, seed=0)
    spec = truth.spec().free(("Xuu", "Yvv", "Zww", "Kpp", "Mqq", "Nrr"))
    res = fit_equation_error(truth, runs, spec=spec)
    assert len(res.free) == 18
    z = np.array([(res.params[n] - tv[n]) / res.stderr[n] for n in res.free])
    assert np.sum(np.abs(z) < 3) >= 15, dict(zip(res.free, np.round(z, 1)))
    cut = res.info["cutoff_hz"]
    assert set(cut) == {r.name for r in runs}
    assert all(0.5 < cut[r][c] < 3.0 for r in cut for c in ("p", "q"))
    assert any("cut-offs [Hz]" in m for m in res.messages)
    assert res.info["covariance"] in ("white", "hac")


def test_linear_and_bounded_spaces_are_data_of_one_program():
    """The LM runs first in the unbounded linear space θ/scale, then (where that optimum leaves a bound)
    in the bounded space: both are the same compiled solve with different arrays. The map from the
    scaled vector is the spec's own, to the bit, in each space, and the two spaces' static parts (what
    a compile is keyed on) are equal."""
    import equinox as eqx
    import jax.numpy as jnp

    from diffship.fit.equation_error import _Space, _unbounded

    spec = Fossen3().spec()
    kinds = {p.kind for p in spec.params if p.free}
    assert len(kinds) >= 2  # sign-bounded and free coefficients: the test sees more than one map
    z = jnp.asarray(np.random.default_rng(3).normal(size=len(spec.free_names)) * 2.0)
    spaces = (spec, _unbounded(spec))
    for sp in spaces:
        np.testing.assert_array_equal(np.asarray(_Space.of(sp).from_z(z)), np.asarray(sp.from_z(z)))
    bounded, linear = (_Space.of(sp) for sp in spaces)
    assert not np.array_equal(np.asarray(bounded.kind), np.asarray(linear.kind))
    assert eqx.partition(bounded, eqx.is_array)[1] == eqx.partition(linear, eqx.is_array)[1]


def test_equation_error_programs_are_exported_and_reload_to_the_same_answer(tmp_path, monkeypatch):
    """The equation-error solve (the output-error fit's start) is a program :mod:`diffship.compiled` exports: its
    arguments are arrays, its outputs plain arrays (the result as an integer code), its code diffship's; a new
    process deserialises it instead of tracing optimistix's loop again. The reloaded program reaches the same
    estimate, to the bit."""
    import jax
    import jax.numpy as jnp

    from diffship import cache, compiled
    from diffship.fit import EquationError, fit
    from diffship.fit.equation_error import _Programs

    monkeypatch.setattr(cache, "cache_dir", lambda: tmp_path)
    truth = Nomoto1(K=0.2, T1=8.0, delta0=0.01)
    runs = nomoto_runs(truth, n_runs=1, duration=40.0, dt=0.1, noise="none")
    problem = EquationError(flt=Filter("none")).prepare(Nomoto1(), runs, Nomoto1().spec(), None, None, print)
    w, pm, pw, model, samples, space = EquationError()._args(problem, np.ones(1))
    args = (jnp.zeros(3), w, pm, pw, model, samples, (space.kind, space.lo, space.hi, space.s))
    owner = _Programs(space.idx, space.n)
    saved = compiled.exported()["saved"]
    exp = compiled._exported(owner, "solve", owner.solve, args, {"max_steps": 50})
    assert exp is not None and compiled.exported()["saved"] == saved + 1
    assert len(list((tmp_path / "exported").iterdir())) == 1
    z_direct = np.asarray(owner.solve(*args, max_steps=50)[0])
    z_loaded = np.asarray(exp.call(*jax.tree_util.tree_leaves(args))[0])
    np.testing.assert_array_equal(z_loaded, z_direct)
    res = fit(Nomoto1(), runs, EquationError(flt=Filter("none")), n_starts=1)
    assert res.params["K"] == pytest.approx(0.2, rel=2e-3)
