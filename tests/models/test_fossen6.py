"""Fossen 6-DOF ROV model: reference behaviour and identification (seed 004)."""

import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from diffship.fit import OutputErrorOptions, fit_equation_error, fit_output_error
from diffship.models import MODELS, Fossen6, get_model
from diffship.preprocess import Filter
from diffship.simulate import simulate

sys.path.insert(0, str(Path(__file__).parent))
from _rov_data import ROV_NOISE, rov_runs  # noqa: E402


def _abs_err(fitted, truth, spec, names):
    """Error relative to max(|truth|, scale): some reference coefficients are exactly 0."""
    return {n: abs(fitted[n] - truth[n]) / max(abs(truth[n]), spec[n].scale) for n in names}


def test_registered_with_named_inputs_and_angles():
    m = get_model("fossen6")
    assert MODELS["fossen6"] is Fossen6
    assert m.input_names == ("tau_x", "tau_y", "tau_z", "tau_k", "tau_m", "tau_n")
    assert m.angle_outputs == ("phi", "theta", "psi")
    assert set(m.spec().free_names) == {"Xudot", "Yvdot", "Zwdot", "Kpdot", "Mqdot", "Nrdot",
                                        "Xu", "Yv", "Zw", "Kp", "Mq", "Nr"}


def test_bluerov2_steady_surge_and_roll_period():
    """Constant 20 N forward thrust: terminal speed solves X_u u + X_|u|u u² = −20 N; a released 10° heel
    oscillates at the natural frequency √(k/(I_x − K_ṗ)) with k = (z_g W − z_b B)."""
    m = Fossen6(B=Fossen6().W)  # neutral, so depth stays put
    t = jnp.arange(0.0, 40.0, 0.05)
    tau = jnp.zeros((2, t.size, 6)).at[0, :, 0].set(20.0)
    x0 = np.zeros((2, 12))
    x0[1, 3] = 10 * np.pi / 180
    both = np.asarray(jax.jit(jax.vmap(lambda u, x: simulate(m, t, u, x).xs))(tau, jnp.asarray(x0)))
    xs, roll = both[0], both[1][:, 3]
    Xu, Xuu = float(m.Xu), float(m.Xuu)
    u_ss = (Xu + np.sqrt(Xu**2 + 4 * (-Xuu) * 20.0)) / (2 * -Xuu)
    assert xs[-1, 6] == pytest.approx(u_ss, rel=1e-3)
    assert abs(xs[-1, 2]) < 1e-9  # no heave when neutral
    k = float(m.zg * m.W - m.zb * m.B)
    wn = np.sqrt(k / (float(m.Ix) - float(m.Kpdot)))
    crossings = np.nonzero(np.diff(np.sign(roll)) != 0)[0]
    period = 2 * np.mean(np.diff(np.asarray(t)[crossings]))
    assert period == pytest.approx(2 * np.pi / wn, rel=0.03)  # lightly damped: ω_d ≈ ω_n


def test_equation_error_least_squares_with_known_thrust():
    """Seed 004: added mass and linear damping by least squares on Mν̇ + C(ν)ν + D(ν)ν + g(η) = τ with
    known thrust and Coriolis included. Noisy DVL/gyro data (0.01 m/s, 0.2°/s): every coefficient
    within 10 % of max(|value|, scale) (measured ≤ 6 %: filtered accelerations are slightly attenuated,
    inflating the added masses)."""
    truth = Fossen6()
    runs = rov_runs(truth, n_runs=2, duration=60.0, dt=0.05, noise=ROV_NOISE)
    spec, tv = truth.spec(), truth.param_values()
    # start far from the truth: ±60 % of max(|value|, scale), alternating
    start = truth.with_params({n: tv[n] + (0.6 if i % 2 else -0.6) * max(abs(tv[n]), spec[n].scale)
                               for i, n in enumerate(spec.free_names)})
    assert min(_abs_err(start.param_values(), tv, spec, spec.free_names).values()) > 0.59
    ee = fit_equation_error(start, runs, flt=Filter("savgol", window=1.0))
    err = _abs_err(ee.params, tv, spec, ee.free)
    assert max(err.values()) < 0.10, err
    assert ee.converged


def test_output_error_refines_rov():
    """Output error from the equation-error estimate: every coefficient within 2 % of max(|value|, scale)."""
    truth = Fossen6()
    runs = rov_runs(truth, n_runs=2, duration=60.0, dt=0.05, noise=ROV_NOISE)
    ee = fit_equation_error(truth, runs, flt=Filter("savgol", window=1.0))
    start = {n: min(ee.params[n], -1e-3) if n.endswith("dot") else ee.params[n] for n in ee.free}
    oe = fit_output_error(truth.with_params(start), runs, options=OutputErrorOptions(estimate_x0=("u", "v", "w", "p", "q", "r", "phi", "theta")))
    assert oe.converged, oe.status
    err = _abs_err(oe.params, truth.param_values(), truth.spec(), oe.free)
    ee_err = _abs_err(ee.params, truth.param_values(), truth.spec(), ee.free)
    assert max(err.values()) < 0.02, err
    assert max(err.values()) < max(ee_err.values())
