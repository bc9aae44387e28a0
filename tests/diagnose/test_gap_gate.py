"""The gap gate comes from the data's sample counts: it matches the scatter of E with no
structural error, and a weak effect above that scatter is a gap (a fixed 1.1 left effects with
E 1.06–1.09, significant and closing the gap on every validation run, unattributed).

No simulation of a model: white noise on smooth signals (the noise floor estimated as diagnose
does), and the judgement on given scores."""

from types import SimpleNamespace

import numpy as np

import diffship  # noqa: F401
from diffship.data import Run
from diffship.diagnose import DiagnoseOptions, make_effect
from diffship.diagnose.screen import RefitResult
from diffship.diagnose.where import noise_estimates, structural_gate
from diffship.diagnose.which import Search
from diffship.models import Nomoto1

T = np.arange(0.0, 70.0, 0.1)  # two 70-s zigzag-like runs at 10 Hz for validation, four for training
SIG = {"psi": 0.002, "r": 0.0005}


def _runs(rng, n):
    out = []
    for i in range(n):
        ph = rng.uniform(0, 2 * np.pi)
        clean = {"psi": 0.3 * np.sin(2 * np.pi * T / 35 + ph), "r": 0.02 * np.cos(2 * np.pi * T / 35 + ph)}
        noise = {c: rng.normal(0.0, s, T.size) for c, s in SIG.items()}
        out.append((Run(f"r{i}", T, {c: clean[c] + noise[c] for c in SIG}), noise))
    return out


def test_gate_matches_the_null_scatter_of_E():
    rng = np.random.default_rng(0)
    E2 = []
    for _ in range(150):
        rs = _runs(rng, 6)
        runs = [r for r, _ in rs]
        est = noise_estimates(runs, list(SIG))
        # the model is exact: the validation residual is the noise of the two held-out runs
        ms = {c: np.mean(np.concatenate([nz[c] for _, nz in rs[4:]]) ** 2) for c in SIG}
        E2.append(np.mean([ms[c] / est[c].sigma ** 2 for c in SIG]))
    gate = structural_gate(list(SIG), runs, runs[4:], est)
    sd = float(np.std(E2, ddof=1))
    assert 0.75 < sd / gate.sd_E2 < 1.33, (sd, gate.sd_E2)
    assert 1.03 < gate.value < 1.07  # below the former fixed 1.1 for this much data
    assert np.mean(np.sqrt(E2) >= gate.value) <= 0.02
    # fewer samples, wider gate; a given noise level drops the floor-estimation term
    short = structural_gate(list(SIG), [Run("s", T[:100], {c: np.zeros(100) for c in SIG})] * 6,
                            [Run("s", T[:100], {c: np.zeros(100) for c in SIG})] * 2, est)
    assert short.value > 1.1
    assert structural_gate(list(SIG), runs, runs[4:], None).value < gate.value


def test_weak_effect_above_the_data_gate_is_attributed():
    """Ship input delay, weak: E 1.085 → 1.004 on both validation runs, τ 0.48 ± 0.02 s. Under
    the fixed 1.1 gate (and the fixed ΔE > 0.1) it was only 'possible'; the data's gate is 1.05."""
    rng = np.random.default_rng(1)
    runs = [r for r, _ in _runs(rng, 6)]
    gate = structural_gate(list(SIG), runs, runs[4:], noise_estimates(runs, list(SIG)))
    eff = make_effect(Nomoto1(), "input_delay")
    base = SimpleNamespace(E=1.085, E_runs={"a": 1.10, "b": 1.07})
    s = Search(SimpleNamespace(effects=[eff]), None, base, DiagnoseOptions(), lambda m: None, gate=gate.value)
    rf = RefitResult(("input_delay",), {"tau_d": 0.48}, {"tau_d": 0.018}, {}, 1.0, 5, 0.1, True)
    j = s.judge(rf, base, SimpleNamespace(E=1.004, E_runs={"a": 1.005, "b": 1.003}), ["input_delay"])
    assert j.ok, j.why
    # a null-sized wobble (E 1.03, drop 0.02) is still no gap and no attribution
    null = SimpleNamespace(E=1.03, E_runs={"a": 1.04, "b": 1.02})
    s0 = Search(SimpleNamespace(effects=[eff]), None, null, DiagnoseOptions(), lambda m: None, gate=gate.value)
    j0 = s0.judge(rf, null, SimpleNamespace(E=1.01, E_runs={"a": 1.02, "b": 1.0}), ["input_delay"])
    assert not j0.ok
