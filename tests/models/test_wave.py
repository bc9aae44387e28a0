"""The periodic (wave-like) disturbance family: exact null (to the 1e-12 of the null-value
contract: a different compiled program may round differently), the stated period, the registry's
start rule."""

import jax.numpy as jnp
import numpy as np
import pytest

import diffship  # noqa: F401
from diffship.errors import ModelError
from diffship.models import Nomoto1, Nomoto2
from diffship.models.effects import NomotoWave, Wave, augment, library, make_effect
from diffship.synthetic import nomoto_runs, simulate_run, usv_excitation, usv_truth

CH = ("x0", "y0", "psi", "u", "v", "r")


@pytest.fixture(scope="module")
def usv():
    base = usv_truth()
    t, inp = usv_excitation(30.0, 0.1, seed=3)
    return base, t, inp, np.array([0.0, 0.0, 0.0, 2.0, 0.1, 0.0])


def test_null_leaves_the_base_model_unchanged_exactly(usv):
    base, t, inp, x0 = usv
    ref = simulate_run(base, t, inp, x0)
    for T in (2.5, 6.0, 40.0):  # zero amplitudes: whatever the period
        got = simulate_run(augment(base, "wave", T_w=T), t, inp, x0)
        assert max(float(np.max(np.abs(np.asarray(got[c]) - np.asarray(ref[c])))) for c in CH) <= 1e-12
    # and it acts away from the null: a 300 N·m yaw moment moves the yaw rate
    got = simulate_run(augment(base, "wave", T_w=6.0, A_Ns=300.0), t, inp, x0)
    assert float(np.max(np.abs(np.asarray(got["r"]) - np.asarray(ref["r"])))) > 1e-3


def test_force_has_the_stated_period_amplitude_and_phase():
    base = usv_truth()
    e = make_effect(base, "wave", T_w=5.0, A_Yc=30.0, A_Ys=40.0, A_Nc=-120.0, A_Ns=0.0)
    t = np.arange(0.0, 40.0, 0.05)
    f = np.array([np.asarray(e.force(base, jnp.asarray(tt), jnp.zeros(6), None, None)) for tt in t])
    assert np.all(f[:, 0] == 0.0)  # no surge force
    # one period later the force repeats; half a period later it is reversed
    k = int(round(5.0 / 0.05))
    assert np.max(np.abs(f[k:, 1:] - f[:-k, 1:])) < 1e-9
    assert np.max(np.abs(f[k // 2:, 1:] + f[:-(k // 2), 1:])) < 1e-9
    # the spectral line is at 1/T_w, amplitude √(30² + 40²) = 50 N
    spec = np.abs(np.fft.rfft(f[:, 1])) * 2 / t.size
    fr = np.fft.rfftfreq(t.size, 0.05)
    assert fr[np.argmax(spec)] == pytest.approx(1 / 5.0)
    assert np.max(np.abs(f[:, 1])) == pytest.approx(50.0, rel=1e-3)
    assert f[0, 1] == pytest.approx(30.0) and f[0, 2] == pytest.approx(-120.0)


def test_nomoto_form_is_a_rudder_equivalent_disturbance():
    run = nomoto_runs(Nomoto1(K=0.2, T1=8.0), n_runs=1, duration=30.0)[0]
    for cls in (Nomoto1, Nomoto2):
        base = cls(K=0.2, T1=8.0)
        e = make_effect(base, "wave", T_w=7.0)
        assert isinstance(e, NomotoWave) and e.param_names == ("a_c", "a_s", "T_w")
        x0 = base.initial_state({c: float(np.asarray(run[c])[0]) for c in ("psi", "r") if run.has(c)})
        t = np.asarray(run.time)
        inp = {"delta": np.asarray(run["delta"])}
        ref = simulate_run(base, t, inp, x0)
        assert float(np.max(np.abs(np.asarray(simulate_run(augment(base, e), t, inp, x0)["r"]) - np.asarray(ref["r"])))) <= 1e-12
    # a_c cos(2πt/T) added to δ is the same simulation as that rudder signal given to the base model
    base = Nomoto1(K=0.2, T1=8.0)
    x0 = np.array([0.0, 0.0])
    wave = simulate_run(augment(base, "wave", T_w=7.0, a_c=0.02), t, inp, x0)
    own = simulate_run(base, t, {"delta": inp["delta"] + 0.02 * np.cos(2 * np.pi * t / 7.0)}, x0)
    assert float(np.max(np.abs(np.asarray(wave["r"]) - np.asarray(own["r"])))) < 1e-6  # RK4 with ZOH inputs vs exact
    assert float(np.max(np.abs(np.asarray(wave["r"]) - np.asarray(ref["r"])))) > 1e-3


def test_library_builds_the_wave_only_with_a_start_period():
    base = usv_truth()
    effs, skipped = library(base, None, ["wave", "current"])
    assert [e.name for e in effs] == ["current"] and "no start for its parameter T_w" in skipped["wave"]
    effs, skipped = library(base, None, ["wave"], starts={"wave": {"T_w": 6.3}})
    (w,) = effs
    assert isinstance(w, Wave) and not skipped
    assert w.null() == {"A_Yc": 0.0, "A_Ys": 0.0, "A_Nc": 0.0, "A_Ns": 0.0, "T_w": 6.3}
    assert isinstance(library(Nomoto2(), None, ["wave"], starts={"wave": {"T_w": 6.3}})[0][0], NomotoWave)
    with pytest.raises(ModelError, match="unknown parameter"):
        make_effect(base, "wave", period=6.0)
