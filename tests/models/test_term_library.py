"""The term library's content and what a term does to fossen3's equations of motion.

A term c·φ(u, v, r) in equation j adds M⁻¹ e_j c φ to the accelerations; the monomials that fossen3's
C(ν)ν already carries with mass-tied coefficients (X: v r, Y: u r, N: u v) are terms of their own."""

import jax.numpy as jnp
import numpy as np
import pytest

from diffship.errors import ModelError
from diffship.models import Fossen3
from diffship.models.terms import LIBRARIES, library_terms, monomials, parse_term, term_class, with_terms

# a USV with added masses and no sway–yaw mass coupling (xg = Yrdot = Nvdot = 0): M is diagonal
BASE = Fossen3(m=4935.14, Iz=20928.0, Xudot=-400.0, Yvdot=-700.0, Nrdot=-3000.0)
STATE = jnp.array([0.0, 0.0, 0.3, 4.0, 0.6, -0.15])  # x0, y0, ψ, u, v, r
TAU = jnp.array([4000.0, 300.0, -1500.0])


def _acc(model):
    return np.asarray(model.vector_field(0.0, STATE, TAU))[3:]


@pytest.mark.parametrize("term, value, axis, regressor, mass", [
    ("X_v_r", 2500.0, 0, 0.6 * -0.15, 4935.14 + 400.0),
    ("Y_u_r", -1800.0, 1, 4.0 * -0.15, 4935.14 + 700.0),
    ("N_u_v", 900.0, 2, 4.0 * 0.6, 20928.0 + 3000.0),
    ("N_r_r_r", -8000.0, 2, (-0.15) ** 3, 20928.0 + 3000.0),
    ("Y_v_v_r", -6000.0, 1, 0.6 ** 2 * -0.15, 4935.14 + 700.0),
])
def test_a_coriolis_monomial_is_a_term_of_its_own(term, value, axis, regressor, mass):
    """X_v_r changes the surge acceleration by X_vr·v·r/(m − Xu̇) (and nothing else), etc."""
    d = _acc(with_terms(BASE, [term], {term: value})) - _acc(BASE)
    expect = np.zeros(3)
    expect[axis] = value * regressor / mass
    np.testing.assert_allclose(d, expect, rtol=1e-10, atol=1e-14)


def test_x_vr_equal_to_minus_the_tied_coefficient_cancels_the_centripetal_force():
    """fossen3's surge equation holds +(m − Yv̇)·v·r (from −C(ν)ν); X_vr = −(m − Yv̇) removes it: the
    surge acceleration is then the one at v = r = 0. A model without the term cannot do this."""
    tied = 4935.14 + 700.0
    m = with_terms(BASE, ["X_v_r"], {"X_v_r": -tied})
    still = STATE.at[4].set(0.0).at[5].set(0.0)
    a_turn = float(m.vector_field(0.0, STATE, TAU)[3])
    a_straight = float(BASE.vector_field(0.0, still, TAU)[3])
    np.testing.assert_allclose(a_turn, a_straight, rtol=1e-12)
    # without the term the turn adds (m − Yv̇) v r / (m − Xu̇) = −0.0954 m/s² of centripetal surge acceleration
    np.testing.assert_allclose(float(BASE.vector_field(0.0, STATE, TAU)[3]) - a_straight,
                               tied * 0.6 * -0.15 / (4935.14 + 400.0), rtol=1e-10)


def test_libraries_hold_the_cross_terms_and_not_the_base_duplicates():
    sym, full = set(LIBRARIES["symmetric"]), set(LIBRARIES["all"])
    for t in ("X_v_r", "X_r_r", "Y_u_r", "N_u_v", "N_u_r", "Y_v_v_r", "N_v_r_r", "N_r_r_r", "N_v_ar", "Y_r_ar",
              "X_u_u_u", "X_v_v"):
        assert t in sym, t
    for t in ("Y_v_av", "N_r_ar", "X_u_au", "X_u_u", "X_u", "Y_v", "Y_r", "N_v", "N_r"):  # fossen3's own parameters
        assert t not in full, t
    assert sym < full and len(monomials(3)) == 43 and len(full) == 3 * 43 - 8


def test_symmetric_library_is_the_mirror_invariant_part_of_all():
    """Mirror (v, r) → (−v, −r): a surge term must not change, a sway or yaw term must change sign."""
    rng = np.random.default_rng(0)
    u, v, r = rng.uniform(1, 6, 50), rng.normal(0, 0.5, 50), rng.normal(0, 0.1, 50)
    for name in LIBRARIES["all"]:
        cls = term_class(name)
        a, b = np.asarray(cls.regressor(u, v, r)), np.asarray(cls.regressor(u, -v, -r))
        symmetric = np.allclose(b, a) if cls.equation == "X" else np.allclose(b, -a)
        assert symmetric == (name in LIBRARIES["symmetric"]), name


def test_no_two_regressors_of_an_equation_coincide_on_forward_speed_data():
    """With u > 0 the base's own regressors (X: u, u|u|; Y: v, r, v|v|; N: v, r, r|r|) and the library's are
    linearly independent: the library holds no exact duplicate (a rank drop means one)."""
    rng = np.random.default_rng(1)
    u, v, r = rng.uniform(1, 6, 400), rng.normal(0, 0.5, 400), rng.normal(0, 0.1, 400)
    base = {"X": [u, u * np.abs(u)], "Y": [v, r, v * np.abs(v)], "N": [v, r, r * np.abs(r)]}
    for eq in "XYN":
        cols = base[eq] + [np.asarray(term_class(t).regressor(u, v, r)) for t in LIBRARIES["all"] if t[0] == eq]
        A = np.stack(cols, axis=1)
        A = A / np.linalg.norm(A, axis=0)
        assert np.linalg.matrix_rank(A, tol=1e-9) == A.shape[1], eq


def test_expressions_reduce_to_the_one_name():
    assert parse_term("X: v*r") == "X_v_r" and parse_term("N: |v|^2") == "N_v_v"
    assert parse_term("N: |r|^3") == "N_r_r_ar" and library_terms("X: v r, Y:u r") == ("X_v_r", "Y_u_r")
    with pytest.raises(ModelError, match="same function as N_v_v"):
        parse_term("N_av_av")
