"""The model interface: parameters declared once, the shared 3-DOF mass solve, and the
declarative equation-error form (the layering itself is checked in tests/test_architecture.py)."""

import dataclasses
from typing import ClassVar

import jax.numpy as jnp
import numpy as np
import pytest

from diffship.models import (
    MMG,
    MODELS,
    AbstractModel,
    Fossen3,
    Nomoto1,
    VMMAbkowitz,
    VMMLinear,
    VMMSimple,
    get_model,
    param,
    scalar,
)
from diffship.models.vmm import _POWERS
from diffship.params import Param

# -- parameters declared once -------------------------------------------------------------
class _Toy(AbstractModel):
    name: ClassVar[str] = "toy"
    a: jnp.ndarray = param(2.0, lower=0.0, scale=3.0, unit="s", description="a time")
    offset: jnp.ndarray = scalar(1.0)  # a plain field, not a parameter
    b: jnp.ndarray = param(-1.0, free=False)


def test_params_derived_from_the_fields():
    assert _Toy.PARAMS == (Param("a", 2.0, lower=0.0, scale=3.0, unit="s", description="a time"),
                           Param("b", -1.0, free=False))
    toy = _Toy(a=5.0)
    assert toy.PARAMS is _Toy.PARAMS and toy.param_names == ("a", "b")
    assert toy.spec()["a"].value == 5.0 and toy.param_values() == {"a": 5.0, "b": -1.0}
    assert float(toy.with_params({"b": 3.0}).b) == 3.0 and toy.theta().dtype == jnp.float64


@pytest.mark.parametrize("name", sorted(MODELS))
def test_every_param_is_a_field_with_its_default(name):
    model = get_model(name)
    fields = {f.name: f for f in dataclasses.fields(model)}
    for p in type(model).PARAMS:
        assert "param" in fields[p.name].metadata, p.name
    if name != "fossen3_waterjet":  # built by usv_standard, defaults are the class's
        assert model.spec() == type(model)().spec()


def test_vmm_members_select_their_polynomial():
    for cls in (VMMLinear, VMMSimple, VMMAbkowitz):
        hydro = tuple(p.name for p in cls.PARAMS if p.name in _POWERS)
        assert hydro == cls.X_TERMS + cls.Y_TERMS + cls.N_TERMS
        assert cls().param_names[:12] == ("m", "Iz", "xG", "L", "rho", "U0", "XT",
                                          "Xudot", "Yvdot", "Yrdot", "Nvdot", "Nrdot")
    assert "Xvv" not in VMMLinear().param_names and "Xvv" in VMMSimple().param_names


def test_explicit_params_class_variable_still_overrides():
    class Explicit(_Toy):
        PARAMS: ClassVar[tuple[Param, ...]] = (Param("a", 7.0),)

    assert Explicit().param_names == ("a",) and _Toy().param_names == ("a", "b")


# -- one 3-DOF mass solve -----------------------------------------------------------------
@pytest.mark.parametrize("model", [Fossen3(Xudot=-300.0, Yvdot=-900.0, Yrdot=-50.0, Nvdot=80.0, Nrdot=-4e3, xg=0.4),
                                   VMMAbkowitz(), MMG()], ids=["fossen3", "vmm", "mmg"])
def test_solve_mass_inverts_mass_matrix(model):
    rng = np.random.default_rng(1)
    M = np.asarray(model.mass_matrix())
    assert M[0, 1] == M[0, 2] == M[1, 0] == M[2, 0] == 0.0
    for _ in range(5):
        b = rng.normal(size=3) * np.abs(np.diag(M))
        np.testing.assert_allclose(M @ np.asarray(model.solve_mass(jnp.asarray(b))), b, rtol=1e-12)


