import math

import jax.numpy as jnp
import numpy as np
import pytest

from diffship.errors import ModelError
from diffship.params import Param, ParamSpec, parse_assignments


def _spec():
    return ParamSpec((
        Param("a", 2.0, scale=1.0),
        Param("b", 3.0, lower=0.0, scale=5.0),
        Param("c", -250.0, upper=0.0, scale=100.0),
        Param("d", 0.3, lower=0.0, upper=1.0),
        Param("e", 7.0, free=False),
    ))


def test_scaled_space_round_trip_and_bounds():
    spec = _spec()
    z = spec.to_z()
    assert z.shape == (4,)
    back = np.asarray(spec.from_z(jnp.asarray(z)))
    np.testing.assert_allclose(back, [2.0, 3.0, -250.0, 0.3], rtol=1e-12)
    # any z maps inside the bounds: the sign constraints hold by construction
    wild = np.asarray(spec.from_z(jnp.asarray([40.0, -40.0, 40.0, -40.0])))
    assert wild[1] > 0 and wild[2] < 0 and 0 <= wild[3] <= 1
    # derivative used for standard errors matches finite differences
    h = 1e-6
    fd = (np.asarray(spec.from_z(jnp.asarray(z + h))) - np.asarray(spec.from_z(jnp.asarray(z - h)))) / (2 * h)
    np.testing.assert_allclose(spec.dtheta_dz(z), fd, rtol=1e-6)


def test_fix_free_and_full_values():
    spec = _spec().fix({"a": 5.0}).free(["e"])
    assert spec.free_names == ("b", "c", "d", "e")
    full = np.asarray(spec.full_values(jnp.asarray(spec.to_z()), jnp.asarray([5.0, 3.0, -250.0, 0.3, 7.0])))
    np.testing.assert_allclose(full, [5.0, 3.0, -250.0, 0.3, 7.0])


def test_bad_parameters_are_named():
    with pytest.raises(ModelError, match="unknown parameter 'zz'"):
        _spec()["zz"]
    with pytest.raises(ModelError, match="c.*bounds"):
        _spec().with_values({"c": 10.0}).to_z()
    with pytest.raises(ModelError, match="scale"):
        Param("x", 1.0, scale=0.0)
    with pytest.raises(ModelError, match="NAME=VALUE"):
        parse_assignments(["T1"])
    with pytest.raises(ModelError, match="not a number"):
        parse_assignments(["T1=abc"])
    assert parse_assignments(["T1=2.5", " K = 0.1"]) == {"T1": 2.5, "K": 0.1}
    assert math.isinf(_spec()["a"].upper)


def test_fix_refuses_a_value_outside_the_bounds():
    spec = ParamSpec((Param("K", 0.5), Param("T1", 5.0, lower=0.0, unit="s")))
    for bad, words in ((-5.0, "-5 s"), (0.0, "on a bound"), (math.nan, "not finite"), ("x", "not a number")):
        with pytest.raises(ModelError, match="parameter T1: fixed value") as e:
            spec.fix({"T1": bad})
        assert words in str(e.value)
    assert spec.fix({"T1": 3.0})["T1"].free is False
    with pytest.raises(ModelError, match="parameter T1: fixed value -5"):
        spec.with_values({"T1": -5.0}).fix(["T1"])
    held = ParamSpec((Param("Xudot", 0.0, upper=0.0, held_bounds=(0.0,)),))
    assert held.fix({"Xudot": 0.0})["Xudot"].value == 0.0
