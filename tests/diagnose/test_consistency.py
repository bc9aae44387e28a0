"""Data consistency (:mod:`diffship.diagnose.consistency`): a heading bias from the track against the
over-ground velocities, the time the motion follows the logged rudder — each recovered from logs made
here with plain NumPy (no diffship model), nothing claimed on clean logs, and on the real HSVA zigzags
the injected sizes recovered against the logs as they are."""

import math

import numpy as np
import pytest

import diffship  # noqa: F401
from diffship.data import Run
from diffship.diagnose.consistency import corrected, data_checks, heading_consistency, in_data_line, rudder_timing

D = math.pi / 180


def _track_runs(b: float = 0.0, current=(0.0, 0.0), n: int = 6, seed: int = 0) -> list[Run]:
    """Runs of a craft weaving at about 1.5 m/s: over-ground u, v, the track integrated on a fine grid
    with the true heading, the heading logged as ψ + b; noise on every channel."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        tf = np.arange(0.0, 120.0, 0.01)
        w = 0.05 + 0.01 * i
        psi = 0.4 * np.sin(w * tf) + 0.2 * i
        u_w, v_w = 1.5 + 0.1 * np.sin(0.5 * w * tf), 0.15 * np.cos(w * tf)  # through the water
        c, s = np.cos(psi), np.sin(psi)
        xd, yd = c * u_w - s * v_w + current[0], s * u_w + c * v_w + current[1]
        x = np.concatenate([[0.0], np.cumsum(0.5 * (xd[1:] + xd[:-1]) * 0.01)])
        y = np.concatenate([[0.0], np.cumsum(0.5 * (yd[1:] + yd[:-1]) * 0.01)])
        u, v = c * xd + s * yd, -s * xd + c * yd  # over ground
        k = slice(None, None, 10)
        m = len(tf[k])
        ch = {"x0": x[k] + rng.normal(0, 0.05, m), "y0": y[k] + rng.normal(0, 0.05, m),
              "psi": psi[k] + b + rng.normal(0, 0.2 * D, m), "u": u[k] + rng.normal(0, 0.01, m),
              "v": v[k] + rng.normal(0, 0.01, m)}
        out.append(Run(f"run{i}", tf[k], ch))
    return out


def test_heading_bias_recovered_and_judged_on_held_out_runs():
    runs = _track_runs(b=1.5 * D)
    f = heading_consistency(runs[:4], runs[4:])
    assert f.found, f.reason
    assert abs(f.value / D - 1.5) < 0.05
    assert f.heldout[1] < 0.2 * f.heldout[0]  # the held-out track misfit falls with the bias
    assert "heading_bias b_psi = 1.5" in in_data_line({"heading_bias": f})


@pytest.mark.parametrize("current", [(0.0, 0.0), (0.2, -0.1)])
def test_no_heading_bias_claimed_on_consistent_logs(current):
    """Over-ground u, v are consistent with the track whatever the water does: no bias, with a current too."""
    runs = _track_runs(current=current, seed=1)
    f = heading_consistency(runs[:4], runs[4:])
    assert not f.found and abs(f.value) < 0.1 * D
    assert in_data_line({"heading_bias": f}) is None


def test_heading_check_needs_velocities_and_leaves_logs_unchanged():
    runs = _track_runs(b=1.0 * D, n=4)
    before = {r.name: r["psi"].copy() for r in runs}
    heading_consistency(runs[:3], runs[3:])
    assert all(np.array_equal(r["psi"], before[r.name]) for r in runs)
    no_v = [Run(r.name, r.time, {c: r[c] for c in ("x0", "y0", "psi", "u")}) for r in runs]
    assert heading_consistency(no_v[:3], no_v[3:]) is None


def _nomoto_runs(tau: float, n: int = 6, seed: int = 0, r_noise: float = 0.01 * D) -> list[Run]:
    """A first-order Nomoto ship (T = 8 s, K = 0.1 1/s) whose hull answers the logged rudder ``tau`` s
    later (a logging clock offset when tau > 0); zigzag-like rudder through a 10°/s gear; a fibre-optic gyro's 0.01°/s noise on r."""
    rng = np.random.default_rng(seed)
    K, T, dt = 0.1, 8.0, 0.01
    out = []
    for i in range(n):
        t = np.arange(0.0, 90.0, dt)
        period = 30.0 + 4 * i
        cmd = (15 + 3 * i) * D * np.sign(np.sin(2 * np.pi * t / period + 0.3 * i))
        d = np.empty_like(t)
        d[0] = 0.0
        for k in range(1, len(t)):  # rate-limited steering gear
            d[k] = d[k - 1] + np.clip(cmd[k] - d[k - 1], -10 * D * dt, 10 * D * dt)
        dh = np.interp(t - tau, t, d, left=0.0)  # what the hull answers
        r = np.zeros_like(t)
        for k in range(1, len(t)):
            r[k] = r[k - 1] + dt * (K * dh[k - 1] - r[k - 1]) / T
        psi = np.concatenate([[0.0], np.cumsum(0.5 * (r[1:] + r[:-1]) * dt)])
        k = slice(None, None, 10)
        m = len(t[k])
        out.append(Run(f"zz{i}", t[k], {"delta": d[k], "r": r[k] + rng.normal(0, r_noise, m),
                                          "psi": psi[k] + rng.normal(0, 0.1 * D, m)}))
    return out


