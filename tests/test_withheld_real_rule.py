"""The 'found' rule of ``benchmarks/withheld_real.py`` (real logs with injected effects): pure
bookkeeping on recorded rows, no fit. A selection is not enough — the attributed size, minus the
none row's determined estimate, must be within 30 % of the injected one."""

import math
import sys
from pathlib import Path

import pytest

ROOT = str(Path(__file__).resolve().parents[1])
sys.path.insert(0, ROOT)
try:
    from benchmarks import withheld_real as wr
finally:
    sys.path.remove(ROOT)

D = math.pi / 180
VC = wr.injected_vector("water_drift")  # 0.02 m/s towards 0.8 rad


def _row(scenario, selected, ranking_params, final_params, estimates, stderr=0.001):
    exp = wr.SCENARIOS[scenario][0]
    return {"scenario": scenario, "expected": exp, "first_selected": selected.split("+")[0] if selected else "none",
            "selected": selected, "params": final_params, "estimates": estimates,
            "ranking": {exp: {"params": ranking_params, "validation_gain": 0.3, "verdict": "attributed"}}}


def test_a_current_selected_first_with_its_size_is_found_and_one_with_the_wrong_size_is_not():
    est = {"current": {"value": [float(VC[0]), float(VC[1])], "half95": [0.002, 0.002], "source": "single refit"}}
    good = _row("water_drift", "current+damping_vr", {"Vcx": VC[0] * 0.9, "Vcy": VC[1] * 1.1},
                {"Vcx": -0.02, "Vcy": 0.01}, est)
    j = wr.judge(good, None)
    assert j["found"] and j["selected_first"] and j["rel_error"] < 0.15  # the attributed (first-step) size
    assert j["rel_error_final"] > 1.0  # the final model's current is reported, not hidden
    half = _row("water_drift", "current", {"Vcx": VC[0] * 0.5, "Vcy": VC[1] * 0.5}, {"Vcx": 0.0, "Vcy": 0.0}, est)
    assert not wr.judge(half, None)["found"]  # selected, 50 % off: not found
    missed = _row("water_drift", "damping_vr", {"Vcx": VC[0], "Vcy": VC[1]}, {}, est)
    assert not wr.judge(missed, None)["found"]  # right size, never selected: not found


def test_the_none_rows_estimate_is_subtracted_only_where_it_is_determined():
    row = _row("clock_offset", "damping_vr+input_delay", {"tau_d": 0.7}, {"tau_d": 0.8},
               {"input_delay": {"value": [0.8], "half95": [0.04], "source": "final model"}})
    determined = {"estimates": {"input_delay": {"value": [0.3], "half95": [0.04]}}}
    undetermined = {"estimates": {"input_delay": {"value": [0.3], "half95": [math.inf]}}}
    assert wr.judge(row, determined)["delta"] == pytest.approx([0.5])  # 0.8 − 0.3: the logs' own 0.3 s
    assert wr.judge(row, determined)["found"]
    j = wr.judge(row, undetermined)
    assert j["delta"] == pytest.approx([0.8]) and not j["found"]  # 60 % off: not found


def test_a_rudder_zero_absorbed_by_the_base_delta0_is_counted_apart():
    row = _row("rudder_zero", "damping_vr", {"Y0": 1.0, "N0": -12.0}, {},
               {"base:rudder_offset": {"value": [1.02 * D + 0.0004], "half95": [0.003], "source": "base"}})
    none = {"estimates": {"base:rudder_offset": {"value": [0.0004], "half95": [0.003]}}}
    j = wr.judge(row, none)
    assert j["found_in_base"] and not j["found"]
    assert j["delta_in_base"] == pytest.approx([1.02], rel=1e-6)  # degrees
