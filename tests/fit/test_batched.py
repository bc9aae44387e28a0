"""The batched Levenberg–Marquardt (:mod:`diffship.fit.batched`): B problems in one program behave as
B independent solves, finished problems stay frozen, each problem has its own status, and masked
(padded) unknowns stay where they start."""

import math
import os

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
import pytest

from diffship.fit._lm import MaterialisedLM, rms_norm
from diffship.fit.batched import CODES, lm_advance, lm_start, solve_batch
from diffship.fit.kernel import Kernel, kernel_data
from diffship.fit.output_error import channel_spread
from diffship.fit.problem import make_batch
from diffship.models import Nomoto1
from diffship.preprocess import Filter
from diffship.synthetic import nomoto_runs

T = np.linspace(0.0, 10.0, 100)
SIGMA = 0.01
TOL = dict(rtol=1e-8, atol=1e-8, ftol=1e-12, gntol=0.05, variance=None, gn_params=None, max_steps=200)


def _residuals(z, y):
    """Two decaying exponentials (rates e^{z1}, e^{z3}): a curved, slow LM valley."""
    return (jnp.exp(z[0] - jnp.exp(z[1]) * T) + jnp.exp(z[2] - jnp.exp(z[3]) * T) - y) / SIGMA


@pytest.fixture(scope="module")
def y():
    rng = np.random.default_rng(0)
    return jnp.asarray(np.exp(-0.3 * T) + 0.5 * np.exp(-0.4 * T) + SIGMA * rng.normal(size=T.size))


@pytest.fixture(scope="module")
def programs():
    start = jax.jit(lambda z, d, f: lm_start(_residuals, z, d, f, **TOL))
    advance = jax.jit(lambda s, d, k: lm_advance(_residuals, s, d, k, **TOL))
    start_pp = jax.jit(lambda z, d, f: lm_start(_residuals, z, d, f, data_axis=0, **TOL))
    advance_pp = jax.jit(lambda s, d, k: lm_advance(_residuals, s, d, k, data_axis=0, **TOL))
    return start, advance, start_pp, advance_pp


STARTS = np.array([[math.log(0.5), math.log(0.15), math.log(0.25), math.log(0.6)],
                   [math.log(1.5), math.log(0.2), math.log(0.1), math.log(0.5)],
                   [math.log(0.8), math.log(0.35), math.log(0.7), math.log(0.45)],
                   [0.0, math.log(0.25), math.log(0.4), math.log(0.5)],
                   [math.log(0.3), math.log(0.1), math.log(0.9), math.log(0.7)]])


def _single(z0, y, free=None):
    """The optimistix reference: MaterialisedLM on one problem (held unknowns: a reduced problem)."""
    z0 = jnp.asarray(z0)
    if free is None:
        fn, x0 = _residuals, z0
    else:
        idx = np.flatnonzero(free)
        fn = lambda x, d: _residuals(z0.at[idx].set(x), d)
        x0 = z0[idx]
    solver = MaterialisedLM(rtol=TOL["rtol"], atol=TOL["atol"], norm=rms_norm, ftol=TOL["ftol"])
    sol = optx.least_squares(fn, solver, x0, args=y, max_steps=TOL["max_steps"], throw=False)
    z = np.asarray(sol.value) if free is None else np.asarray(z0.at[idx].set(sol.value))
    return z, int(sol.stats["num_steps"]), sol.result


@pytest.mark.parametrize("repack", [False, True])
def test_batch_equals_independent_single_solves(y, programs, repack):
    start, advance, *_ = programs
    st = solve_batch(start, advance, STARTS, y, np.ones(STARTS.shape, bool), per_problem_data=False, repack=repack)
    assert np.all(st["status"] == CODES["successful"])
    for b, z0 in enumerate(STARTS):
        z, steps, result = _single(z0, y)
        assert result == optx.RESULTS.successful
        np.testing.assert_allclose(st["z"][b], z, rtol=0, atol=1e-9)
        assert st["steps"][b] == steps  # the same iterations, step for step
    # the starts differ in how long they take: per-problem convergence, not lockstep
    assert len(set(st["steps"].tolist())) > 1


