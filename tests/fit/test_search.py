"""The search of an output-error fit (:mod:`diffship.fit.search`) and the likelihood that decides it."""

import math

import numpy as np

from diffship.fit.search import candidates
from diffship.fit.weights import concentrated_cost, self_consistent_scales


def test_whole_run_candidates_are_the_distinct_proposals_then_the_starts_themselves():
    """``--starts N`` means N whole-run candidates: distinct converged warm-up points first (lowest cost),
    then unconverged proposals, then the starts as they are; a start equal to a kept point is not repeated."""
    per = np.zeros(3)
    s = [np.array([0.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 2.0, 0.0]), np.array([0.0, 0.0, 3.0])]
    p = np.array([0.5, 0.5, 0.5])
    proposals = [(0, p, 10.0, True), (1, p + 1e-7, 10.0, True), (2, p + 1.0, 9.0, True), (3, p - 1.0, 5.0, False)]
    out = candidates(s, proposals, per)
    assert [(i, kind) for i, _, kind in out] == [(2, "warm-up point"), (0, "warm-up point"), (3, "warm-up point"),
                                                 (0, "start")]
    assert np.allclose(out[0][1], p + 1.0) and np.allclose(out[3][1], s[0])
    # every warm-up at one point: that point and three starts as they are
    same = [(i, p, 10.0, True) for i in range(4)]
    out = candidates(s, same, per)
    assert [kind for _, _, kind in out] == ["warm-up point", "start", "start", "start"]
    assert [i for i, _, _ in out] == [0, 0, 1, 2]
    assert len(candidates(s, same, per, n=2)) == 2


def test_an_initial_heading_a_turn_apart_is_one_candidate():
    per = np.array([0.0, 2 * math.pi / 10.0])
    z = np.array([0.3, 0.1])
    out = candidates([z, z + np.array([0.0, per[1]])], [], per)
    assert len(out) == 1


def test_the_likelihood_does_not_depend_on_the_weights_and_its_scales_are_self_consistent():
    """:func:`concentrated_cost` of the same errors weighted two ways is the same number; the weighted
    least-squares gradient at :func:`self_consistent_scales` is the likelihood's gradient (checked by a
    finite difference in one error)."""
    rng = np.random.default_rng(0)
    mask = np.ones((2, 50), bool)
    e = rng.normal(0, [0.01, 0.2], (2, 50, 2))  # errors in model units, two channels
    tau = np.array([4.0, 1.5])
    for w in (np.array([1.0, 1.0]), np.array([0.01, 0.3])):
        f = concentrated_cost((e / w).reshape(-1), mask, w, tau)
        assert math.isclose(f, concentrated_cost(e.reshape(-1), mask, np.ones(2), tau), rel_tol=1e-12)
    s = self_consistent_scales(e.reshape(-1), mask, np.ones(2), tau, np.zeros(2))
    sse = np.sum(e ** 2, axis=(0, 1))
    assert np.allclose(s, np.sqrt(tau * sse / 100))
    # d F / d e_k = (N/τ_c) e_k / SSE_c = e_k / s_c²: the weighted least-squares gradient at those scales
    h = 1e-7
    e2 = e.copy()
    e2[0, 3, 0] += h
    dF = (concentrated_cost(e2.reshape(-1), mask, np.ones(2), tau) - concentrated_cost(e.reshape(-1), mask, np.ones(2), tau)) / h
    assert math.isclose(dF, e[0, 3, 0] / s[0] ** 2, rel_tol=1e-4)
    # a prior row adds ½ p²
    assert math.isclose(concentrated_cost(e.reshape(-1), mask, np.ones(2), tau, np.array([2.0])) -
                        concentrated_cost(e.reshape(-1), mask, np.ones(2), tau), 2.0)


def test_candidates_out_of_steps_keep_residuals_and_their_scales_together():
    """A candidate whose step budget runs out between two reweighting rounds keeps ``r`` (and its Jacobian)
    normalised by the scales of the solve that made them (``r_scales``), not by the next round's: its
    likelihood is then the likelihood of its point. (Comparing ``r`` against the next round's scales made a
    drifting candidate on the USV look 60 000 log-likelihood units better than the truth.)"""
    import jax.numpy as jnp

    from tests.fit.test_kernel import _problem
    from diffship.fit.search import reweighted_solves
    from diffship.fit.weights import correlation_time

    runs, spec, kernel, data = _problem(2, 40.0, 0.2, seed=3)
    n_z = len(spec.free_names) + 2 * len(kernel.x0_idx)
    rng = np.random.default_rng(1)
    zs = [rng.normal(0.0, 1.0, n_z) for _ in range(3)]
    first = np.array([0.01, 0.002])
    out = reweighted_solves(kernel, zs, data, first, {"jacobian": True, "max_steps": 8, "rtol": 1e-6, "atol": 1e-6,
                                                          "gntol": 0.05}, cap=8, total=7,
                            floor=np.full(2, 1e-9))  # a budget that ends mid-round: scales moved after the last solve
    mask = np.asarray(data.mask)
    moved = 0
    for c in out:
        if c["blew_up"]:
            continue
        again = np.asarray(kernel.split(np.asarray(kernel.residuals(jnp.asarray(c["z"]),
                                                                    data.replace(scales=jnp.asarray(c["r_scales"])))),
                                        data)[0])
        np.testing.assert_allclose(c["r"], again, rtol=1e-9, atol=1e-12)
        moved += int(not np.allclose(c["scales"], c["r_scales"]))
        tau = correlation_time(c["r"], mask, 2)
        f_true = concentrated_cost(again, mask, c["r_scales"], tau)
        assert math.isclose(concentrated_cost(c["r"], mask, c["r_scales"], tau), f_true, rel_tol=1e-9)
    assert moved >= 1  # the case the test is about: scales re-estimated after the residuals were made


