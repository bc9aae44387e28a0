"""Integrators: diffrax stepping equals the hand-written RK4; every integrator fits to the same optimum."""

import jax.numpy as jnp
import numpy as np
import pytest

from diffship.fit import OutputErrorOptions, fit_output_error
from diffship.integrators import INTEGRATORS, RK4, Diffrax, Tsit5, get_integrator
from diffship.models import Fossen3, Nomoto1
from diffship.simulate import simulate
from diffship.synthetic import usv_runs, usv_truth


def test_diffrax_rk4_tableau_is_the_classical_rk4():
    m = Fossen3()
    ts = jnp.linspace(0.0, 30.0, 301)
    us = jnp.stack([jnp.full(301, 3000.0), 200.0 * jnp.sin(0.3 * ts), -800.0 * jnp.sin(0.2 * ts)], 1)
    x0 = jnp.array([0.0, 0.0, 0.1, 2.0, 0.0, 0.0])
    for n in (1, 3):
        a = simulate(m, ts, us, x0, RK4(substeps=n)).xs
        b = simulate(m, ts, us, x0, Diffrax(substeps=n)).xs
        np.testing.assert_allclose(np.asarray(b), np.asarray(a), rtol=1e-12, atol=1e-12)


def test_unrolled_stages_equal_diffrax_step():
    """The stages of diffrax's tableau written out (the default) give diffrax's ``step`` up to
    round-off, values and forward-mode derivatives, for RK4 and for Tsit5 (an FSAL stage left out)."""
    import diffrax
    import jax

    m = Fossen3()
    ts = jnp.linspace(0.0, 30.0, 301)
    us = jnp.stack([jnp.full(301, 3000.0), 200.0 * jnp.sin(0.3 * ts), -800.0 * jnp.sin(0.2 * ts)], 1)
    x0 = jnp.array([0.0, 0.0, 0.1, 2.0, 0.0, 0.0])
    for solver, n in ((None, 2), (diffrax.Tsit5(scan_kind="lax"), 1)):
        kw = {} if solver is None else {"solver": solver}

        def xs(x, unroll, n=n, kw=kw):
            return simulate(m, ts, us, x, Diffrax(substeps=n, unroll=unroll, **kw)).xs

        def both(x, xs=xs):
            return (xs(x, True), xs(x, False), jax.jacfwd(lambda y: xs(y, True))(x),
                    jax.jacfwd(lambda y: xs(y, False))(x))
        a, b, ja, jb = jax.jit(both)(x0)
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-12, atol=1e-10)
        np.testing.assert_allclose(np.asarray(ja), np.asarray(jb), rtol=1e-10, atol=1e-10)


def test_get_integrator_names_and_errors():
    assert set(INTEGRATORS) >= {"diffrax-rk4", "diffrax-tsit5", "rk4", "tsit5"}
    assert isinstance(get_integrator("tsit5"), Tsit5)
    assert get_integrator(RK4(substeps=2)) == RK4(substeps=2)
    with pytest.raises(ValueError, match="diffrax-rk4"):
        get_integrator("euler")
    with pytest.raises(ValueError, match="substeps"):
        RK4(substeps=0)


@pytest.fixture(scope="module")
def usv_short():
    return usv_runs(2, 40.0, 0.1, noise="realistic", seed=5)


# CI time budget (run with -m slow): diffrax-rk4 is the default the reference fit already uses
@pytest.mark.parametrize("name", [pytest.param("diffrax-rk4", marks=pytest.mark.slow), "rk4",
                                  pytest.param("tsit5", marks=pytest.mark.slow)])
def test_every_integrator_reaches_the_same_optimum(name, usv_short):
    """Fossen 3-DOF USV on velocities from a start ±50 % off: the adaptive path (Tsit5 + PID inside
    each sample interval) fits as the fixed-step ones do (it used to end in a singular normal matrix)."""
    truth = usv_truth().param_values()
    free = Fossen3().spec().free_names
    start = {n: truth[n] * (1.5 if i % 2 else 0.5) for i, n in enumerate(free)}
    spec = Fossen3().spec().with_values({**{n: truth[n] for n in Fossen3().spec().fixed_names}, **start})
    opts = OutputErrorOptions(estimate_x0=("u", "v", "r"), weights="spread", integrator=get_integrator(name))
    res = fit_output_error(Fossen3(), usv_short, spec=spec, channels=("u", "v", "r"), options=opts)
    assert res.converged, res.status
    assert res.integrator == get_integrator(name)
    ref = fit_output_error(Fossen3(), usv_short, spec=spec, channels=("u", "v", "r"),
                           options=OutputErrorOptions(estimate_x0=("u", "v", "r"), weights="spread"))
    for n in free:
        assert res.params[n] == pytest.approx(ref.params[n], rel=1e-3, abs=1e-6 * abs(truth[n])), n
        assert np.isfinite(res.stderr[n]) and res.stderr[n] < abs(res.params[n])