def test_frozen_problem_does_not_move(y, programs):
    start, advance, *_ = programs
    z0 = jnp.asarray(STARTS[:2])
    st = start(z0, y, jnp.ones(z0.shape, bool))
    st = dict(st, done=st["done"].at[1].set(True))  # problem 1 finished (e.g. by an earlier round)
    out = advance(st, y, jnp.asarray(0, jnp.int32))
    assert np.array_equal(np.asarray(out["z"][1]), np.asarray(z0[1]))
    # not even evaluated: the start's residuals and Jacobian are the first pass of lm_advance
    assert int(out["steps"][1]) == int(st["steps"][1]) == 0 and float(out["cost"][1]) == float(st["cost"][1])
    r0 = np.asarray(_residuals(z0[0], y))
    assert float(out["cost"][0]) < 0.01 * 0.5 * float(r0 @ r0)  # problem 0 did converge meanwhile


def test_each_problem_has_its_own_status(y, programs):
    start, advance, *_ = programs
    starts = STARTS[:3].copy()
    starts[1] = [800.0, 0.0, 0.0, 0.0]  # exp(800) overflows: a start whose cost is not finite
    st = solve_batch(start, advance, starts, y, np.ones(starts.shape, bool), per_problem_data=False, repack=False)
    assert st["status"][1] == CODES["divergence"]
    assert st["status"][0] == st["status"][2] == CODES["successful"]
    for b in (0, 2):
        np.testing.assert_allclose(st["z"][b], _single(starts[b], y)[0], atol=1e-9)
    # a budget too small for some problems: those report it, the others still converge
    full = solve_batch(start, advance, STARTS, y, np.ones(STARTS.shape, bool), per_problem_data=False, repack=False)
    budget = int(np.median(full["steps"]))
    short = jax.jit(lambda s, d, k: lm_advance(_residuals, s, d, k, **dict(TOL, max_steps=budget)))
    start_b = jax.jit(lambda z, d, f: lm_start(_residuals, z, d, f, **dict(TOL, max_steps=budget)))
    st = solve_batch(start_b, short, STARTS, y, np.ones(STARTS.shape, bool), per_problem_data=False, repack=False)
    over = full["steps"] > budget
    assert over.any() and (~over).any()
    assert np.all(st["status"][over] == CODES["max_steps"]) and np.all(st["steps"][over] == budget)
    assert np.all(st["status"][~over] == CODES["successful"])
    np.testing.assert_allclose(st["z"][~over], full["z"][~over], atol=1e-12)


def test_masked_unknowns_stay_put_and_the_rest_solves_the_reduced_problem(y, programs):
    start, advance, *_ = programs
    free = np.ones(STARTS.shape, bool)
    free[1, 2:] = False  # problem 1: a "smaller structure" padded to the batch's 4 unknowns
    free[3, 0] = False
    st = solve_batch(start, advance, STARTS, y, free, per_problem_data=False, repack=False)
    assert np.array_equal(st["z"][1, 2:], STARTS[1, 2:]) and st["z"][3, 0] == STARTS[3, 0]
    for b in (1, 3):
        z, steps, result = _single(STARTS[b], y, free[b])
        np.testing.assert_allclose(st["z"][b], z, atol=1e-8)
        assert st["status"][b] == CODES["successful"]


def test_per_problem_data(y, programs):
    *_, start_pp, advance_pp = programs
    ys = jnp.stack([y, 1.1 * y, 0.9 * y])
    z0 = np.tile(STARTS[0], (3, 1))
    st = solve_batch(start_pp, advance_pp, z0, ys, np.ones(z0.shape, bool), per_problem_data=True, repack=True)
    for b in range(3):
        np.testing.assert_allclose(st["z"][b], _single(z0[b], ys[b])[0], atol=1e-9)


# -- the output-error kernel: solve_many's layouts give the same fits --------------------------------
@pytest.fixture(scope="module")
def nomoto_kernel():
    truth = Nomoto1(K=0.2, T1=8.0, delta0=0.01)
    runs = nomoto_runs(truth, n_runs=2, duration=40.0, dt=0.2, noise="realistic", seed=3)
    model = Nomoto1()
    spec = model.spec()
    batch = make_batch(model, runs, ("r",), Filter("none"))
    kernel = Kernel(spec=spec.structural(), out_idx=(model.output_names.index("r"),), angle=(False,))
    data = kernel_data(model, batch.ts, batch.us, batch.ys, batch.mask, batch.x0, channel_spread(batch))
    return kernel, data, spec, truth


