"""The real SSPA zigzag (bundled): nomoto2 by output error against nomoto1 and equation error.

Seed 001 found the second-order Nomoto model "not an improvement" with equation error on this
run; by output error it is, and the first-order fit reproduces the seed's K ≈ 0.74, T ≈ 1.57 s.
"""

import pytest

from diffship.data import example_runs
from diffship.fit import fit_both
from diffship.metrics import evaluate
from diffship.models import Nomoto1, Nomoto2


@pytest.fixture(scope="module")
def sspa():
    return [r.resample(0.1) for r in example_runs("sspa_zigzag")]


@pytest.fixture(scope="module")
def fits(sspa):
    out = {}
    for cls in (Nomoto1, Nomoto2):
        res = fit_both(cls(), sspa)
        out[cls.name] = {m: (r, evaluate(r.model, sspa, r.initial_states if m == "output_error" else None))
                         for m, r in res.items()}
    return out


def test_nomoto1_matches_seed_equation_error(fits):
    ee = fits["nomoto1"]["equation_error"][0]
    assert ee.params["K"] == pytest.approx(0.74, abs=0.02)
    assert ee.params["T1"] == pytest.approx(1.57, abs=0.05)


def test_nomoto2_output_error_has_lowest_heading_rmse(fits):
    oe2 = fits["nomoto2"]["output_error"][1].rmse["psi"]
    oe1 = fits["nomoto1"]["output_error"][1].rmse["psi"]
    ee2 = fits["nomoto2"]["equation_error"][1].rmse["psi"]
    assert fits["nomoto2"]["output_error"][0].converged
    assert oe2 < 0.8 * oe1, (oe2, oe1)
    assert oe2 < ee2, (oe2, ee2)
    assert oe2 < 0.015  # rad: better than 0.9° over the whole 41 s zigzag
