"""Vessel particulars: bundled reference vessels, derived quantities, missing particulars,
plausibility checks before any compute, fixed values in the report."""

import json
import re

import numpy as np
import pytest

from diffship.errors import ModelError
from diffship.fit.cli import main as fit_main
from diffship.models import MODELS, Fossen6, get_model
from diffship.models.mmg import KVLCC2_L7
from diffship.vessel import (
    QUANTITIES,
    Vessel,
    bundled_vessels,
    fixed_values_text,
    load_vessel,
    particulars,
    plausibility,
    require_particulars,
)


def test_every_declared_particular_is_a_known_quantity():
    for name in MODELS:
        m = get_model(name)
        assert set(m.PARTICULARS) <= set(m.param_names), name
        assert set(m.PARTICULARS.values()) <= set(QUANTITIES), name
        if m.REFERENCE_VESSEL:
            assert m.REFERENCE_VESSEL in bundled_vessels(), name
    # what vmm_simple needs: m, Iz, xG, L, rho, U0, XT and five added masses
    assert set(get_model("vmm_simple").PARTICULARS) == {"m", "Iz", "xG", "L", "rho", "U0", "XT", "Xudot", "Yvdot",
                                                        "Yrdot", "Nvdot", "Nrdot"}


@pytest.mark.parametrize("name", [n for n in MODELS if get_model(n).REFERENCE_VESSEL])
def test_reference_vessel_file_gives_the_models_defaults(name):
    """The bundled file of each model's reference vessel reproduces its default particulars (same
    numbers, reached through masses, radii of gyration, positions in metres and the parallel-axis theorem)."""
    m = get_model(name)
    got = m.with_vessel(load_vessel(m.REFERENCE_VESSEL)).param_values()
    for n in m.PARTICULARS:
        assert got[n] == pytest.approx(m.param_values()[n], rel=1e-9, abs=1e-12), n


def test_derived_quantities():
    v = Vessel(name="t", mass=None, displacement=2.0, rho=1000.0, cg=(0.5, 0.0, 0.1), inertia_about="origin",
               inertia=(None, None, 700.0), length=4.0)
    assert v.quantity("mass") == (2000.0, "rho × displacement")
    izg, how = v.quantity("Izz_cg")
    assert izg == pytest.approx(700.0 - 2000.0 * 0.25) and "origin" in how  # parallel axis back to the CG
    assert v.quantity("Izz_origin")[0] == pytest.approx(700.0)
    assert v.quantity("kzz_L")[0] == pytest.approx(np.sqrt(200.0 / 2000.0) / 4.0)
    assert v.quantity("weight")[0] == pytest.approx(2000.0 * 9.81)
    assert v.quantity("Ixx_cg")[0] is None


def test_added_mass_estimates_against_the_kvlcc2_pmm_values():
    """Brix/Clarke estimates from L, B, T, C_B, ∇ against the measured KVLCC2 L7 added masses of Yasukawa &
    Yoshimura (m'_x, m'_y on ½ρL²d, J'_z on ½ρL⁴d): surge within 30 %, sway and yaw within 20 %."""
    v = load_vessel("kvlcc2_model")
    dl = KVLCC2_L7["d"] / KVLCC2_L7["L"]  # ½ρL²d → ½ρL³ and ½ρL⁴d → ½ρL⁵
    for key, measured, tol in (("Xudot_prime", -KVLCC2_L7["mx"] * dl, 0.3), ("Yvdot_prime", -KVLCC2_L7["my"] * dl, 0.2),
                               ("Nrdot_prime", -KVLCC2_L7["Jz"] * dl, 0.2)):
        est, how = v.quantity(key)
        assert est == pytest.approx(measured, rel=tol), (key, est, measured)
        assert "Clarke" in how or "Brix" in how


