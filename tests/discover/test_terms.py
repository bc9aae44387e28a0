"""The term library: names, expressions, null value, the added force, and fit files that record terms."""

import json

import jax.numpy as jnp
import numpy as np
import pytest

from diffship.errors import ModelError
from diffship.fitfile import load_fit
from diffship.models import Fossen3
from diffship.models.terms import LIBRARIES, library_terms, parse_term, term_label, terms_of, with_terms


def test_names_and_expressions_agree():
    assert parse_term("N: v*r") == "N_v_r"
    assert parse_term("Y:r|r|") == "Y_r_ar"
    assert parse_term("N: v^2 r") == "N_v_v_r"
    assert parse_term("N_v_ar") == "N_v_ar"
    assert term_label("N_v_ar") == "N: v|r|"
    assert set(LIBRARIES["symmetric"]) < set(LIBRARIES["all"])
    assert library_terms("N_v_r, Y: r|r|, N_v_r") == ("N_v_r", "Y_r_ar")


@pytest.mark.parametrize("bad", ["N_q_r", "Z_v_r", "N: v*q", "N_r_v"])
def test_unknown_term_is_one_clear_error(bad):
    with pytest.raises(ModelError, match="term"):
        parse_term(bad)


def test_null_value_is_the_base_model_and_a_term_is_its_force():
    base = Fossen3()
    x, u = jnp.array([0.0, 0.0, 0.3, 4.0, 0.5, 0.2]), jnp.array([100.0, 50.0, 200.0])
    m0 = with_terms(base, ["N_v_ar", "Y_r_ar"])
    np.testing.assert_allclose(m0.vector_field(0.0, x, u), base.vector_field(0.0, x, u), atol=1e-12)
    m1 = m0.with_params({"N_v_ar": 1000.0})
    d = np.asarray(m1.vector_field(0.0, x, u) - base.vector_field(0.0, x, u))
    expect = np.asarray(base.solve_mass(jnp.array([0.0, 0.0, 1000.0 * 0.5 * 0.2])))
    np.testing.assert_allclose(d[3:], expect, rtol=1e-10)
    assert terms_of(m1) == ("N_v_ar", "Y_r_ar") and "N_v_ar" in m1.param_names


def test_fit_file_with_terms_is_rebuilt(tmp_path):
    m = with_terms(Fossen3(), ["N_v_ar"], {"N_v_ar": 2500.0})
    doc = {"schema": "diffship.fit/1", "model": {"name": m.name, "registry": "fossen3", "terms": ["N_v_ar"],
                                                  "inputs": list(m.input_names)},
           "params": m.param_values(), "integrator": {"name": "rk4", "options": {}}}
    p = tmp_path / "fit.json"
    p.write_text(json.dumps(doc))
    fit = load_fit(p)
    assert terms_of(fit.model) == ("N_v_ar",) and fit.model.param_values()["N_v_ar"] == 2500.0


def test_a_structure_within_the_whole_library_is_the_structure_alone():
    """discover simulates every structure with the all-terms model, the other terms at zero (one compiled
    simulation for all): its vector field equals the structure's own model's, term for term."""
    base = Fossen3()
    terms = library_terms("symmetric")
    vals = {"Y_v_v_r": -8000.0, "N_v_r_r": 12000.0}
    own = with_terms(base, list(vals), vals)
    whole = with_terms(base, terms).with_params(vals)
    rng = np.random.default_rng(0)
    for _ in range(5):
        x = jnp.asarray(np.r_[rng.normal(size=3), 4.0 + rng.normal(), rng.normal(0, 0.5, 2)])
        u = jnp.asarray(rng.normal(0, 300.0, 3))
        np.testing.assert_array_equal(np.asarray(whole.vector_field(0.0, x, u)), np.asarray(own.vector_field(0.0, x, u)))


def test_term_scales_make_a_unit_explain_a_tenth_of_the_force():
    """A term's scale is a tenth of its equation's force level over its regressor's RMS: one scale unit of any
    term carries the same share of the force, whatever its units."""
    from diffship.data import Run
    from diffship.discover.discovery import term_scales
    from diffship.models.terms import term_class

    t = np.linspace(0.0, 100.0, 1001)
    run = Run("r", t, {"u": 4.0 + 0.5 * np.sin(0.1 * t), "v": 0.3 * np.sin(0.2 * t), "r": 0.1 * np.cos(0.15 * t)})
    level = {"X": 200.0, "Y": 800.0, "N": 5000.0}
    sc = term_scales([run], ["X_v_r", "N_r_r_r", "Y_v_v_r"], level)
    for name, s in sc.items():
        cls = term_class(name)
        force = s * np.asarray(cls.regressor(run["u"], run["v"], run["r"]))
        assert np.sqrt(np.mean(force ** 2)) == pytest.approx(0.1 * level[cls.equation], rel=1e-9)
