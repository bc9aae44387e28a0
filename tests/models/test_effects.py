"""Every library effect vanishes exactly at its null value, and acts away from it; the registry."""

import os
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import diffship  # noqa: F401
from diffship.diagnose import EFFECT_NAMES, Augmented, augment, library
from diffship.models.effects import EFFECTS, FAMILY, DampingRR, NorrbinRR, applicability, make_effect
from diffship.errors import ModelError
from diffship.fit.problem import make_batch
from diffship.models import Nomoto1, Nomoto2
from diffship.simulate import initial_state, simulate
from diffship.synthetic import nomoto_runs, simulate_run, usv_excitation, usv_truth

D = np.pi / 180


@pytest.fixture(scope="module")
def usv():
    base = usv_truth()
    t, inp = usv_excitation(20.0, 0.1, seed=3)
    n = t.size
    inp = {**inp, "wind_speed": np.full(n, 8.0), "wind_dir": np.full(n, 0.7)}
    run = simulate_run(base, t, inp, np.array([0, 0, 0, 2.0, 0.1, 0.0]), name="u0")
    run = run.with_channels(wind_speed=inp["wind_speed"], wind_dir=inp["wind_dir"])
    return base, run


_jsim = jax.jit(simulate)


def _sim(model, run):
    b = make_batch(model, [run], ("psi", "u", "v", "r") if "u" in model.output_names else ("psi", "r"))
    x0 = initial_state(model, run)
    return _jsim(model, jnp.asarray(b.ts[0]), jnp.asarray(b.us[0]), jnp.asarray(x0))


def test_every_fossen3_effect_is_exact_at_null_and_acts_at_probe(usv):
    base, run = usv
    effs, skipped = library(base, [run], starts={"wave": {"T_w": 6.0}})
    # wind is measured and the wave has a period: all apply but the rudder angle offset of a rudder-steered model
    # (on a 3-DOF ship a constant sway force and yaw moment is constant_force)
    assert [e.name for e in effs] == [n for n in EFFECT_NAMES if n != "rudder_offset"]
    assert "constant_force" in skipped["rudder_offset"]
    ref = _sim(base, run)
    # all twelve composed in one model (one compilation): identical at null ...
    everything = Augmented(base, effs)
    sol = _sim(everything, run)
    assert float(jnp.max(jnp.abs(sol.ys - ref.ys))) <= 1e-12
    assert float(jnp.max(jnp.abs(sol.xs[:, :6] - ref.xs))) <= 1e-12
    # ... and each one acts on its own at its probe value, the others at null
    for e in effs:
        probe = _sim(everything.with_params(e.PROBE), run)
        if e.name != "heading_bias":  # a heading bias only moves positions
            assert float(jnp.max(jnp.abs(probe.ys - ref.ys))) > 1e-4, e.name
        else:
            assert float(jnp.max(jnp.abs(probe.xs[:, :2] - ref.xs[:, :2]))) > 0.1
    # one effect alone at null (a different composition)
    m = Augmented(base, [effs[1]])
    assert float(jnp.max(jnp.abs(_sim(m, run).ys - ref.ys))) <= 1e-12


@pytest.mark.parametrize("cls", [Nomoto1, Nomoto2])
def test_nomoto_effects_exact_at_null(cls):
    base = cls()
    run = nomoto_runs(Nomoto1(K=0.2, T1=8.0), n_runs=1, duration=20.0)[0]
    effs, skipped = library(base, [run], starts={"wave": {"T_w": 6.0}})
    assert {e.name for e in effs} == {"input_delay", "actuator_lag", "rate_limit", "rudder_offset", "damping_rr",
                                      "lag_trend", "wave"}
    assert "rudder_offset" not in skipped
    ref = _sim(base, run)
    everything = Augmented(base, effs)
    assert float(jnp.max(jnp.abs(_sim(everything, run).ys - ref.ys))) <= 1e-12
    for e in effs:
        assert float(jnp.max(jnp.abs(_sim(everything.with_params(e.PROBE), run).ys - ref.ys))) > 1e-5, e.name
    # the rudder offset is the model's own delta0 (ṙ = (K(δ + δ0) − r)/T1): the same simulation
    off = _sim(augment(base, "rudder_offset", delta_off=0.01), run)
    own = _sim(base.with_params({"delta0": 0.01}), run)
    assert float(jnp.max(jnp.abs(off.ys - own.ys))) <= 1e-12
    assert float(jnp.max(jnp.abs(off.ys - ref.ys))) > 1e-3


