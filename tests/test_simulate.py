"""Simulation: accuracy against closed-form solutions, blow-up status, vmap and forward mode."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from diffship.models import Fossen3, Nomoto1
from diffship.integrators import get_integrator
from diffship.simulate import simulate


@pytest.mark.parametrize("solver", ["rk4", "tsit5"])
def test_nomoto1_step_response_matches_closed_form(solver):
    K, T, d = 0.3, 4.0, 0.1
    m = Nomoto1(K=K, T1=T, delta0=0.0)
    ts = jnp.linspace(0.0, 40.0, 401)
    us = jnp.full((401, 1), d)
    sol = simulate(m, ts, us, jnp.zeros(2), get_integrator(solver))
    t = np.asarray(ts)
    r = K * d * (1 - np.exp(-t / T))
    psi = K * d * (t - T * (1 - np.exp(-t / T)))
    assert bool(sol.ok)
    np.testing.assert_allclose(np.asarray(sol.ys[:, 1]), r, atol=1e-7)
    np.testing.assert_allclose(np.asarray(sol.ys[:, 0]), psi, atol=1e-6)


def test_blow_up_is_a_status_not_nan():
    m = Fossen3(Xu=1e5, Xuu=1e5)  # "negative damping": surge speed explodes
    ts = jnp.arange(0.0, 60.0, 0.1)
    us = jnp.zeros((ts.size, 3))
    sol = simulate(m, ts, us, jnp.array([0.0, 0.0, 0.0, 2.0, 0.0, 0.0]))
    assert not bool(sol.ok)
    assert bool(jnp.all(jnp.isfinite(sol.xs)))
    first_bad = int(jnp.argmin(sol.valid))
    assert 0 < first_bad < ts.size


def test_vmap_over_parameter_sets_and_forward_mode():
    ts = jnp.linspace(0.0, 20.0, 201)
    us = jnp.stack([jnp.full(201, 3000.0), 200.0 * jnp.sin(0.3 * ts), -800.0 * jnp.sin(0.3 * ts)], 1)
    x0 = jnp.array([0.0, 0.0, 0.0, 2.0, 0.0, 0.0])
    base = Fossen3()
    xus = jnp.array([-40.0, -50.0, -60.0])

    def final_u(xu):
        return simulate(base.with_params({"Xu": xu}), ts, us, x0).xs[-1, 3]

    batched = jax.vmap(final_u)(xus)
    singles = jnp.stack([final_u(x) for x in xus])
    np.testing.assert_allclose(np.asarray(batched), np.asarray(singles), rtol=1e-12)
    # more surge damping, lower speed
    assert float(batched[0]) > float(batched[2])
    def f(xu, solver):
        return simulate(base.with_params({"Xu": xu}), ts, us, x0, get_integrator(solver)).xs[-1, 3]

    # Finite differences are reliable on the fixed-step solver only (an adaptive solver's step
    # choice makes them noisy, which is why peers relying on them stall); forward mode through
    # both solvers must agree with them.
    fd = (f(-50.0 + 1e-3, "rk4") - f(-50.0 - 1e-3, "rk4")) / 2e-3
    for solver in ("rk4", "tsit5"):
        fwd = jax.jacfwd(f)(-50.0, solver)
        np.testing.assert_allclose(float(fwd), float(fd), rtol=1e-4)


def test_a_horizon_simulates_the_first_samples_exactly_and_skips_whole_blocks_after_it():
    """``horizon`` (a traced count, one compiled program for every horizon): the first ``horizon``
    samples are the plain simulation's, bit for bit; the blocks wholly after it are not simulated
    (the state is held), at any run length (the last block padded)."""
    from diffship.simulate import BLOCK
    m = Nomoto1(K=0.2, T1=8.0)
    n = 5 * BLOCK + 17  # not a multiple of the block
    t = np.arange(n) * 0.1
    u = np.sin(0.05 * t)[:, None] * 0.3
    x0 = np.array([0.1, 0.0])
    plain = simulate(m, t, u, x0)
    run = jax.jit(lambda h: simulate(m, t, u, x0, horizon=h).xs)
    for h in (n, 2 * BLOCK + 5, BLOCK, 1):
        xs = np.asarray(run(jnp.asarray(h)))
        assert xs.shape == np.asarray(plain.xs).shape
        np.testing.assert_array_equal(xs[:h], np.asarray(plain.xs)[:h])
        last = -(-h // BLOCK) * BLOCK + 1  # samples up to the end of the horizon's block are simulated
        if last < n:
            assert np.all(xs[last:] == xs[last - 1]), "the blocks after the horizon are held, not simulated"
            assert not np.allclose(np.asarray(plain.xs)[last:], xs[last - 1])


def _nomoto_case():
    t = np.arange(50) * 0.2
    return Nomoto1(K=0.2, T1=8.0), t, (0.1 * np.sin(0.3 * t))[:, None], np.array([0.0, 0.01])


@pytest.mark.parametrize("change, match", [
    (lambda t, u, x: (t[::-1], u, x), "strictly increasing|ts[1]"),
    (lambda t, u, x: (np.r_[t[:5], t[4:-1]], u, x), "strictly increasing|ts[5]"),
    (lambda t, u, x: (t, u[:-5], x), "us must have shape|(50, 1)|['delta']|got shape (45, 1)"),
    (lambda t, u, x: (t, u[:, 0], x), "us must have shape|got shape (50,)"),
    (lambda t, u, x: (t, np.hstack([u, u]), x), "us must have shape|got shape (50, 2)"),
    (lambda t, u, x: (t, u, x[:1]), "x0 must have shape (2,)|['psi', 'r']|got shape (1,)"),
])
def test_arguments_that_do_not_fit_the_model_or_the_grid_stop_before_simulating(change, match):
    from diffship.errors import DataError
    m, t, u, x = _nomoto_case()
    copies = [a.copy() for a in (t, u, x)]
    with pytest.raises(DataError) as info:
        simulate(m, *change(t, u, x))
    for part in match.split("|"):
        assert part in str(info.value)
    for a, b in zip((t, u, x), copies):
        np.testing.assert_array_equal(a, b)


def test_grid_order_is_checked_on_concrete_arrays_only_and_a_failed_simulation_shows_in_ok():
    import equinox as eqx
    m, t, u, x = _nomoto_case()
    assert bool(jax.jit(lambda t, u, x: simulate(m, t, u, x).ok)(t, u, x))
    broken = eqx.tree_at(lambda q: q.T1, m, jnp.asarray(0.0))  # an invalid model: the rate turns non-finite
    sol = simulate(broken, t, u, x)
    assert not bool(sol.ok) and not bool(sol.valid[-1])
    assert "sol.ok" in simulate.__doc__
