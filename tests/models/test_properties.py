"""Structural properties of the rigid-body + hydrodynamic matrices, over many random states.

Hypothesis-style: random velocities (and random physical parameter sets) drawn with NumPy;
every property must hold for all draws.

* C(ν) skew-symmetric, hence νᵀC(ν)ν = 0 (Coriolis–centripetal forces do no work);
* D(ν) dissipative: νᵀD(ν)ν > 0 for ν ≠ 0 when every damping coefficient is negative;
* M symmetric positive definite (Fossen3 when Y_ṙ = N_v̇);
* component forms (used in the vector fields) equal the matrix products;
* with no damping and no restoring forces, kinetic energy ½νᵀMν is conserved by the 6-DOF model.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from diffship.models import Fossen3, Fossen6
from diffship.simulate import simulate

N_DRAWS = 50
rng = np.random.default_rng(20240611)

# jitted once per model structure (parameter values are traced), so the many draws are cheap
_C = jax.jit(lambda m, nu: (m.coriolis_matrix(nu), m.coriolis_vector(nu)))
_D = jax.jit(lambda m, nu: (m.damping_matrix(nu), m.damping_vector(nu)))
_M = jax.jit(lambda m, b: (m.mass_matrix(), m.solve_mass(b)))


def _fossen3_draw(r):
    Yrdot = r.uniform(-500, 500)
    return Fossen3(
        m=r.uniform(1e3, 1e4), Iz=r.uniform(1e4, 5e4), xg=r.uniform(-1, 1),
        Xudot=-r.uniform(0, 1e3), Yvdot=-r.uniform(0, 5e3), Yrdot=Yrdot, Nvdot=Yrdot, Nrdot=-r.uniform(0, 2e4),
        Xu=-r.uniform(1, 100), Yv=-r.uniform(10, 500), Nr=-r.uniform(100, 2e3),
        Yr=r.uniform(-50, 50), Nv=r.uniform(-50, 50),
        Xuu=-r.uniform(1, 300), Yvv=-r.uniform(1, 3e3), Nrr=-r.uniform(1, 5e3),
    )


def _fossen6_draw(r, dissipative=True):
    neg = (lambda lo, hi: -r.uniform(lo, hi)) if dissipative else (lambda lo, hi: r.uniform(-hi, hi))
    kw = dict(
        m=r.uniform(5, 50), Ix=r.uniform(0.1, 2), Iy=r.uniform(0.1, 2), Iz=r.uniform(0.1, 2),
        xg=r.uniform(-0.05, 0.05), yg=r.uniform(-0.05, 0.05), zg=r.uniform(-0.05, 0.05),
        xb=r.uniform(-0.05, 0.05), yb=r.uniform(-0.05, 0.05), zb=r.uniform(-0.05, 0.05),
        Xudot=-r.uniform(0, 20), Yvdot=-r.uniform(0, 20), Zwdot=-r.uniform(0, 30),
        Kpdot=-r.uniform(0, 0.5), Mqdot=-r.uniform(0, 0.5), Nrdot=-r.uniform(0, 0.5),
    )
    for n in ("Xu", "Yv", "Zw"):
        kw[n] = neg(1, 50)
    for n in ("Kp", "Mq", "Nr"):
        kw[n] = neg(0.1, 2)
    for n in ("Xuu", "Yvv", "Zww"):
        kw[n] = neg(10, 300)
    for n in ("Kpp", "Mqq", "Nrr"):
        kw[n] = neg(0.1, 3)
    return Fossen6(**kw, rigid_body_cg=True)


def _nu(r, n):
    scale = np.array([3.0, 1.0, 1.0, 0.5, 0.5, 0.5][:n])
    return r.normal(size=n) * scale * r.uniform(0.01, 3.0)


@pytest.mark.parametrize("kind", ["fossen3", "fossen6"])
def test_coriolis_skew_and_workless(kind):
    draw, n = (_fossen3_draw, 3) if kind == "fossen3" else (_fossen6_draw, 6)
    for _ in range(N_DRAWS):
        model = draw(rng)
        nu = _nu(rng, n)
        C, Cnu = (np.asarray(a) for a in _C(model, jnp.asarray(nu)))
        scale = np.abs(C).max() + 1e-12
        assert np.abs(C + C.T).max() <= 1e-12 * scale
        assert abs(nu @ C @ nu) <= 1e-10 * scale * (nu @ nu)
        assert np.allclose(C @ nu, Cnu, rtol=1e-10, atol=1e-10 * scale)


@pytest.mark.parametrize("kind", ["fossen3", "fossen6"])
def test_damping_dissipative(kind):
    draw, n = (_fossen3_draw, 3) if kind == "fossen3" else (_fossen6_draw, 6)
    for _ in range(N_DRAWS):
        model = draw(rng)
        nu = _nu(rng, n)
        D, Dnu = (np.asarray(a) for a in _D(model, jnp.asarray(nu)))
        if kind == "fossen3":
            # the sway–yaw coupling Yr, Nv is bounded by the diagonal in these draws, so D + Dᵀ > 0
            assert np.linalg.eigvalsh(D + D.T).min() > 0
        assert nu @ D @ nu > 0
        assert np.allclose(D @ nu, Dnu, rtol=1e-12, atol=1e-12)


def test_damping_not_dissipative_when_a_coefficient_is_positive():
    """The property test can fail: a positive (destabilising) linear term gives νᵀDν < 0 at low speed."""
    model = Fossen6(Xu=+20.0)
    nu = np.array([0.01, 0, 0, 0, 0, 0])
    assert nu @ np.asarray(model.damping_matrix(jnp.asarray(nu))) @ nu < 0


@pytest.mark.parametrize("kind", ["fossen3", "fossen6"])
def test_mass_matrix_spd_and_solve(kind):
    draw, n = (_fossen3_draw, 3) if kind == "fossen3" else (_fossen6_draw, 6)
    for _ in range(N_DRAWS):
        model = draw(rng)
        b = rng.normal(size=n)
        M, x = (np.asarray(a) for a in _M(model, jnp.asarray(b)))
        assert np.allclose(M, M.T, rtol=0, atol=1e-12 * np.abs(M).max())
        assert np.linalg.eigvalsh(M).min() > 0
        assert np.allclose(M @ x, b, rtol=1e-9, atol=1e-9 * np.abs(b).max())
        if kind == "fossen6":
            assert np.allclose(np.asarray(model.mass_times(jnp.asarray(b))), M @ b, rtol=1e-12, atol=1e-12)


def test_fossen3_mass_matrix_not_symmetric_when_cross_terms_differ():
    M = np.asarray(Fossen3(Yrdot=-100.0, Nvdot=300.0).mass_matrix())
    assert not np.allclose(M, M.T)


def test_fossen6_fast_path_equals_full_rigid_body_when_cg_at_origin():
    """The default (rigid_body_cg=False) component forms equal the general ones for r_g = 0."""
    for _ in range(10):
        full = _fossen6_draw(rng)
        full = Fossen6(**{**full.param_values(), "xg": 0.0, "yg": 0.0, "zg": 0.0}, rigid_body_cg=True)
        fast = Fossen6(**full.param_values())
        nu, b = jnp.asarray(_nu(rng, 6)), jnp.asarray(rng.normal(size=6))
        for f in ("coriolis_vector", "damping_vector", "solve_mass", "mass_times"):
            arg = b if f == "solve_mass" else nu
            assert np.allclose(getattr(fast, f)(arg), getattr(full, f)(arg), rtol=1e-12, atol=1e-12), f
        assert np.allclose(fast.coriolis_matrix(nu), full.coriolis_matrix(nu), atol=1e-12)


def test_fossen6_kinematics_is_zyx_rotation():
    from scipy.spatial.transform import Rotation

    model = Fossen6()
    for _ in range(20):
        eta = np.concatenate([rng.normal(size=3), rng.uniform(-1.2, 1.2, size=3)])
        nu = rng.normal(size=6)
        R = Rotation.from_euler("ZYX", eta[[5, 4, 3]]).as_matrix()
        phi, th = eta[3], eta[4]
        T = np.array([[1, np.sin(phi) * np.tan(th), np.cos(phi) * np.tan(th)], [0, np.cos(phi), -np.sin(phi)],
                      [0, np.sin(phi) / np.cos(th), np.cos(phi) / np.cos(th)]])
        got = np.asarray(model.kinematics(jnp.asarray(eta), jnp.asarray(nu)))
        assert np.allclose(got, np.concatenate([R @ nu[:3], T @ nu[3:]]), atol=1e-12)


def test_fossen6_energy_conserved_without_damping_and_restoring():
    zero = {n: 0.0 for n in ("Xu", "Yv", "Zw", "Kp", "Mq", "Nr", "Xuu", "Yvv", "Zww", "Kpp", "Mqq", "Nrr")}
    # no restoring: W = B = 0, on W's open bound (a weightless vehicle, outside what a model may hold), set directly
    weightless = lambda m: eqx.tree_at(lambda m: (m.W, m.B), m, (jnp.float64(0.0), jnp.float64(0.0)))  # noqa: E731
    free = weightless(Fossen6(**zero, xg=0.02, yg=-0.01, zg=0.03, rigid_body_cg=True))
    damped = weightless(Fossen6(xg=0.02, yg=-0.01, zg=0.03, rigid_body_cg=True))  # BlueROV2 damping on
    both = jax.tree.map(lambda a, b: jnp.stack([a, b]), free, damped)
    t = jnp.arange(0.0, 8.0, 0.01)
    x0 = jnp.asarray([0, 0, 0, 0, 0, 0, 0.5, 0.2, -0.1, 0.3, 0.2, 0.4])
    xs = jax.jit(jax.vmap(lambda m: simulate(m, t, jnp.zeros((t.size, 6)), x0).xs))(both)
    for i, model in enumerate((free, damped)):
        M = np.asarray(model.mass_matrix())
        nu = np.asarray(xs[i])[:, 6:]
        E = 0.5 * np.einsum("ni,ij,nj->n", nu, M, nu)
        if i == 0:
            assert np.abs(E - E[0]).max() < 1e-7 * E[0]
        else:  # with damping on, energy decays monotonically
            assert np.all(np.diff(E) <= 1e-12) and E[-1] < 0.5 * E[0]


def test_fossen6_restoring_matches_hydrostatics():
    """Neutral, CB above CG: upright is an equilibrium and a heel produces a righting moment k·sinφ."""
    model = Fossen6(B=Fossen6().W)
    g0 = np.asarray(model.restoring(jnp.asarray(0.0), jnp.asarray(0.0)))
    assert np.allclose(g0, 0.0, atol=1e-12)
    phi = 0.2
    g = np.asarray(model.restoring(jnp.asarray(phi), jnp.asarray(0.0)))
    k = float(model.zg * model.W - model.zb * model.B)  # = 0.01·W
    assert g[3] == pytest.approx(k * np.sin(phi), rel=1e-12)
    assert g[3] > 0  # opposes the heel in Mν̇ = τ − g


def test_jitted_vector_field_has_no_matrix_solve():
    """The 6-DOF vector field is written in component form (no LAPACK custom calls in the hot loop)."""
    for model in (Fossen6(xg=0.01, zg=0.02), Fossen6(xg=0.01, zg=0.02, rigid_body_cg=True)):
        x = jnp.zeros(12)
        u = jnp.zeros(6)
        hlo = jax.jit(lambda m, x, u: m.vector_field(0.0, x, u)).lower(model, x, u).as_text()
        assert "lapack" not in hlo.lower() and "custom_call" not in hlo
