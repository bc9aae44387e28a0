"""The output-error kernel's block Jacobian (:meth:`diffship.fit.kernel.Kernel.blocked_jacobian`)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from diffship.fit.kernel import Kernel, kernel_data
from diffship.fit.problem import make_batch
from diffship.models import Nomoto1
from diffship.preprocess import Filter
from diffship.synthetic import nomoto_runs


def _problem(n_runs: int, duration: float, dt: float, seed: int, priors: bool = False):
    """A first-order Nomoto output-error problem: ``(runs, spec, kernel, data)``, heading and rate
    fitted, both initial states estimated, prior rows on every unknown when ``priors``."""
    truth = Nomoto1(K=0.2, T1=8.0, delta0=0.01)
    runs = nomoto_runs(truth, n_runs=n_runs, duration=duration, dt=dt, noise="realistic", seed=seed)
    model = Nomoto1()
    spec = model.spec()
    chans = ("psi", "r")
    batch = make_batch(model, runs, chans, Filter("none"))
    x0_idx = tuple(model.state_names.index(s) for s in model.states_for_channels(chans))
    kernel = Kernel(spec=spec.structural(), out_idx=tuple(model.output_names.index(c) for c in chans),
                    angle=(True, False), x0_idx=x0_idx)
    n_t, n_d = len(spec.free_names), len(runs) * len(x0_idx)
    pri = dict(prior_mean=np.full(n_t, 0.1), prior_w=np.full(n_t, 3.0),
               x0_prior_w=np.full(n_d, 0.5)) if priors else {}
    data = kernel_data(model, batch.ts, batch.us, batch.ys, batch.mask, batch.x0, np.array([0.01, 0.002]),
                       x0_scale=np.full(len(x0_idx), 0.05), **pri)
    return runs, spec, kernel, data


@pytest.mark.parametrize("priors", [False, True])
def test_block_jacobian_equals_forward_mode_over_every_unknown(priors):
    """Run i's rows depend on the shared parameters and on its own initial-state offsets only: the
    block-assembled Jacobian is the dense forward-mode one, zero blocks included (a run's rows
    must not move with another run's initial state), with and without prior rows."""
    runs, spec, kernel, data = _problem(3, 30.0, 0.2, seed=5, priors=priors)
    x0_idx = kernel.x0_idx
    n_t, n_d = len(spec.free_names), len(runs) * len(x0_idx)
    z = jnp.asarray(np.random.default_rng(0).normal(0.0, 0.3, n_t + n_d))
    assert kernel.own_jacobian() is not None
    J, r = kernel.blocked_jacobian(z, data)
    dense = jax.jacfwd(kernel.residuals)(z, data)
    np.testing.assert_allclose(np.asarray(r), np.asarray(kernel.residuals(z, data)), rtol=0, atol=1e-12)
    assert J.shape == dense.shape
    scale = float(jnp.max(jnp.abs(dense)))
    np.testing.assert_allclose(np.asarray(J), np.asarray(dense), rtol=0, atol=1e-10 * scale)
    # the structure it relies on: run 0's rows do not depend on run 1's initial state
    m = data.ts.shape[1] * data.ys.shape[-1]
    assert float(jnp.max(jnp.abs(dense[:m, n_t + len(x0_idx):n_t + 2 * len(x0_idx)]))) == 0.0
    assert float(jnp.max(jnp.abs(dense[:m, n_t:n_t + len(x0_idx)]))) > 0.0


def test_a_warm_up_horizon_scores_the_same_samples_as_the_sliced_runs():
    """Data with a horizon (:meth:`KernelData.with_horizon`): the warm-up's head keeps the shapes —
    one compiled program for the warm-up and the whole runs — and gives the sliced head's residual
    rows, the later rows zero."""
    _, spec, kernel, data = _problem(2, 60.0, 0.1, seed=7)
    z = jnp.asarray(np.random.default_rng(1).normal(0.0, 0.2, len(spec.free_names) + 4))
    n = 250
    sliced = np.asarray(kernel.residuals(z, data.head(n))).reshape(2, n, 2)
    held = data.with_horizon().head(n)
    assert held.ts.shape == data.ts.shape
    r = np.asarray(kernel.residuals(z, held)).reshape(2, -1, 2)
    np.testing.assert_allclose(r[:, :n], sliced, rtol=0, atol=1e-12)
    assert not np.any(r[:, n:])
    full = np.asarray(kernel.residuals(z, data.with_horizon()))
    np.testing.assert_allclose(full, np.asarray(kernel.residuals(z, data)), rtol=0, atol=1e-12)


@pytest.mark.slow  # CI time budget: run with python -m pytest -m slow
def test_a_traced_step_cap_gives_the_static_caps_solves_and_the_start_jacobian():
    """``KernelData.step_cap``: one compiled solve runs any number of steps under its static cap —
    k steps equal a solve compiled with ``max_steps=k`` — and a cap of 1 returns the start itself
    with its residuals and Jacobian (what a caller without a Jacobian program of its own needs)."""
    _, spec, kernel, data = _problem(2, 30.0, 0.2, seed=9)
    z0 = np.zeros(len(spec.free_names) + 4)
    lm = dict(rtol=1e-10, atol=1e-10, jacobian=True)
    for k in (3, 7):
        z_s, res_s, n_s, r_s, J_s = kernel.call("solve", z0, data, max_steps=k, **lm)
        z_t, res_t, n_t, r_t, J_t = kernel.call("solve", z0, data.replace(step_cap=jnp.asarray(k)), max_steps=40, **lm)
        assert int(n_s) == int(n_t) == k
        np.testing.assert_allclose(np.asarray(z_t), np.asarray(z_s), rtol=0, atol=1e-13)
        np.testing.assert_allclose(np.asarray(J_t), np.asarray(J_s), rtol=0, atol=1e-12)
    z1, _, n1, r1, J1 = kernel.call("solve", z0, data.replace(step_cap=jnp.asarray(1)), max_steps=40, **lm)
    assert int(n1) == 1
    np.testing.assert_array_equal(np.asarray(z1), z0)
    np.testing.assert_allclose(np.asarray(r1), np.asarray(kernel.residuals(jnp.asarray(z0), data)), rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.asarray(J1), np.asarray(kernel.jacobian(jnp.asarray(z0), data)), rtol=0, atol=1e-10)
    # the uncapped solve moves: the cap is what held it
    z40, _, n40, _, _ = kernel.call("solve", z0, data.replace(step_cap=jnp.asarray(40)), max_steps=40, **lm)
    assert int(n40) > 7 and np.max(np.abs(np.asarray(z40) - z0)) > 0.05
