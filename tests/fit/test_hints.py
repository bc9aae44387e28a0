"""What a report suggests when no fit is usable (:mod:`diffship.fit.hints`)."""

from __future__ import annotations

import math

from diffship.fit.hints import held_reference_coefficients, next_steps
from diffship.models import Nomoto1
from diffship.models.mmg import kvlcc2_mmg
from diffship.usability import RunProblem


def test_held_reference_coefficients_are_the_fixed_ones_with_a_reference_value():
    model = kvlcc2_mmg()
    spec = model.spec()
    held = held_reference_coefficients(model, spec)
    assert held and set(held) <= set(spec.fixed_names)
    assert "Yvvv" in held and "Nvvv" in held  # hull coefficients the default free set leaves at the reference
    assert not set(held) & set(spec.free_names)
    # freeing them all leaves nothing to suggest
    assert held_reference_coefficients(model, spec.free(held)) == []
    # another vessel's particulars: the reference set is no prior for it, so nothing is suggested
    other = spec.fix({"m": 2.0 * spec.values()["m"]})
    assert held_reference_coefficients(model, other) == []


def test_next_steps_name_the_options_and_why():
    model = kvlcc2_mmg()
    spec = model.spec()
    late = RunProblem("Z_35_05", "psi", -20.5, 65.8, "training")
    early = RunProblem("Z_20_05", "psi", -5.0, math.nan, "training")  # not followed from the start: no horizon helps
    held_out = RunProblem("Z_10_10_P", "psi", -5.0, 30.0, "validation")
    steps = next_steps(model, spec, [late, early, held_out], horizon=None, priors=True, free_hydrodynamic=False)
    assert len(steps) == 2
    assert steps[0].startswith("--free-hydrodynamic: ") and "Yvvv" in steps[0]
    assert steps[1].startswith("--horizon 60: ") and "Z_35_05" in steps[1] and "t = 66 s" in steps[1]
    # already given: not suggested again; --no-prior: no reference prior to hold them
    assert next_steps(model, spec, [late], horizon=60.0, priors=True, free_hydrodynamic=True) == []
    assert next_steps(model, spec, [], horizon=None, priors=False, free_hydrodynamic=False) == []
    # a longer horizon than the run is followed for is shortened
    assert next_steps(model, spec, [late], horizon=100.0, priors=True,
                      free_hydrodynamic=True)[0].startswith("--horizon 60: ")


def test_a_model_without_a_reference_set_suggests_no_freeing():
    model = Nomoto1()
    assert held_reference_coefficients(model, model.spec()) == []
