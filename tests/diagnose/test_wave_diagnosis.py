"""The wave candidate in the diagnosis: its period starts at the periodic training residual
(Fisher's g, refined by a least-squares scan), a wave injected by the independent generator is
attributed with its period, and a null stays null."""

import sys
from pathlib import Path

import numpy as np
import pytest

import diffship  # noqa: F401
from diffship.data import Run
from diffship.diagnose.periodic import periodic_residual, refine_period

GEN = Path(__file__).resolve().parents[2] / "benchmarks"


def _residual_runs(period, amp, seed, n_runs=4, duration=40.0, dt=0.1, noise=1.0):
    """Runs of white noise plus (when amp > 0) a line at ``period`` with a random phase per run."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, dt)
    runs, res, steer = [], {}, {}
    for i in range(n_runs):
        e = noise * rng.standard_normal(t.size)
        if amp:
            e = e + amp * np.cos(2 * np.pi * t / period + rng.uniform(0, 2 * np.pi))
        name = f"r{i}"
        runs.append(Run(name, t, {"r": e}, {}, check_units=False))
        res[name] = {"r": e}
        steer[name] = np.sign(np.sin(2 * np.pi * t / 37.0))  # a slow square wave: no line near the period
    return runs, res, steer


def test_refined_period_is_within_a_twentieth_of_a_bin():
    """On 40-s runs the Fourier bins near 6.2 s are 5.7 and 6.7 s; the scan gets 6.2 s back."""
    for seed in (1, 2, 3):
        runs, res, steer = _residual_runs(6.2, 0.8, seed)
        found = periodic_residual(runs, res, steer, ["r"])
        assert found is not None and found["channels"] == ["r"]
        assert abs(found["period_s"] - 6.2) < 0.6  # the bin: 1/40 Hz wide
        T = refine_period(runs, res, ["r"], found["period_s"])
        assert T == pytest.approx(6.2, abs=0.06)


def test_a_line_the_steering_shares_counts_only_when_the_steering_is_not_asked_and_it_repeats_enough():
    """Under an autopilot the rudder answers a sea state at its period: ``steer=None`` keeps such a line; ``cycles``
    keeps a manoeuvre's own few-per-run period out."""
    runs, res, _ = _residual_runs(6.2, 0.8, 5, duration=120.0)
    steer = {r.name: res[r.name]["r"] for r in runs}  # the steering shares the residual's line
    assert periodic_residual(runs, res, steer, ["r"]) is None
    assert periodic_residual(runs, res, None, ["r"], cycles=10.0)["period_s"] == pytest.approx(6.2, abs=0.4)
    runs, res, _ = _residual_runs(30.0, 0.8, 6, duration=120.0)  # four cycles per run
    assert periodic_residual(runs, res, None, ["r"]) is not None
    assert periodic_residual(runs, res, None, ["r"], cycles=10.0) is None


def _zigzag_rudder(t, rudder_deg, switch_deg, K=0.06, T=12.0, rate_deg=15.8):
    """The rudder of a zigzag flown by its switching rule on a first-order Nomoto ship [rad]."""
    dt, psi, r, d, target, out = t[1] - t[0], 0.0, 0.0, 0.0, np.radians(rudder_deg), []
    for _ in t:
        if (psi > np.radians(switch_deg) and target > 0) or (psi < -np.radians(switch_deg) and target < 0):
            target = -target
        d += np.clip(target - d, -np.radians(rate_deg) * dt, np.radians(rate_deg) * dt)
        r += dt * (K * d - r) / T
        psi += dt * r
        out.append(d)
    return np.array(out)


def test_a_line_at_the_zigzags_harmonics_is_driven_though_each_zigzag_has_its_own_period():
    """Basin zigzags 10/5, 20/5, 35/5 and 20/10 (100 s at 0.2 s): each rudder has a line near 20 s (a harmonic of its
    own period), in neighbouring Fourier bins. A model error there is the answer to the rudder: no wave. (Averaged
    over the runs before the test, the lines fell below the threshold and started a sea-state check.)"""
    rng = np.random.default_rng(7)
    t = np.arange(0.0, 100.2, 0.2)
    runs, res, steer = [], {}, {}
    for i, (rudder, switch) in enumerate(((10, 5), (20, 5), (35, 5), (20, 10))):
        name = f"z{i}"
        e = 0.05 * np.sin(2 * np.pi * t / 20.04 + i) + 0.01 * rng.standard_normal(t.size)
        runs.append(Run(name, t, {"r": e}, {}, check_units=False))
        res[name], steer[name] = {"r": e}, _zigzag_rudder(t, rudder, switch)
    assert periodic_residual(runs, res, None, ["r"])["period_s"] == pytest.approx(20.0, rel=0.05)  # a line
    assert periodic_residual(runs, res, steer, ["r"]) is None  # every run's rudder has it


