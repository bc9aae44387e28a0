"""The independent scenario generator (benchmarks/independent) shares no code with diffship.

Its files are parsed (``ast``) and every import must be NumPy/SciPy/pandas, the standard
library, or the generator itself; it is then run in a fresh interpreter where no ``diffship``
or ``jax`` module may be loaded. Two physics checks make sure the effects do what they claim.
"""

import ast
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

GEN = Path(__file__).resolve().parents[2] / "benchmarks" / "independent"
ALLOWED = {"numpy", "scipy", "pandas", "__future__", "dataclasses", "collections", "math", "typing"}


def _imports(path: Path) -> list[tuple[str, int]]:
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out += [(a.name, 0) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            out.append((node.module or "", node.level))
    return out


def test_generator_imports_nothing_from_diffship():
    files = sorted(GEN.glob("*.py"))
    assert len(files) >= 4, f"generator files missing in {GEN}"
    bad = []
    for f in files:
        for mod, level in _imports(f):
            if level:  # relative: the generator's own modules
                continue
            if mod.split(".")[0] not in ALLOWED:
                bad.append(f"{f.name}: import {mod}")
    assert not bad, "the independent generator must import only numpy/scipy/pandas and the standard library: " + "; ".join(bad)


def test_generator_runs_without_diffship_or_jax_loaded():
    code = ("import sys; sys.path.insert(0, sys.argv[1]); import independent as I; "
            "g = I.generate(I.Scenario('ship', 'actuator_lag', 'in', 'strong', 1)); "
            "assert len(g['train']) == 4 and len(g['val']) == 2; "
            "bad = sorted(m for m in sys.modules if m.split('.')[0] in ('diffship', 'jax', 'equinox', 'diffrax')); "
            "assert not bad, bad; print('ok')")
    p = subprocess.run([sys.executable, "-c", code, str(GEN.parent)], capture_output=True, text=True, timeout=300,
                       check=False)
    assert p.returncode == 0 and p.stdout.strip() == "ok", p.stderr[-2000:]


def _gen():
    sys.path.insert(0, str(GEN.parent))
    try:
        from independent import effects, vessels
    finally:
        sys.path.pop(0)
    return effects, vessels


def test_current_in_relative_velocity_form_drifts_the_track_by_vc_t():
    """Straight running in a constant current: same motion through the water, so the track over
    ground is the still-water track shifted by v_c·t (to integration accuracy)."""
    fx, vs = _gen()
    t = np.arange(0.0, 20.0, 0.1)
    cmd = np.tile([3000.0, 0.0, 0.0], (t.size, 1))
    still = vs.simulate(vs.USV(), [], t, commands=cmd)
    cur = fx.Current(V=0.3, beta=0.8)
    moving = vs.simulate(vs.USV(), [cur], t, commands=cmd)
    dx = moving["clean"]["x0"] - still["clean"]["x0"]
    dy = moving["clean"]["y0"] - still["clean"]["y0"]
    np.testing.assert_allclose(dx, 0.3 * np.cos(0.8) * t, atol=1e-6)
    np.testing.assert_allclose(dy, 0.3 * np.sin(0.8) * t, atol=1e-6)


def test_delay_equals_the_shifted_command():
    """An input delay τ gives the response to the command shifted by τ (open loop)."""
    fx, vs = _gen()
    t = np.arange(0.0, 30.0, 0.1)
    cmd = vs.usv_commands(t, np.random.default_rng(3))
    delayed = vs.simulate(vs.USV(), [fx.Delay(tau=1.0, channels=(1, 2))], t, commands=cmd)
    shifted = cmd.copy()
    shifted[:, 1:] = np.stack([np.interp(t - 1.0, t, cmd[:, j], left=cmd[0, j]) for j in (1, 2)], axis=1)
    ref = vs.simulate(vs.USV(), [], t, commands=shifted)
    for c in ("psi", "r", "v"):
        np.testing.assert_allclose(delayed["clean"][c], ref["clean"][c], atol=2e-4)
    assert np.max(np.abs(delayed["clean"]["r"] - vs.simulate(vs.USV(), [], t, commands=cmd)["clean"]["r"])) > 0.01


@pytest.mark.parametrize("label", ["actuator_lag", "none"])
def test_ship_zigzag_reverses_at_the_switch_heading(label):
    """The helmsman reverses the rudder when the compass passes the switch angle."""
    sys.path.insert(0, str(GEN.parent))
    try:
        import independent as ind
    finally:
        sys.path.pop(0)
    g = ind.generate(ind.Scenario("ship", label, "in", "strong", 1))
    run = g["train"][1]  # 20/20 zigzag
    d, psi = run["channels"]["delta"], run["clean"]["psi"]
    k = int(np.argmax(np.diff(np.abs(d)) < -1e-9))  # the first sample where the rudder comes back
    assert k > 0 and abs(d[k]) == pytest.approx(20 * np.pi / 180)
    assert abs(abs(psi[k]) - 20 * np.pi / 180) < 0.5 * np.pi / 180  # the helmsman reversed at ±20° heading


def test_usv_coriolis_conserves_kinetic_energy():
    """C_RB(ν) and C_A(ν) are skew-symmetric: with no damping and no forcing the kinetic
    energy ½νᵀMν of the generator's USV stays constant (a sign error in the added-mass
    Coriolis terms breaks this)."""
    _, vs = _gen()
    usv = vs.USV(Xu=0.0, Yv=0.0, Nv=0.0, Nr=0.0, Xuu=0.0, Yvv=0.0, Nrr=0.0)
    t = np.arange(0.0, 30.0, 0.1)
    x = np.array([0.0, 0.0, 0.0, 2.0, 0.4, 0.15])
    for k in range(t.size - 1):
        x = vs.rk4_interval(lambda tt, xx: usv.rhs(tt, xx, np.zeros(3), lambda *a: np.zeros(3),
                                                    lambda tt: (np.zeros(2), np.zeros(2))), t[k], t[k + 1], x)

    def energy(x):
        u, v, r = x[3:]
        return 0.5 * ((usv.m - usv.Xudot) * u ** 2 + (usv.m - usv.Yvdot) * v ** 2 + (usv.Iz - usv.Nrdot) * r ** 2)

    assert energy(x) == pytest.approx(energy(np.array([0, 0, 0, 2.0, 0.4, 0.15])), rel=1e-6)
    assert abs(x[4] - 0.4) > 0.01  # the motion did change (energy moved between DOFs)


def test_usv_added_mass_terms_match_the_textbook_component_form():
    """Without damping or forcing: (m − X_u̇)u̇ = (m − Y_v̇)vr, (m − Y_v̇)v̇ = −(m − X_u̇)ur and
    (I_z − N_ṙ)ṙ = (Y_v̇ − X_u̇)uv (the Munk moment turns the hull broadside: negative for u, v > 0
    when |Y_v̇| > |X_u̇|). Energy conservation alone does not fix these signs."""
    _, vs = _gen()
    usv = vs.USV(Xu=0.0, Yv=0.0, Nv=0.0, Nr=0.0, Xuu=0.0, Yvv=0.0, Nrr=0.0)
    u, v, r = 2.0, 0.4, 0.15
    d = usv.rhs(0.0, np.array([0.0, 0.0, 0.0, u, v, r]), np.zeros(3), lambda *a: np.zeros(3),
                lambda tt: (np.zeros(2), np.zeros(2)))
    m, Xa, Ya, Na = usv.m, usv.Xudot, usv.Yvdot, usv.Nrdot
    np.testing.assert_allclose(d[3:], [(m - Ya) * v * r / (m - Xa), -(m - Xa) * u * r / (m - Ya),
                                       (Ya - Xa) * u * v / (usv.Iz - Na)], rtol=1e-12)
    assert d[5] < 0


def test_ship_null_has_no_rudder_offset_and_the_rudder_offset_effect_shifts_the_rudder():
    """The truth ship holds a straight course at zero rudder (no built-in offset, so a null
    scenario is null under diffship's effect definitions), and the injected ``RudderOffset`` is the
    same truth as a ship whose logged rudder is shifted by δ_off (open loop, to integration
    accuracy); from rest (30 s pre-roll) it turns the ship towards the Nomoto steady rate K·δ_off,
    r(t) = K·δ_off·(1 − exp(−(t + 30 s)/T))."""
    fx, vs = _gen()
    t = np.arange(0.0, 60.0, 0.1)
    zero = np.zeros((t.size, 1))
    null = vs.simulate(vs.Ship(), [], t, commands=zero)
    assert np.max(np.abs(null["clean"]["psi"])) < 1e-12
    off = 1.0 * np.pi / 180
    cmd = np.where(t > 5.0, 10 * np.pi / 180, 0.0)[:, None]
    injected = vs.simulate(vs.Ship(), [fx.RudderOffset(delta_off=off)], t, commands=cmd)
    shifted = vs.simulate(vs.Ship(), [], t, commands=cmd + off)
    np.testing.assert_allclose(injected["clean"]["r"], shifted["clean"]["r"], atol=1e-10)
    np.testing.assert_allclose(injected["commands"], cmd)  # the log holds the command, not what the hull sees
    steady = vs.simulate(vs.Ship(), [fx.RudderOffset(delta_off=off)], t, commands=zero)
    K, T = vs.Ship().K, vs.Ship().T
    np.testing.assert_allclose(steady["clean"]["r"], K * off * (1 - np.exp(-(t + 30.0) / T)), rtol=1e-6)


def test_ship_in_family_effects_include_rudder_offset_at_sea_trial_size():
    sys.path.insert(0, str(GEN.parent))
    try:
        import independent as ind
    finally:
        sys.path.pop(0)
    strong = ind.Scenario("ship", "rudder_offset", "in", "strong", 1).effect()
    weak = ind.Scenario("ship", "rudder_offset", "in", "weak", 1).effect()
    assert strong.delta_off == pytest.approx(np.pi / 180) and weak.delta_off == pytest.approx(0.25 * np.pi / 180)
    assert ind.Scenario("ship", "none", "none", "strong", 100).effect() is None
    names = [s.name for s in ind.scenarios(("ship",), sizes=("weak", "strong"), seeds=(1,), nulls=1)]
    assert "ship-rudder_offset-weak-s1" in names and "ship-rudder_offset-strong-s1" in names