def test_adaptive_integrator_failure_is_a_blow_up_not_nan():
    m = Nomoto1(K=0.5, T1=-1e-3)  # violently unstable: the adaptive solver runs out of steps
    ts = jnp.linspace(0.0, 10.0, 101)
    sol = simulate(m, ts, jnp.full((101, 1), 0.1), jnp.zeros(2), Tsit5(max_steps=8))
    assert not bool(sol.ok)
    assert bool(jnp.all(jnp.isfinite(sol.xs)))


def test_input_hold_zero_holds_the_sample_and_is_checked():
    """``hold="zero"``: the input keeps its sample value over the interval (ẋ = u gives u₀·h, the linear
    hold (u₀ + u₁)/2·h) for every integrator; an unknown hold is refused; the fit file keeps it."""
    from diffship.fitfile import integrator_name

    f = lambda t, x, u: u  # noqa: E731
    for name in INTEGRATORS:
        lin, zoh = get_integrator(name), get_integrator(name, hold="zero")
        a = float(lin.interval(f, 0.0, 2.0, jnp.zeros(1), jnp.ones(1), jnp.full(1, 3.0))[0])
        b = float(zoh.interval(f, 0.0, 2.0, jnp.zeros(1), jnp.ones(1), jnp.full(1, 3.0))[0])
        assert a == pytest.approx(4.0, rel=1e-9) and b == pytest.approx(2.0, rel=1e-9), name
        assert "zero-order hold" in zoh.describe() and "zero-order hold" not in lin.describe()
        doc = integrator_name(zoh)
        assert get_integrator(doc["name"], **doc["options"]) == zoh
    assert integrator_name(RK4(substeps=3))["options"]["substeps"] == 3  # the fit file kept RK4's substeps
    with pytest.raises(ValueError, match="input hold"):
        RK4(hold="cubic")


def _nomoto1_zoh_run(K, T, dt, duration, seed):
    """Exact solution (no integrator) of ψ̇ = r, T ṙ = K δ − r with δ held over each sample (a digital command)."""
    from diffship.data import Run

    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration + 0.5 * dt, dt)
    delta = np.deg2rad(20.0) * np.sign(np.sin(2 * np.pi * t / 16.0) + 0.3 * rng.standard_normal(t.size))
    psi, r = np.zeros(t.size), np.zeros(t.size)
    e = np.exp(-dt / T)
    for k in range(t.size - 1):
        target = K * delta[k]
        r[k + 1] = target + (r[k] - target) * e
        psi[k + 1] = psi[k] + target * dt + (r[k] - target) * T * (1.0 - e)
    psi += np.deg2rad(0.2) * rng.standard_normal(t.size)
    r += np.deg2rad(0.05) * rng.standard_normal(t.size)
    return Run(f"zoh_{seed}", t, {"delta": delta, "psi": psi, "r": r}, {})


def test_a_digital_command_log_is_fitted_without_bias_under_the_zero_order_hold():
    """A rudder command logged at 1 Hz and held: read as first-order hold, the log leads the true input by
    half a sample and the time constant comes out biased; with ``hold="zero"`` K and T are within 3 SE."""
    K, T = 0.2, 8.0
    runs = [_nomoto1_zoh_run(K, T, 1.0, 300.0, s) for s in (0, 1)]
    fits = {}
    for hold in ("zero", "linear"):
        opts = OutputErrorOptions(integrator=get_integrator("diffrax-rk4", substeps=4, hold=hold),
                                  reference_priors=False, estimate_x0=("psi", "r"))
        res = fit_output_error(Nomoto1(K=0.1, T1=4.0), runs, options=opts)
        assert res.converged, res.status
        fits[hold] = res
    z = fits["zero"]
    assert abs(z.params["K"] - K) < 3 * z.stderr["K"] and abs(z.params["T1"] - T) < 3 * z.stderr["T1"], (z.params, z.stderr)
    lin = fits["linear"]
    assert abs(lin.params["T1"] - T) > 3 * lin.stderr["T1"], (lin.params, lin.stderr)  # the half-sample lead biases T
    assert lin.noise_std["psi"] > 1.2 * z.noise_std["psi"]  # and the heading residuals are larger (noise 0.2°)
