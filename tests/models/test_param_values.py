"""A model holds only valid parameter values: one finite number each. The declared bounds are the fit's (what a fit
may estimate or hold fixed, :meth:`diffship.params.ParamSpec.fix`), not the model's: a model may hold a
course-unstable ship's T1 < 0 or a destabilising term, so that a simulation can show what such a ship does."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from diffship.errors import ModelError
from diffship.models import Fossen3, Nomoto1


@pytest.mark.parametrize("values, words", [
    ({"T1": float("nan")}, ("T1", "nan", "not finite")),
    ({"K": float("inf")}, ("K", "inf", "not finite")),
    ({"T1": "x"}, ("T1", "'x'", "not a number")),
])
def test_with_params_refuses_bad_values(values, words):
    with pytest.raises(ModelError) as e:
        Nomoto1().with_params(values)
    assert all(w in str(e.value) for w in words), str(e.value)


def test_a_model_may_hold_values_beyond_the_fits_bounds_but_a_fit_may_not_fix_them():
    m = Nomoto1().with_params({"T1": -5.0})  # a course-unstable ship, to be simulated
    assert float(m.T1) == -5.0 and float(Fossen3().with_params({"Xudot": 1.0}).Xudot) == 1.0
    for name, value in (("T1", -5.0), ("T1", 0.0)):  # an open lower bound: 0 itself is refused
        with pytest.raises(ModelError, match=rf"parameter {name}: fixed value {value:g} s is not strictly inside"):
            Nomoto1().spec().fix({name: value})
    with pytest.raises(ModelError, match="parameter m: fixed value -1 kg"):
        Fossen3().spec().fix({"m": -1.0})


def test_a_declared_value_on_its_bound_may_be_held():
    """Fossen 3's zero added masses sit on their sign bound: a fit may hold them fixed there (and starts inside)."""
    m = Fossen3()
    assert float(m.Xudot) == 0.0
    assert m.spec().fix({"Xudot": 0.0})["Xudot"].value == 0.0


@pytest.mark.parametrize("theta, given", [(np.array([1.0]), "1 parameter value"), (np.arange(1.0, 6.0), "5 parameter"),
                                          (np.float64(1.0), "a single number")])
def test_with_params_array_needs_one_value_per_parameter(theta, given):
    with pytest.raises(ModelError, match=f"{given}.*K, T1, delta0"):
        Nomoto1().with_params(theta)


def test_with_params_array_values_checked_and_traced_values_not():
    with pytest.raises(ModelError, match="T1"):
        Nomoto1().with_params(np.array([0.5, np.nan, 0.0]))
    m = Nomoto1()
    out = jax.jit(lambda th: m.with_params(th).T1)(jnp.array([0.5, np.nan, 0.0]))  # traced: not checked
    assert np.isnan(float(out))
    assert float(jax.vmap(lambda t1: m.with_params({"T1": t1}).T1)(jnp.array([-1.0, 2.0]))[1]) == 2.0


def test_constructor_checks_values():
    with pytest.raises(ModelError, match="T1: model value nan"):
        Nomoto1(T1=float("nan"))
    assert float(Nomoto1(T1=7.0).T1) == 7.0 and float(Nomoto1(T1=-5.0).T1) == -5.0