def test_a_constant_force_is_named_for_what_it_is():
    """On a 3-DOF ship a constant sway force and yaw moment is ``constant_force``; ``rudder_offset`` is the rudder
    angle offset of a rudder-steered model, which MMG carries as its own delta0."""
    from diffship.models import MMG
    from diffship.models.effects import applicability

    for ship in (usv_truth(), MMG()):
        assert applicability(ship, "constant_force") == ""
        why = applicability(ship, "rudder_offset")
        assert "3-DOF" in why and "delta0" in why and "constant_force" in why
    assert "not a 3-DOF" in applicability(Nomoto1(), "constant_force")
    assert applicability(Nomoto1(), "rudder_offset") == ""
    m = augment(MMG(), "constant_force", Y0=3.0, N0=-7.0)
    assert m.param_values()["Y0"] == 3.0 and "delta0" in m.param_names


def test_current_shifts_ground_velocity_by_the_current():
    """In steady straight motion the measured (over-ground) velocity is ν_r + Rᵀ v_c."""
    base = usv_truth()
    t = np.arange(0.0, 200.0, 0.1)
    inp = {"tau_x": np.full(t.size, 3000.0), "tau_y": np.zeros(t.size), "tau_z": np.zeros(t.size)}
    plain = simulate_run(base, t, inp, np.array([0, 0, 0, 2.0, 0, 0]))
    m = augment(base, "current", Vcx=0.3, Vcy=0.0)
    cur = simulate_run(m, t, inp, np.array([0, 0, 0, 2.0, 0, 0]))
    assert cur["u"][-1] - plain["u"][-1] == pytest.approx(0.3, abs=1e-6)
    assert cur["x0"][-1] - plain["x0"][-1] == pytest.approx(0.3 * 200.0, rel=0.05)


def test_changing_current_moves_the_ground_velocity_with_it():
    """A current changing along the run, v_c(t) = v_c0 + v̇_c t: in steady straight motion the
    over-ground velocity follows it (the Rᵀ v̇_c term), and with no trend it is the constant current."""
    base = usv_truth()
    t = np.arange(0.0, 200.0, 0.1)
    inp = {"tau_x": np.full(t.size, 3000.0), "tau_y": np.zeros(t.size), "tau_z": np.zeros(t.size)}
    x0 = np.array([0, 0, 0, 2.0, 0, 0])
    plain = simulate_run(base, t, inp, x0)
    tr = simulate_run(augment(base, "current_trend", Vcx_0=0.1, dVcx=1e-3), t, inp, x0)
    assert tr["u"][-1] - plain["u"][-1] == pytest.approx(0.1 + 1e-3 * t[-1], abs=2e-3)
    assert tr["x0"][-1] - plain["x0"][-1] == pytest.approx(0.1 * t[-1] + 0.5e-3 * t[-1] ** 2, rel=0.05)
    const = simulate_run(augment(base, "current", Vcx=0.1), t, inp, x0)
    same = simulate_run(augment(base, "current_trend", Vcx_0=0.1), t, inp, x0)
    assert np.max(np.abs(const["x0"] - same["x0"])) < 1e-9


def test_parameters_and_bad_names():
    base = usv_truth()
    m = augment(base, "constant_force", "actuator_lag", Y0=5.0, T_act=0.5)
    assert m.param_names[-3:] == ("T_act", "Y0", "N0") or set(m.param_names[-3:]) == {"T_act", "Y0", "N0"}
    assert m.param_values()["Y0"] == 5.0 and m.param_values()["T_act"] == 0.5
    assert m.with_params({"Y0": 7.0}).param_values()["Y0"] == 7.0
    with pytest.raises(ModelError, match="unknown effect"):
        make_effect(base, "gremlins")
    with pytest.raises(ModelError, match="does not apply"):
        make_effect(Nomoto1(), "current")


def test_registry_picks_the_implementation_for_the_base_model():
    assert EFFECT_NAMES == tuple(EFFECTS) and set(FAMILY) == set(EFFECT_NAMES)
    assert isinstance(make_effect(usv_truth(), "damping_rr"), DampingRR)
    assert isinstance(make_effect(Nomoto1(), "damping_rr"), NorrbinRR)
    assert applicability(usv_truth(), "wind") == ""
    assert "no measured wind" in applicability(usv_truth(), "wind", nomoto_runs(Nomoto1(), n_runs=1, duration=5.0))
    assert "needs a 3-DOF model" in applicability(Nomoto2(), "current")


def test_importing_effects_does_not_load_the_fitter():
    code = ("import sys, diffship.models.effects; "
            "print(' '.join(m for m in sys.modules if m.startswith('diffship')))")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    loaded = set(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                                env=env).stdout.split())
    assert "diffship.models.effects.registry" in loaded
    for heavy in ("diffship.fit", "diffship.metrics", "diffship.simulate", "diffship.diagnose.screen",
                  "diffship.diagnose.diagnosis", "diffship.diagnose.where"):
        assert heavy not in loaded, heavy