@pytest.mark.slow  # CI time budget (22 s on 2 cores): run with python -m pytest -m slow
def test_solve_many_batched_equals_threads_equals_solve(nomoto_kernel):
    kernel, data, spec, truth = nomoto_kernel
    free = spec.free_names
    rng = np.random.default_rng(1)
    Z = np.stack([spec.to_z({n: truth.param_values()[n] * f for n, f in
                             zip(free, np.exp(rng.uniform(-0.7, 0.7, len(free))))}) for _ in range(3)])
    lm = dict(max_steps=100, rtol=1e-8, atol=1e-8)
    a = kernel.solve_many(Z, data, method="batched", **lm)
    b = kernel.solve_many(Z, data, method="threads", workers=2, **lm)
    one = kernel.call("solve", Z[0], data, **lm)
    for (za, ra, sa, _), (zb, rb, sb, _) in zip(a, b):
        assert ra == rb == optx.RESULTS.successful
        np.testing.assert_allclose(np.asarray(za), np.asarray(zb), atol=1e-8)
        assert int(sa) == int(sb)
    np.testing.assert_allclose(np.asarray(one[0]), np.asarray(a[0][0]), atol=1e-8)
    # Kernel.solve stays vmappable (benchmarks vmap it): the same fits in lockstep
    zv = jax.jit(jax.vmap(lambda z: kernel.solve(z, data, **lm)[0]))(jnp.asarray(Z))
    np.testing.assert_allclose(np.asarray(zv), np.stack([np.asarray(o[0]) for o in a]), atol=1e-8)
    theta = spec.from_z(np.asarray(a[0][0]))
    assert abs(float(theta[free.index("K")]) - 0.2) < 0.02  # recovers K = 0.2 1/s within 10 %


def test_solve_many_rejects_bad_input(nomoto_kernel):
    kernel, data, spec, _ = nomoto_kernel
    z = np.atleast_2d(spec.to_z())
    with pytest.raises(ValueError, match="method"):
        kernel.solve_many(z, data, method="gpu", max_steps=5, rtol=1e-6, atol=1e-6)
    with pytest.raises(ValueError, match="free mask shape"):
        kernel.solve_many(z, data, free=np.ones((1, z.shape[1] + 1), bool), max_steps=5, rtol=1e-6, atol=1e-6)


def test_default_threads_from_the_environment(monkeypatch, nomoto_kernel):
    """``$DIFFSHIP_THREADS`` (a fleet worker's share of the cores) sets solve_many's threads; a bad value
    is a clear error naming the variable; the starts' answers do not depend on it."""
    from diffship.fit.kernel import default_threads

    monkeypatch.delenv("DIFFSHIP_THREADS", raising=False)
    assert default_threads() == (os.cpu_count() or 1)
    monkeypatch.setenv("DIFFSHIP_THREADS", "3")
    assert default_threads() == 3
    for bad in ("two", "0", "-1"):
        monkeypatch.setenv("DIFFSHIP_THREADS", bad)
        with pytest.raises(ValueError, match=f"DIFFSHIP_THREADS must be a positive integer, got '{bad}'"):
            default_threads()
    kernel, data, spec, _ = nomoto_kernel
    Z = np.stack([spec.to_z(), spec.to_z()])
    lm = {"max_steps": 5, "rtol": 1e-6, "atol": 1e-6}
    monkeypatch.setenv("DIFFSHIP_THREADS", "1")
    a = kernel.solve_many(Z, data, **lm)
    monkeypatch.setenv("DIFFSHIP_THREADS", "2")
    b = kernel.solve_many(Z, data, **lm)
    for (za, _, sa, _), (zb, _, sb, _) in zip(a, b):
        np.testing.assert_array_equal(np.asarray(za), np.asarray(zb))
        assert int(sa) == int(sb) > 0


def test_stall_rule_stops_a_crawl_early_and_leaves_converging_problems_alone(y):
    """``stall_steps``/``stall_rtol``: a problem whose cost falls by less than ρ·cost over W steps
    while the Gauss–Newton model still promises more stops, not converged, before the cap; the
    problems that converge do so at the same point in the same steps."""
    def run(**kw):
        s = jax.jit(lambda z, d, f: lm_start(_residuals, z, d, f, **TOL, **kw))
        a = jax.jit(lambda st, d, k: lm_advance(_residuals, st, d, k, **TOL, **kw))
        return solve_batch(s, a, STARTS, y, np.ones(STARTS.shape, bool), per_problem_data=False, repack=False)
    full, st = run(), run(stall_steps=5, stall_rtol=1e-2)
    assert np.all(full["status"] == CODES["successful"])
    crawl = st["status"] == CODES["max_steps"]
    # the slowest start (127 steps along the curved valley) crawls: stopped early, its cost within a few % of the optimum
    assert crawl[4] and st["steps"][4] < full["steps"][4] / 3
    assert st["cost"][4] < 1.1 * full["cost"][4]
    ok = ~crawl
    assert ok.sum() >= 3
    assert np.all(st["status"][ok] == CODES["successful"]) and np.array_equal(st["steps"][ok], full["steps"][ok])
    np.testing.assert_allclose(st["z"][ok], full["z"][ok], atol=1e-12)


