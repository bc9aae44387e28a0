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


@pytest.mark.parametrize("name", ["diffrax-rk4", "rk4", pytest.param("tsit5", marks=pytest.mark.slow)])  # tsit5: CI time budget (-m slow)
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