def test_white_residuals_give_no_period():
    hits = 0
    for seed in range(10):
        runs, res, steer = _residual_runs(6.2, 0.0, 100 + seed)
        hits += periodic_residual(runs, res, steer, ["r"]) is not None
    assert hits == 0  # p < 1e-3 per test: no false line in ten null cases


def _independent_wave(seed, drift):
    sys.path.insert(0, str(GEN))
    try:
        import independent as I
        from independent import effects as fx
    finally:
        sys.path.pop(0)
    S = sys.modules["independent.scenarios"]  # the package exports a function of that name
    orig = S._usv_effect
    S._usv_effect = lambda label, k: fx.Wave(F_mean=150.0 * k * drift, beta=1.0, F_osc=150.0 * k, N_osc=600.0 * k,
                                             period=6.0)
    try:
        g = I.generate(I.Scenario("usv", "wave", "out", "strong", seed))
    finally:
        S._usv_effect = orig
    mk = lambda gs: [Run(x["name"], x["time"], x["channels"], {"source": "independent"}) for x in gs]  # noqa: E731
    return mk(g["train"]), mk(g["val"])


@pytest.mark.slow
def test_an_injected_wave_is_attributed_with_its_period():
    """The independent generator's 6-s sway force and yaw moment (150 N, 600 N·m, no mean drift):
    the wave is the first selected effect and its period is 6 s within two standard errors."""
    from diffship.diagnose import DiagnoseOptions, diagnose
    from diffship.models import Fossen3

    train, val = _independent_wave(1, drift=0.0)
    d = diagnose(Fossen3(), train, val, options=DiagnoseOptions(effects=("wave", "current", "constant_force")))
    assert d.selected[:1] == ("wave",)
    row = next(r for r in d.ranking if r.effect == "wave")
    T, se = d.final_model.param_values()["T_w"], row.stderr["T_w"]
    assert abs(T - 6.0) < max(2 * se, 0.01), (T, se)
    assert d.shrink > 0.5


@pytest.mark.slow
def test_a_null_stays_null_with_the_wave_candidate():
    """No disturbance: no periodic training residual, so no wave candidate, and nothing selected."""
    from diffship.diagnose import DiagnoseOptions, diagnose
    from diffship.models import Fossen3

    sys.path.insert(0, str(GEN))
    try:
        import independent as I
    finally:
        sys.path.pop(0)
    g = I.generate(I.Scenario("usv", "none", "none", "strong", 100))
    mk = lambda gs: [Run(x["name"], x["time"], x["channels"], {"source": "independent"}) for x in gs]  # noqa: E731
    d = diagnose(Fossen3(), mk(g["train"]), mk(g["val"]), options=DiagnoseOptions(effects=("wave", "current")))
    assert d.selected == ()
    assert "wave" in d.skipped and "no start for its parameter T_w" in d.skipped["wave"]


@pytest.mark.slow
def test_the_nomoto_form_is_attributed_on_independent_zigzags():
    """The independent first-order Nomoto ship with a yaw disturbance F = 0.03 rad/s · sin(2πt/8 s)
    in T ṙ + r = K(δ + δ0) + F: the wave (rudder-equivalent a_s = F/K) is the first selected effect,
    with its period and amplitude."""
    from diffship.diagnose import DiagnoseOptions, diagnose
    from diffship.models import Nomoto1

    sys.path.insert(0, str(GEN))
    try:
        import independent as I
        from independent import effects as fx
    finally:
        sys.path.pop(0)
    S = sys.modules["independent.scenarios"]
    orig = S._ship_effect
    S._ship_effect = lambda label, k: fx.Wave(N_osc=0.03, period=8.0)
    try:
        g = I.generate(I.Scenario("ship", "damping_rr", "in", "strong", 1))
    finally:
        S._ship_effect = orig
    mk = lambda gs: [Run(x["name"], x["time"], x["channels"], {"source": "independent"}) for x in gs]  # noqa: E731
    d = diagnose(Nomoto1(), mk(g["train"]), mk(g["val"]), options=DiagnoseOptions(effects=("wave", "actuator_lag")))
    assert d.selected[:1] == ("wave",)
    row = next(r for r in d.ranking if r.effect == "wave")
    assert abs(row.params["T_w"] - 8.0) < max(3 * row.stderr["T_w"], 0.05), (row.params, row.stderr)
    assert row.params["a_s"] == pytest.approx(0.03 / 0.11, rel=0.1)  # F/K, the generator's K = 0.11 1/s
