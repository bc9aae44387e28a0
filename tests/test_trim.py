"""Trim: straight-course equilibrium at zero rudder for any model with a surge state."""

import jax.numpy as jnp
import numpy as np
import pytest

from diffship.errors import ModelError
from diffship.integrators import RK4
from diffship.models import Nomoto1, usv_standard
from diffship.models.mmg import kvlcc2_mmg
from diffship.simulate import simulate
from diffship.trim import trim


def test_kvlcc2_published_set_settles_at_1_02_m_s_and_stays_there():
    """The published KVLCC2 L7 set at the measured 10.23 rps slows to about 1.02 m/s."""
    m = kvlcc2_mmg()
    t = trim(m, inputs={"n": 10.23})
    assert t.ok and t.solved_for == "speed" and 1.00 < t.speed < 1.04
    ts = jnp.arange(0.0, 100.0, 0.5)
    us = jnp.tile(jnp.asarray([0.0, 10.23]), (ts.shape[0], 1))
    x0 = jnp.asarray(m.initial_state({"u": t.speed}))
    xs = np.asarray(simulate(m, ts, us, x0, RK4()).xs)
    assert np.max(np.abs(xs[:, 3] - t.speed)) < 1e-6
    back = trim(m, speed=1.179)  # the test's speed needs more propeller
    assert back.inputs["n"] > 10.23 and trim(m, inputs={"n": back.inputs["n"]}).speed == pytest.approx(1.179, abs=1e-8)


def test_force_input_trim_matches_closed_form():
    """Fossen 3-DOF with force inputs: at v = r = 0 the surge balance is τ_x = −(X_u u + X_|u|u |u| u)."""
    m = usv_standard()
    U = 2.0
    t = trim(m, speed=U, input="tau_x")
    expected = -(float(m.Xu) * U + float(m.Xuu) * U * abs(U))
    assert t.solved_for == "tau_x" and t.inputs["tau_x"] == pytest.approx(expected, rel=1e-9)
    assert trim(m, inputs={"tau_x": expected, "tau_y": 0.0, "tau_z": 0.0}).speed == pytest.approx(U, rel=1e-9)


def test_trim_needs_a_surge_state_and_one_unknown():
    with pytest.raises(ModelError, match="no surge state"):
        trim(Nomoto1(), speed=1.0)
    with pytest.raises(ModelError, match="either speed"):
        trim(kvlcc2_mmg(), speed=1.0, inputs={"n": 10.0})
    with pytest.raises(ModelError, match="say which one"):
        trim(usv_standard(), speed=1.0)