def _bounded_residuals(z, y):
    """One decaying exponential whose amplitude is bounded above by 0.8 (``a = 0.8 − e^{z₀}``, the
    parameter space's upper-bound map) and rate ``z₁``, against data of amplitude 1: the optimum is on the
    bound."""
    return ((0.8 - jnp.exp(z[0])) * jnp.exp(-z[1] * T) - y) / SIGMA


def test_a_parameter_on_its_bound_stops_the_solve_where_the_others_have_converged():
    """On its bound a parameter's optimum is at z = −∞ and the Gauss–Newton step in z keeps its length: plain
    Levenberg–Marquardt crawls there until the cost stalls. With the bounds' kinds (``bounded``) the solve
    stops as converged once the amplitude is within ``gntol`` standard errors of its bound and the rate's step
    is short; the rate is then the constrained optimum (the amplitude held on the bound) within 0.05 of its
    standard error."""
    rng = np.random.default_rng(1)
    y = jnp.asarray(np.exp(-0.3 * T) + SIGMA * rng.normal(size=T.size))
    z0 = np.array([[math.log(0.5), 0.2]])

    def run(**kw):
        s = jax.jit(lambda z, d, f: lm_start(_bounded_residuals, z, d, f, **TOL, **kw))
        a = jax.jit(lambda st, d, k: lm_advance(_bounded_residuals, st, d, k, **TOL, **kw))
        return solve_batch(s, a, z0, y, np.ones(z0.shape, bool), per_problem_data=False, repack=False)
    crawl, stop = run(), run(bounded=(2, 0))
    assert stop["status"][0] == CODES["successful"]
    assert stop["steps"][0] < crawl["steps"][0] / 2, (stop["steps"], crawl["steps"])
    # the constrained optimum: the rate alone with the amplitude on its bound (a linear-in-nothing 1-D fit)
    fixed = optx.least_squares(lambda k, yy: (0.8 * jnp.exp(-k * T) - yy) / SIGMA,
                               optx.LevenbergMarquardt(rtol=1e-12, atol=1e-12), jnp.asarray(0.2), args=y).value
    J = jax.jacfwd(lambda k: 0.8 * jnp.exp(-k * T) / SIGMA)(fixed)
    se = math.sqrt(float(2 * 0.5 * jnp.sum(((0.8 * jnp.exp(-fixed * T) - y) / SIGMA) ** 2) / (T.size - 1))
                   / float(J @ J))
    assert abs(stop["z"][0, 1] - float(fixed)) < 0.05 * se
    assert 0.0 < math.exp(stop["z"][0, 0]) < 1e-3  # the amplitude inside its bound, on it to 0.1 % of its value


def test_a_solve_ends_where_an_unknown_reaches_its_absorbing_bound(y):
    """``stop_above`` (item 7): the rate of the first exponential clipped at e^{-2} inside the residuals, while the
    data ask e^{-1.2}; the solve that ends on the bound holds the rate where the full solve leaves it (beyond the
    clip its Jacobian column is zero, so the rest of the full solve never moves it), stopped as not converged."""
    hi = -2.0

    def res(z, yy):
        return (jnp.exp(z[0] - jnp.exp(jnp.clip(z[1], -10.0, hi)) * T) - yy) / SIGMA

    z0, free = jnp.asarray([[0.0, -3.0]]), jnp.ones((1, 2), bool)
    full = jax.jit(lambda s, d, k: lm_advance(res, s, d, k, **TOL))(lm_start(res, z0, y, free, **TOL), y, 0)
    early = jax.jit(lambda s, d, k: lm_advance(res, s, d, k, stop_above=((1, hi),), **TOL))(
        lm_start(res, z0, y, free, **TOL), y, 0)
    assert float(full["z"][0, 1]) >= hi and float(early["z"][0, 1]) == float(full["z"][0, 1])
    assert int(early["status"][0]) == CODES["max_steps"] and int(early["steps"][0]) < int(full["steps"][0])
    assert float(early["cost"][0]) >= float(full["cost"][0])  # the other unknown not yet at its optimum
