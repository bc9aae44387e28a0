"""The independent discovery truths (benchmarks/independent/discovery_truths.py): physics, visibility of every
term on the held-out runs, the record form and term names diffship reads."""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from benchmarks.independent import discovery_truths as D  # noqa: E402
from diffship.models.terms import LIBRARIES, parse_term  # noqa: E402

P = D.PARAMS


def test_without_damping_and_forcing_kinetic_energy_is_conserved():
    """C_RB and C_A are skew-symmetric: d/dt ½νᵀMν = 0 with D = 0, τ = 0, no extra terms."""
    p = {**P, **{k: 0.0 for k in ("Xu", "Xuu", "Yv", "Yvv", "Nv", "Nr", "Nrr")}}
    x = np.array([0.0, 0.0, 0.4, 3.0, 1.2, -0.3])
    xd = D._rhs(p, {}, x, np.zeros(3))
    mass = np.array([P["m"] - P["Xudot"], P["m"] - P["Yvdot"], P["Iz"] - P["Nrdot"]])
    assert abs(float(np.sum(mass * x[3:] * xd[3:]))) < 1e-9 * float(np.sum(mass * x[3:] ** 2))


def test_an_extra_term_adds_its_force_over_the_equations_mass():
    x = np.array([0.0, 0.0, 0.0, 3.5, 0.8, 0.2])
    d = D._rhs(P, {"X_v_r": -3000.0, "N_r_r_r": -8000.0}, x, np.zeros(3)) - D._rhs(P, {}, x, np.zeros(3))
    np.testing.assert_allclose(d[3:], [-3000.0 * 0.8 * 0.2 / (P["m"] - P["Xudot"]), 0.0,
                                       -8000.0 * 0.2 ** 3 / (P["Iz"] - P["Nrdot"])], rtol=1e-12)


def test_truths_use_symmetric_library_names_and_one_null():
    ts = D.truths()
    assert sum(not t.terms for t in ts) == 1 and sum(2 <= len(t.terms) <= 4 for t in ts) >= 5
    for t in ts:
        for name in t.terms:
            assert parse_term(name) == name and name in LIBRARIES["symmetric"], name
    every = {n for t in ts for n in t.terms}
    assert {"X_v_r", "Y_v_v_r", "N_v_r_r", "N_r_r_r"} <= every


@pytest.mark.slow  # CI time budget: run with python -m pytest -m slow
def test_every_term_moves_the_held_out_heading_by_several_noise_levels():
    """The weakest truth (the Coriolis-carried monomials): removing any one term changes the noise-free
    held-out heading by at least 3× the heading noise (0.5°) in RMS on some held-out run."""
    truth = next(t for t in D.truths() if t.name == "coriolis_monomials")
    eff = D.term_effects(truth, duration=240.0)
    for name, per_run in eff.items():
        assert max(per_run.values()) > 3 * D.NOISE["psi"], (name, per_run)


def test_records_have_the_robust_truths_form_and_the_stated_noise():
    truth = D.truths()[-1]
    out = D.runs(truth, duration=60.0)
    assert len(out["train"]) == 4 and len(out["held_out"]) == 2
    rec = out["held_out"][0]
    assert {"name", "time", "x0", "y0", "psi", "u", "v", "r", "tau_x", "tau_y", "tau_z", "truth"} == set(rec)
    assert rec["truth"]["terms"] == {} and rec["time"][1] - rec["time"][0] == pytest.approx(0.1)
    t, xs, _ = D.simulate("pullout", {}, 100 * truth.seed + 10, 60.0)
    err = rec["psi"] - xs[:, 2]
    assert 0.8 * D.NOISE["psi"] < np.std(err) < 1.2 * D.NOISE["psi"] and abs(err[0]) > 0.0
