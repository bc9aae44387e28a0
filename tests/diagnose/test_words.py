"""The miss in a naval architect's words, and position floors a positioning system can deliver.
No simulation of a model: signals built by hand."""

import math

import numpy as np
import pytest

import diffship  # noqa: F401
from diffship.data import Run
from diffship.diagnose.floors import distance_sailed, physical_position_floor
from diffship.diagnose.where import NoiseEstimate, WHITE, structural_gate
from diffship.diagnose.words import channel_words, overshoots, reversals, where_in_words

D = math.pi / 180


def _zigzag(overshoot_deg, t):
    """A 10/10 zigzag-like record: rudder ±10° switched when ψ passes ±10°, heading swinging
    past the switch heading by ``overshoot_deg`` (a sine through each check)."""
    a = (10 + overshoot_deg) * D
    psi = a * np.sin(2 * np.pi * (t - 5) / 40) * (t > 5)
    delta = np.where(t < 5, 0.0, -10 * D * np.sign(np.cos(2 * np.pi * (t - 5) / 40 - 1e-9)))
    return delta, psi


def test_overshoot_angles_of_a_zigzag():
    t = np.arange(0, 120, 0.05)
    delta, psi = _zigzag(8.0, t)
    ks = reversals(delta)
    assert len(ks) >= 3 and abs(t[ks[0]] - 15.0) < 0.1  # first check at the first heading extreme
    # the swing is reversed at the heading extreme here, so nothing overshoots beyond the check heading
    assert overshoots(t, delta, psi) == pytest.approx([0.0, 0.0], abs=1e-3)
    # checked 5 s (45°) before the extreme: overshoot = a (1 − cos 45°)
    late = np.where(t < 5, 0.0, -10 * D * np.sign(np.cos(2 * np.pi * (t - 5) / 40 + np.pi / 4)))
    a = 18 * D
    assert np.degrees(overshoots(t, late, psi)) == pytest.approx([np.degrees(a * (1 - np.cos(np.pi / 4)))] * 2, rel=0.02)
    # random steering is no zigzag: no overshoots reported
    rng = np.random.default_rng(0)
    assert overshoots(t, rng.normal(size=t.size), psi) == []


def test_channel_words_say_what_the_error_is():
    t = np.arange(0, 60, 0.1)
    meas = {"psi": 0.2 * np.sin(t / 5), "r": 0.04 * np.cos(t / 5), "u": 1.2 - 0.1 * np.sin(t / 5) ** 2}
    sim = {"psi": 0.8 * meas["psi"], "r": 0.8 * meas["r"], "u": meas["u"] + 0.02}
    run = Run("z", t, {**meas, "v": np.zeros_like(t)})
    rmse = {c: float(np.sqrt(np.mean((sim[c] - meas[c]) ** 2))) for c in sim}
    w = channel_words([run], {"z": sim}, rmse, {"psi": 0.001, "r": 0.001, "u": 0.001})
    assert [x["channel"] for x in w] == ["psi", "r", "u"]  # heading, rate, speed first
    assert w[0]["unit"] == "°" and w[0]["rmse"] == pytest.approx(np.degrees(rmse["psi"]))
    assert w[0]["swing_ratio"] == pytest.approx(0.8, rel=1e-6)
    assert w[2]["mean_error"] == pytest.approx(0.02) and w[2]["percent_of_U"] == pytest.approx(100 * 0.02 / 1.16, rel=0.02)
    s = where_in_words(w, {}, {"steady_turn": {"E": 5.0}, "transient": {"E": 2.0}}, {})
    assert s.startswith("heading") and "turns too little" in s and "keeps too much speed" in s
    assert "in the turn with the rudder held" in s


def test_position_floor_is_physical_not_the_scatter_of_a_smooth_track():
    t = np.arange(0, 100, 0.05)
    U = 1.18
    run = Run("k", t, {"x0": U * t, "y0": 0 * t, "u": np.full(t.size, U), "v": 0 * t})
    s = distance_sailed(run)
    assert s[-1] == pytest.approx(U * t[-1], rel=1e-9)
    smooth = {c: NoiseEstimate(1.5e-4, WHITE, 1.5e-4, 0.0, 0.0) for c in ("x0", "y0")}
    out = physical_position_floor(smooth, [run])
    rms_s = U * t[-1] / math.sqrt(3)  # RMS of a distance growing linearly from 0
    assert out["x0"].sigma == pytest.approx(1e-3 * rms_s, rel=0.01)  # 0.1 % of the distance sailed
    assert out["x0"].method.startswith("physical")
    assert physical_position_floor(smooth, [run], accuracy=0.5)["y0"].sigma == 0.5
    # a noisy track keeps its statistical floor (above the physical one)
    noisy = {c: NoiseEstimate(0.5, WHITE, 0.5, 0.0, 0.0) for c in ("x0", "y0")}
    assert physical_position_floor(noisy, [run])["x0"].sigma == 0.5
    # a physical floor is given, not estimated: no floor-estimation term in the gap gate
    g_est = structural_gate(("x0",), [run], [run], smooth)
    g_phys = structural_gate(("x0",), [run], [run], out)
    assert g_phys.sd_E2 < g_est.sd_E2


def test_a_periodic_residual_not_driven_by_the_rudder_is_found():
    """A 7-s oscillation in the residual (a wave-like push) is found with its period; a residual at
    the zigzag's own period is the model's answer to the rudder and is not reported; noise alone
    gives nothing."""
    from diffship.diagnose.periodic import periodic_residual

    rng = np.random.default_rng(2)
    t = np.arange(0, 120, 0.1)
    runs = [Run(f"r{i}", t, {"psi": 0 * t}) for i in range(2)]
    steer = {r.name: 0.2 * np.sign(np.sin(2 * np.pi * t / 40)) for r in runs}
    wave = {r.name: {"psi": 0.01 * np.sin(2 * np.pi * t / 7.0 + i) + rng.normal(0, 0.01, t.size)}
            for i, r in enumerate(runs)}
    hit = periodic_residual(runs, wave, steer, ["psi"])
    assert hit is not None and hit["period_s"] == pytest.approx(7.0, rel=0.05) and hit["channels"] == ["psi"]
    driven = {r.name: {"psi": 0.01 * np.sin(2 * np.pi * t / 40) + rng.normal(0, 0.01, t.size)} for r in runs}
    assert periodic_residual(runs, driven, steer, ["psi"]) is None
    noise = {r.name: {"psi": rng.normal(0, 0.01, t.size)} for r in runs}
    assert periodic_residual(runs, noise, steer, ["psi"]) is None