def test_reweighting_rounds_that_cycle_stop_at_the_first_repeat(monkeypatch):
    """A correlation time that jumps between two readings of a channel makes the rounds' scales cycle: on the
    6-DOF ROV test problem with a period of six rounds, repeated until the step budget ran out (45 of the fit's
    58 s). The candidate stops where the next scales are an earlier round's, and the progress says so. Here the
    estimate alternates between two readings, so the scales repeat every second round."""
    import diffship.fit.search as S
    from tests.fit.test_kernel import _problem

    runs, spec, kernel, data = _problem(2, 40.0, 0.2, seed=3)
    readings, calls = [np.array([1.0, 1.0]), np.array([4.0, 1.0])], [0]

    def jumping(r, mask, n_c):
        calls[0] += 1
        return readings[calls[0] % 2]

    monkeypatch.setattr(S, "correlation_time", jumping)
    z = np.concatenate([spec.with_values({"K": 0.2, "T1": 8.0, "delta0": 0.01}).to_z(),
                        np.zeros(len(runs) * len(kernel.x0_idx))])
    said = []
    lm = {"jacobian": True, "max_steps": 50, "rtol": 1e-6, "atol": 1e-6, "gntol": 0.05}
    out = S.reweighted_solves(kernel, [z], data, np.array([0.01, 0.002]), lm, cap=50, total=10_000,
                              floor=np.full(2, 1e-9), progress=said.append)
    assert out[0]["cycle"] == 2
    assert calls[0] <= 6  # stopped after a few rounds, far from the step budget
    assert any("cycle with a period of 2 rounds" in s for s in said)
    # a steady estimate has no cycle: the candidate converges at its self-consistent scales
    monkeypatch.setattr(S, "correlation_time", lambda r, mask, n_c: readings[0])
    assert S.reweighted_solves(kernel, [z], data, np.array([0.01, 0.002]), lm, cap=50, total=10_000,
                               floor=np.full(2, 1e-9))[0]["cycle"] == 0


def test_rounds_stay_short_while_the_scales_move_and_end_self_consistent(monkeypatch):
    """A candidate whose channel scales moved by more than ``SCALES_MOVING`` over a round takes a round of
    ``FIRST_ROUND_STEPS`` next (its weights follow its residuals); it ends at scales that its own residuals
    reproduce (within ``REWEIGHT_RTOL``), at the point that rounds growing regardless reach."""
    import diffship.fit.search as S
    from diffship.fit.weights import correlation_time
    from tests.fit.test_kernel import _problem

    runs, spec, kernel, data = _problem(2, 40.0, 0.2, seed=3)
    z = np.concatenate([spec.with_values({"K": 0.2, "T1": 8.0, "delta0": 0.01}).to_z(),
                        np.zeros(len(runs) * len(kernel.x0_idx))])
    lm = {"jacobian": True, "max_steps": 100, "rtol": 1e-6, "atol": 1e-6, "gntol": 0.05}
    caps, real = [], type(kernel).solve_many

    def recording(self, z0s, d, **kw):
        caps.append(int(np.asarray(d.step_cap)[0]))
        return real(self, z0s, d, **kw)

    monkeypatch.setattr(type(kernel), "solve_many", recording)
    first = np.array([0.05, 0.02])  # far from the residuals' own levels: the scales move a lot at first
    short = S.reweighted_solves(kernel, [z], data, first, lm, cap=100, total=10_000, floor=np.full(2, 1e-9))[0]
    assert caps[:2] == [S.FIRST_ROUND_STEPS] * 2  # the first round's scales were far off: the second is short too
    mask = np.asarray(data.mask)
    tau = correlation_time(short["r"], mask, 2)
    again = self_consistent_scales(short["r"], mask, short["r_scales"], tau, np.full(2, 1e-9))
    assert np.max(np.abs(again / short["r_scales"] - 1.0)) < 10 * S.REWEIGHT_RTOL
    monkeypatch.setattr(S, "SCALES_MOVING", math.inf)  # rounds growing regardless
    caps.clear()
    grown = S.reweighted_solves(kernel, [z], data, first, lm, cap=100, total=10_000, floor=np.full(2, 1e-9))[0]
    assert caps[:2] == [S.FIRST_ROUND_STEPS, 2 * S.FIRST_ROUND_STEPS]
    n_p = len(spec.free_names)
    np.testing.assert_allclose(short["z"][:n_p], grown["z"][:n_p], atol=2e-3)


def test_no_candidates_are_drawn_beyond_the_starts_when_the_search_is_not_adaptive(monkeypatch):
    """``OutputError(adaptive=False)`` (structure discovery's base fit: a model that lacks terms by design) solves
    the starts' candidates only; by default, a single start that no other candidate confirms draws more."""
    import diffship.fit.output_error as oe_mod
    from diffship.fit import OutputError, fit
    from diffship.models import Nomoto1
    from diffship.synthetic import nomoto_runs

    seen = []
    real = oe_mod.adaptive

    def spy(cands, sols, solve, more, mask, n, say=None):
        seen.append(n)
        return real(cands, sols, solve, more, mask, n, say)

    monkeypatch.setattr(oe_mod, "adaptive", spy)
    runs = nomoto_runs(n_runs=2, duration=60.0, dt=0.2, seed=1)
    a = fit(Nomoto1(), runs, OutputError(adaptive=False), n_starts=1)
    b = fit(Nomoto1(), runs, OutputError(), n_starts=1)
    assert seen == [0, 1]
    # the same data, the same optimum: the draw confirms the start's point
    assert all(math.isclose(a.params[k], b.params[k], rel_tol=1e-4) for k in ("K", "T1"))