def test_vector_fields_use_the_mass_solve():
    """VMM and MMG accelerations are M⁻¹ times their generalised forces (dense check)."""
    x = jnp.asarray([1.0, 2.0, 0.3, 7.0, -0.3, 0.01])
    m = VMMSimple()
    inp = jnp.asarray([0.1, 5e5])
    xd = np.asarray(m.vector_field(0.0, x, inp))
    Xp, Yp, Np = m.hydro_prime(x[3:], inp)
    q = 0.5 * float(m.rho) * float(m.L) ** 2 * float(m.speed(x[3], x[4])) ** 2
    u, v, r = (float(a) for a in x[3:])
    rhs = np.array([q * float(Xp) + float(m.m) * (v * r + float(m.xG) * r * r), q * float(Yp) - float(m.m) * u * r,
                    q * float(m.L) * float(Np) - float(m.m) * float(m.xG) * u * r])
    np.testing.assert_allclose(xd[3:], np.linalg.solve(np.asarray(m.mass_matrix()), rhs), rtol=1e-10)


def test_fossen3_vector_field_is_the_matrix_form():
    """The component form the integrator runs (:meth:`Fossen3.vector_field_parts`, stacked) is
    η̇ = R(ψ)ν, ν̇ = M⁻¹(τ − C(ν)ν − D(ν)ν) with the dense matrices, also with the water-jet map."""
    from diffship.models.actuators import WaterJet

    rng = np.random.default_rng(2)
    for m, inp in ((Fossen3(Xudot=-300.0, Yvdot=-900.0, Yrdot=-50.0, Nvdot=80.0, Nrdot=-4e3, xg=0.4, Yr=30.0),
                    jnp.asarray([2000.0, -300.0, 800.0])),
                   (Fossen3(actuator=WaterJet()), jnp.asarray([0.2, 1500.0]))):
        for _ in range(3):
            x = jnp.asarray(np.r_[rng.normal(size=2), rng.uniform(-3, 3), 2.0 + rng.normal(), rng.normal(size=2) * 0.3])
            nu = np.asarray(x[3:])
            psi = float(x[2])
            R = np.array([[np.cos(psi), -np.sin(psi), 0.0], [np.sin(psi), np.cos(psi), 0.0], [0.0, 0.0, 1.0]])
            tau = np.asarray(m.actuator(inp, x[3:]))
            rhs = tau - np.asarray(m.coriolis_matrix(x[3:])) @ nu - np.asarray(m.damping_matrix(x[3:])) @ nu
            expect = np.r_[R @ nu, np.linalg.solve(np.asarray(m.mass_matrix()), rhs)]
            np.testing.assert_allclose(np.asarray(m.vector_field(0.0, x, inp)), expect, rtol=1e-11, atol=1e-11)
            parts = m.vector_field_parts(0.0, tuple(x[i] for i in range(6)), tuple(inp[i] for i in range(inp.size)))
            np.testing.assert_array_equal(np.asarray(jnp.stack(parts)), np.asarray(m.vector_field(0.0, x, inp)))


# -- equation-error form --------------------------------------------------------------------
def test_equation_error_forms_are_declared():
    for name in ("nomoto1", "nomoto2", "fossen3", "fossen3_waterjet", "vmm_linear", "fossen6", "decay1", "decay2"):
        m = get_model(name)
        assert m.EQUATIONS and m.EQUATION_CHANNELS and m.EQUATION_ORDER in (1, 2), name
    assert not MMG.EQUATIONS


def test_nomoto1_regression_is_exact_for_its_own_equation():
    """The linear form ṙ = a r + b δ + c maps back to K, T1, δ0 that zero the equation residual."""
    truth = Nomoto1(K=0.3, T1=6.0, delta0=0.02)
    rng = np.random.default_rng(0)
    z, u = rng.normal(size=(50, 1)), rng.normal(size=(50, 1))
    zd = (0.3 * (u + 0.02) - z) / 6.0
    form = truth.regressors(jnp.asarray(z), jnp.asarray(zd), jnp.zeros_like(zd), jnp.asarray(u))["first_order"]
    c, *_ = np.linalg.lstsq(np.asarray(form.A), np.asarray(form.y), rcond=None)
    got = truth.from_regression({"first_order": dict(zip(form.names, c))})
    assert got == pytest.approx({"K": 0.3, "T1": 6.0, "delta0": 0.02})
    e = truth.equation_residual(jnp.asarray(z[0]), jnp.asarray(zd[0]), jnp.zeros(1), jnp.asarray(u[0]))
    assert abs(float(e[0])) < 1e-15