def test_missing_particulars_stop_naming_them(tmp_path, capsys):
    csv = tmp_path / "run.csv"
    t = np.arange(0.0, 20.0, 0.5)
    csv.write_text("time,x0,y0,psi,u,v,r,delta,thrust\n" + "\n".join(f"{a},0,0,0,1.2,0,0,0,10" for a in t))
    code = fit_main([str(csv), "--model", "vmm_simple", "--quiet"])  # the full command (the JAX-free path:
    err = capsys.readouterr().err.strip()  # tests/fit/test_args.py)
    assert code == 2, code
    assert err.count("\n") == 0 and err.startswith("error: model vmm_simple needs the vessel's particulars")
    for n in ("m", "Iz", "xG", "L", "rho", "U0", "XT", "Xudot", "Yvdot", "Yrdot", "Nvdot", "Nrdot"):
        assert re.search(rf"\b{n} \(", err), n
    assert "--vessel mariner" in err
    # --fix or --free covers a particular; the rest are still named
    p = particulars(get_model("vmm_simple"), None, fixed=["m", "Iz"], freed=["Xudot"])
    assert "m" not in p.missing and "Xudot" not in p.missing and "L" in p.missing


def test_vessel_file_errors_are_one_clear_line(tmp_path):
    bad = tmp_path / "v.json"
    bad.write_text(json.dumps({"name": "x", "units": "SI", "lenght": 3.0}))
    with pytest.raises(ModelError, match="unknown key.*lenght"):
        load_vessel(bad)
    bad.write_text(json.dumps({"name": "x", "length": 3.0}))
    with pytest.raises(ModelError, match="'units' must be"):
        load_vessel(bad)
    with pytest.raises(ModelError, match="neither a file nor a bundled vessel"):
        load_vessel("no_such_ship")
    with pytest.raises(ModelError, match="lacks .*Iz"):
        require_particulars(get_model("fossen3"), Vessel(name="half", mass=100.0, cg=(0.0, 0.0, None)))


class _FakeRun:
    def __init__(self, u):
        self.u, self.time = np.full(50, u), np.arange(50.0)

    def has(self, *names):
        return all(n in ("u",) for n in names)

    def __getitem__(self, k):
        return self.u


def test_plausibility_checks():
    mariner = load_vessel("mariner")
    w = plausibility(mariner, [_FakeRun(1.18)])
    assert any(s.startswith("warning: data speed 1.18 m/s") and "7.72" in s for s in w), w
    assert not any(s.startswith("warning") for s in plausibility(mariner, [_FakeRun(7.5)]))
    # a full-scale Froude number above 0.4: out of the displacement regime
    assert any(s.startswith("warning: Froude number") for s in plausibility(Vessel(name="f", length=10.0), [_FakeRun(5.0)]))
    # mass against rho ∇ (a file in the wrong density or units)
    heavy = Vessel(name="h", mass=3272.0, displacement=3.27, rho=1025.0 * 1.1)
    assert any(s.startswith("warning: mass") for s in plausibility(heavy))
    assert not any(s.startswith("warning") for s in plausibility(load_vessel("kvlcc2_model")))
    assert any("warning: scale" in s for s in plausibility(Vessel(name="s", length=7.0, scale=20.0,
                                                                    full_scale_length=320.0)))


def test_rigid_body_reference_from_the_vessel():
    off = Vessel(name="rov", mass=13.5, rho=1000.0, displacement=0.0134, cg=(0.0, 0.0, 0.02), cb=(0.0, 0.0, -0.01),
                 inertia=(0.26, 0.23, 0.37))
    m, parts = require_particulars(Fossen6(), off)
    assert m.rigid_body_cg and float(m.zg) == 0.02 and "rigid_body_cg" in parts.sources
    assert not Fossen6().with_vessel(load_vessel("bluerov2")).rigid_body_cg
    text = fixed_values_text(m.spec(), parts.sources)
    assert "zg" in text and "vessel rov: cg[2]" in text and "rigid_body_cg" in text