def test_rudder_timing_recovers_a_clock_offset():
    runs = _nomoto_runs(0.8)
    f = rudder_timing(runs[:4], runs[4:])
    assert f.found, f.reason
    assert abs(f.value - 0.8) < 0.15
    assert f.heldout[1] < f.heldout[0]
    assert f"rudder timing (input_delay) tau_d = {f.value:.3g} ±" in in_data_line({"rudder_timing": f})
    assert f.to_dict()["library_effect"] == "input_delay"


def test_rudder_timing_claims_nothing_without_offset_finds_a_late_rudder():
    f0 = rudder_timing(*_split(_nomoto_runs(0.0, seed=3)))
    assert not f0.found and abs(f0.value) < 0.15
    late = rudder_timing(*_split(_nomoto_runs(-0.8, seed=4)))  # the rudder logged late: the motion leads it
    assert late.found and abs(late.value + 0.8) < 0.15
    assert "logged late" in in_data_line({"rudder_timing": late})


def test_rudder_timing_not_claimed_where_the_yaw_equation_is_mostly_noise():
    """A yaw rate logged with a MEMS gyro's 0.1°/s noise: the shift is estimated, but the held-out equation
    error hardly falls (under the 5 % the model search asks of an effect), so it is left to the model search."""
    f = rudder_timing(*_split(_nomoto_runs(0.8, seed=6, r_noise=0.1 * D)))
    assert abs(f.value - 0.8) < 0.3
    assert not f.found and "only" in f.reason


def _split(runs):
    return runs[:4], runs[4:]


def test_checks_that_do_not_apply_are_absent():
    runs = _nomoto_runs(0.0, n=3)
    assert set(data_checks(runs[:2], runs[2:])) == {"rate_bias", "rudder_timing"}  # no u, v, track: no heading check
    flat = [Run(r.name, r.time, {"delta": 0 * r["delta"], "r": r["r"]}) for r in runs]
    assert rudder_timing(flat[:2], flat[2:]) is None  # a rudder that never moves says nothing


@pytest.fixture(scope="module")
def hsva():
    from diffship.data import kvlcc2_runs
    from diffship.errors import DataError
    try:
        runs = {r.name.split("KVLCC2_")[-1]: r for r in kvlcc2_runs()}
    except DataError as e:
        pytest.skip(f"the HSVA KVLCC2 logs are read from ../shared/data (not shipped): {e}")
    return [runs[n].slice(runs[n].t0, runs[n].t0 + 100).resample(0.2)
            for n in ("Z_10_05", "Z_20_05", "Z_35_05", "Z_20_10_S", "Z_10_10_P", "Z_20_10_P", "Z_15_05")]


def test_real_hsva_zigzags_injected_errors_recovered(hsva):
    """On the real logs: nothing claimed as they are; a 1° heading bias and a 0.5-s rudder clock offset
    injected exactly are recovered against the logs as they are (within 10 %)."""
    base = data_checks(hsva[:4], hsva[4:])
    assert not any(f.found for f in base.values())
    biased = [r.with_channels(psi=r["psi"] + 1.0 * D) for r in hsva]
    hb = heading_consistency(biased[:4], biased[4:])
    assert hb.found and abs((hb.value - base["heading_bias"].value) / D - 1.0) < 0.1
    early = [r.with_channels(delta=np.interp(r.time + 0.5, r.time, r["delta"])) for r in hsva]
    rt = rudder_timing(early[:4], early[4:])
    assert rt.found and abs(rt.value - base["rudder_timing"].value - 0.5) < 0.05