def test_every_hook_has_one_definition_and_both_forms_agree(usv):
    """An effect writes a hook once, on arrays (``force``, ``apply_input``) or on scalar parts
    (``force_parts``, ``apply_input_parts``, what the augmented vector field calls in the time step);
    the other form is derived and gives the same numbers — for effects written either way (wind and
    the Nomoto |r|r term on arrays, the rest on parts), with their extra states."""
    from diffship.models.effects import parts

    base, run = usv
    effs, _ = library(base, [run], starts={"wave": {"T_w": 6.0}})
    nomoto_effs, _ = library(Nomoto2(), nomoto_runs(Nomoto1(K=0.2, T1=8.0), n_runs=1, duration=5.0),
                             starts={"wave": {"T_w": 6.0}})
    rng = np.random.default_rng(5)
    for b, group in ((base, effs), (Nomoto2(), nomoto_effs)):
        for e in group:
            e = Augmented(b, [e]).with_params({n: e.PROBE[n] for n in e.param_names}).effects[0]
            xb = jnp.asarray(rng.normal(size=len(b.state_names)) + (np.r_[0, 0, 0, 2.0, 0, 0] if b is base else 0))
            ub = jnp.asarray(rng.normal(size=len(b.input_names)) * (500.0 if b is base else 0.1))
            xe = jnp.asarray(rng.normal(size=len(e.extra_states(b))) * 0.1)
            uext = jnp.asarray([8.0, 0.7]) if e.extra_inputs else None
            t = jnp.asarray(2.3)
            if e.hook == "force":
                arr = np.asarray(e.force(b, t, xb, ub, uext))
                prt = np.asarray(jnp.stack(e.force_parts(b, t, parts(xb), parts(ub), uext)))
                np.testing.assert_allclose(prt, arr, rtol=1e-14, atol=1e-12, err_msg=e.name)
                assert np.any(arr != 0), e.name
            elif e.hook == "input":
                ua, da = e.apply_input(b, t, xb, xe, ub)
                up, dp = e.apply_input_parts(b, t, parts(xb), parts(xe), parts(ub))
                np.testing.assert_allclose(np.asarray(jnp.stack(up)), np.asarray(ua), rtol=1e-14, err_msg=e.name)
                np.testing.assert_allclose(np.asarray(jnp.stack(dp)) if dp else np.zeros(0), np.asarray(da),
                                           rtol=1e-14, err_msg=e.name)
                assert np.any(np.asarray(ua) != np.asarray(ub)) or np.asarray(da).size, e.name


def test_force_effects_add_their_force_through_the_base_mass_matrix(usv):
    """ν̇ of the augmented model = ν̇ of the base + M⁻¹ Σ Δτ (the dense mass matrix, solved by NumPy),
    for every force effect at its probe value together; positions and heading rates unchanged."""
    base, run = usv
    effs, _ = library(base, [run], starts={"wave": {"T_w": 6.0}})
    force = [e for e in effs if e.hook == "force"]
    m = Augmented(base, force).with_params({n: v for e in force for n, v in e.PROBE.items()})
    x = jnp.asarray([3.0, -2.0, 0.4, 2.1, 0.3, 0.05])
    u = jnp.asarray([3000.0, 200.0, -900.0])
    t = jnp.asarray(1.7)
    uext = jnp.asarray([8.0, 0.7])
    dtau = sum(np.asarray(e.force(base, t, x, u, uext if e.extra_inputs else None)) for e in m.effects)
    expect = np.asarray(base.vector_field(t, x, u)).copy()
    expect[3:] += np.linalg.solve(np.asarray(base.mass_matrix()), dtau)
    got = np.asarray(m.vector_field(t, x, jnp.concatenate([u, uext])))
    np.testing.assert_allclose(got, expect, rtol=1e-12, atol=1e-12)
    assert np.linalg.norm(got[3:] - np.asarray(base.vector_field(t, x, u))[3:]) > 1e-3


def test_all_effects_vector_field_has_no_gather_scatter_or_stacked_intermediates(usv):
    """The augmented vector field of the diagnosis's all-effects workspace is written on scalar
    components: its program holds no gather or scatter (index arrays, ``.at[]`` updates) and one
    concatenation (the result). On a CPU each of those is a kernel of its own in every stage of every
    time step; the USV current case's all-effects workspace had 22 scatters, 8 gathers and 14 concatenations per evaluation."""
    import re

    base, run = usv
    effs, _ = library(base, [run])
    effs = [e for e in effs if not e.extra_inputs]  # measured wind: an extra input, stacked for its array hook
    m = Augmented(base, effs)
    text = jax.jit(lambda m, x, u: m.vector_field(0.0, x, u)).lower(
        m, jnp.zeros(len(m.state_names)), jnp.zeros(len(m.input_names))).as_text()
    ops = re.findall(r"stablehlo\.([a-z_]+)", text)
    assert "gather" not in ops and "scatter" not in ops and "dynamic_update_slice" not in ops
    assert ops.count("concatenate") == 1
    assert len(m.state_names) == 16 and len(m.effects) == 13