def test_cli_vessel_warns_before_fitting_and_reports_fixed_values(tmp_path, capsys):
    """A vmm_linear fit of 1.2 m/s data with the full-scale Mariner particulars: the speed warning comes
    before the fit's progress; the report lists every fixed value with where it came from."""
    from diffship.synthetic import simulate_run

    m = get_model("vmm_linear").with_params({"U0": 1.2, "L": 7.0, "m": 3272.0, "Iz": 1e4, "xG": 0.2, "rho": 1000.0})
    t = np.arange(0.0, 60.0, 0.5)
    delta = 0.2 * np.sign(np.sin(2 * np.pi * t / 30.0))
    T0 = float(-m.X0 * 0.5 * m.rho * m.L**2 * m.U0**2 / m.XT)
    run = simulate_run(m, t, {"delta": delta, "thrust": np.full_like(t, T0)}, np.array([0, 0, 0, 1.2, 0, 0.0]))
    path = tmp_path / "slow.csv"
    run.to_dataframe().to_csv(path, index=False)
    code = fit_main([str(path), "--model", "vmm_linear", "--vessel", "mariner", "--method", "equation-error",
                     "--filter", "savgol:5", "--json", str(tmp_path / "r.json")])
    out = capsys.readouterr()
    assert code == 0, out.err
    lines = out.err.splitlines()
    warn = next(i for i, s in enumerate(lines) if s.startswith("warning: data speed"))
    first_fit = next(i for i, s in enumerate(lines) if "equation error:" in s)
    assert warn < first_fit, lines
    assert "fixed values (not estimated):" in out.out
    assert re.search(r"U0\s+= 7.7175\s+m/s\s+vessel mariner: approach_speed", out.out), out.out
    fixed = json.loads((tmp_path / "r.json").read_text())["methods"]["equation_error"]["fixed"]
    assert fixed["U0"] == {"value": 7.7175, "unit": "m/s", "source": "vessel mariner: approach_speed"}, fixed["U0"]


def test_cli_constant_thrust_and_rigid_body_option(tmp_path, capsys):
    """Runs without a thrust column (constant propeller setting): ``--propulsion constant:N`` fits them; the
    equation-error estimate of the linear derivatives is within 2 % of the truth. ``--rigid-body-cg`` on a model
    without that option stops with one line."""
    from diffship.models import ConstantThrust, VMMLinear
    from diffship.models.vmm import approach_thrust
    from diffship.synthetic import rudder_sequence, simulate_run

    T0 = approach_thrust()
    truth = VMMLinear(propulsion=ConstantThrust(T0))
    tv = truth.param_values()
    truth = truth.with_params({n: 1.2 * tv[n] for n in ("Yv", "Yr", "Yd", "Nv", "Nr", "Nd")})
    t = np.arange(0.0, 300.0, 0.5)
    paths = []
    for i, amp in enumerate((10.0, -20.0)):
        run = simulate_run(truth, t, {"delta": rudder_sequence(t, np.radians(amp), 60.0 + 20 * i, rate=np.radians(2.3))},
                           np.array([0.0, 0.0, 0.0, float(truth.U0), 0.0, 0.0]), name=f"c{i}")
        assert "thrust" not in run.channels
        paths.append(str(tmp_path / f"c{i}.csv"))
        run.to_dataframe().to_csv(paths[-1], index=False)
    js = tmp_path / "c.json"
    code = fit_main([*paths, "--model", "vmm_linear", "--vessel", "mariner", "--propulsion", f"constant:{T0!r}",
                     "--method", "equation-error", "--filter", "savgol:5", "--json", str(js), "--quiet"])
    out = capsys.readouterr()
    assert code == 0, out.err
    got = json.loads(js.read_text())["methods"]["equation_error"]["params"]
    for n in ("Yv", "Yr", "Yd", "Nv", "Nr", "Nd"):
        assert got[n] == pytest.approx(truth.param_values()[n], rel=0.02), n
    assert "propulsion: constant:" in out.out
    assert fit_main(paths + ["--model", "vmm_linear", "--vessel", "mariner", "--free", "dwP", "--quiet"]) == 2
    assert "--free dwP: the wake-fraction correction enters only" in capsys.readouterr().err
    assert fit_main(paths[:1] + ["--model", "nomoto1", "--rigid-body-cg", "--quiet"]) == 2
    assert "--rigid-body-cg: model nomoto1 has no rigid-body reference option" in capsys.readouterr().err