def test_figure_draws_every_check(tmp_path):
    from diffship.diagnose.report import plot_data_checks

    runs, zz = _track_runs(b=1.5 * D), _nomoto_runs(0.8)
    checks = {**data_checks(runs[:4], runs[4:]), **data_checks(zz[:4], zz[4:])}
    assert set(checks) == {"heading_bias", "rate_bias", "rudder_timing"}
    assert len(checks["rudder_timing"].curve[0]) == len(checks["rudder_timing"].curve[1]) > 10
    path = plot_data_checks(checks, tmp_path / "data_checks.png")
    assert path.exists() and path.stat().st_size > 10_000


def test_corrected_takes_out_only_the_findings_and_leaves_the_logs():
    runs = _track_runs(b=1.5 * D, n=4)
    checks = data_checks(runs[:3], runs[3:])
    fixed = corrected(runs, checks)
    assert all(np.allclose(f["psi"], r["psi"] - checks["heading_bias"].value) for f, r in zip(fixed, runs))
    assert heading_consistency(fixed[:3], fixed[3:]).found is False  # nothing left to find
    clean = _track_runs(n=4, seed=2)
    assert all(a is b for a, b in zip(corrected(clean, data_checks(clean[:3], clean[3:])), clean))
    zz = _nomoto_runs(0.8, n=4)
    rt = data_checks(zz[:3], zz[3:])
    again = rudder_timing(corrected(zz[:3], rt), corrected(zz[3:], rt))
    assert abs(again.value) < 0.1 and not again.found


def test_diagnose_corrects_the_logs_when_asked():
    """``DiagnoseOptions(correct_data=True)``: the rudder timing found in the data is taken out before the base
    fit, the diagnosis says so and reports the finding; with a given base fit it refuses in one line."""
    from diffship.diagnose import DiagnoseOptions, diagnose
    from diffship.errors import DataError
    from diffship.models import Nomoto1

    zz = _nomoto_runs(0.8, n=4)
    o = DiagnoseOptions(correct_data=True, effects=("input_delay",))
    d = diagnose(Nomoto1(), zz[:3], zz[3:], options=o)
    assert d.in_data["rudder_timing"].found and any("corrected" in n for n in d.notes)
    assert d.E_before < d.gate.value and not d.selected  # nothing left for the model search
    with pytest.raises(DataError, match="correct_data"):
        diagnose(Nomoto1(), zz[:3], zz[3:], fit=d.base_fit, options=o)


def test_cli_correct_data(tmp_path):
    """``python -m diffship.diagnose ... --correct-data``: the finding taken out before the command's own base
    fit, said in the JSON's notes, and the data checks reported in ``in_data``."""
    import json

    from diffship.diagnose.__main__ import main as diagnose_main

    paths = []
    for r in _nomoto_runs(0.8, n=4):
        paths.append(str(tmp_path / f"{r.name}.csv"))
        r.to_dataframe().to_csv(paths[-1], index=False)
    js = tmp_path / "d.json"
    assert diagnose_main(paths[:3] + ["--validate", paths[3], "--model", "nomoto1", "--effects", "input_delay",
                                      "--correct-data", "--json", str(js), "--quiet"]) == 0
    doc = json.loads(js.read_text())
    assert doc["in_data"]["rudder_timing"]["found"] and abs(doc["in_data"]["rudder_timing"]["value"] - 0.8) < 0.15
    assert any("corrected" in n for n in doc["notes"]) and not doc["selected"]


def test_rate_gyro_zero_error_recovered_and_taken_out():
    """A yaw rate that reads r + 0.05°/s drifts away from the logged heading: recovered to 0.005°/s, judged on the
    held-out runs, taken out by ``corrected``; nothing on the logs as they are."""
    from diffship.diagnose.consistency import rate_consistency

    zz = _nomoto_runs(0.0, n=5, seed=7)
    assert not rate_consistency(zz[:3], zz[3:]).found
    biased = [r.with_channels(r=r["r"] + 0.05 * D) for r in zz]
    f = rate_consistency(biased[:3], biased[3:])
    assert f.found and abs(f.value / D - 0.05) < 0.005 and f.library_effect is None
    assert f"rate_bias b_r = {f.value / D:.3g} ±" in in_data_line({"rate_bias": f})
    fixed = corrected(biased, {"rate_bias": f})
    assert abs(rate_consistency(fixed[:3], fixed[3:]).value) < 0.005 * D
