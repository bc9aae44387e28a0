"""Priors (MAP output error) and the identifiability report on every fit."""

import math

import pytest

from diffship.errors import ModelError
from diffship.fit import OutputErrorOptions, fit_output_error
from diffship.fit.identifiability import direction_text
from diffship.fit.priors import Prior, Priors, default_priors, load_priors, parse_priors
from diffship.models import Fossen3, Nomoto1
from diffship.synthetic import usv_runs, usv_truth

TV = usv_truth().param_values()
X0 = ("psi", "u", "v", "r")


@pytest.fixture(scope="module")
def usv_clean():
    return usv_runs(3, 60.0, 0.1, noise="none", seed=1)


def test_parse_priors_forms_and_errors(tmp_path):
    p = parse_priors(["Nrrr=-0.05±0.02", "Yv=-300+-10%", "K=1.5+/-0.5"])
    assert p.by_name["Nrrr"] == Prior(-0.05, 0.02, "command line")
    assert p.by_name["Yv"].sd == pytest.approx(30.0)
    assert p.by_name["K"].mean == 1.5
    with pytest.raises(ModelError, match="NAME=MEAN±SD"):
        parse_priors(["Yv=-300"])
    with pytest.raises(ModelError, match="positive"):
        parse_priors(["Yv=-300±0"])
    f = tmp_path / "p.json"
    f.write_text('{"Yv": {"mean": -300, "sd": 20}, "Nr": [-1800, 100]}')
    assert load_priors(f).by_name["Nr"] == Prior(-1800.0, 100.0, "file p.json")
    with pytest.raises(ModelError, match="unknown parameter"):
        p.check(Fossen3().spec())


def test_reference_priors_only_on_the_reference_vessel():
    m = Fossen3()
    pri, why = default_priors(m, m.spec())
    assert "on by default" in why
    # every free parameter with a nonzero reference value; the USV standard model has no added
    # masses (zero: not in the reference set, no prior)
    assert set(pri.by_name) == {n for n in m.spec().free_names if getattr(m, n) != 0}
    assert "Xudot" not in pri.by_name and "Nr" in pri.by_name
    other = m.spec().fix({"m": 2 * m.m})  # another vessel: its coefficients are no prior
    pri, why = default_priors(m, other)
    assert len(pri) == 0 and "m" in why and "differ" in why
    assert len(default_priors(Nomoto1(), Nomoto1().spec())[0]) == 0  # no reference set


def test_a_model_with_an_effect_keeps_its_base_reference_priors():
    """A fit with a candidate effect is regularised as the base fit is: the base's coefficients keep their
    reference priors, the effect's parameters get none (they have no reference value)."""
    from diffship.models.effects import augment

    m = Fossen3()
    base_pri, _ = default_priors(m, m.spec())
    aug = augment(m, "current")
    pri, why = default_priors(aug, aug.spec())
    assert "on by default" in why
    assert pri.by_name == base_pri.by_name
    assert not {"Vcx", "Vcy"} & set(pri.by_name)
    other = aug.spec().fix({"m": 2 * m.m})  # another vessel with a current: still no prior
    assert len(default_priors(aug, other)[0]) == 0


@pytest.mark.slow  # 20–30 s on 2 cores; tests/test_cli.py checks the undetermined Nomoto2 direction in the default run
def test_unidentifiable_direction_is_named_and_a_prior_pins_it(usv_clean):
    # m, Xu̇ and Yv̇ enter the 3-DOF equations only as m − Xu̇ and m − Yv̇: the direction
    # (1, 1, 1) in (m, Xu̇, Yv̇) is invisible in any data.
    spec = Fossen3().spec().free(["m"])
    opts = OutputErrorOptions(estimate_x0=X0, reference_priors=False)
    res = fit_output_error(Fossen3(), usv_clean, spec=spec, options=opts)
    ident = res.info["identifiability"]
    weak = ident["weak_directions"]
    assert weak, ident
    names = set(weak[0]["direction"])
    assert names == {"m", "Xudot", "Yvdot"}, weak[0]["text"]
    assert any("poorly identified direction" in m for m in res.messages)
    assert not math.isfinite(res.stderr["m"])

    # on noisy data, a 1 % prior on the mass settles it: finite errors, the added masses
    # recovered within their (posterior) errors, and the data add nothing to the mass
    pri = Priors({"m": Prior(TV["m"], 0.01 * TV["m"])}, "test")
    noisy = usv_runs(3, 60.0, 0.1, noise="realistic", seed=2)
    res2 = fit_output_error(Fossen3(), noisy, spec=spec,
                            options=OutputErrorOptions(estimate_x0=X0, reference_priors=False, priors=pri))
    assert all(math.isfinite(res2.stderr[n]) for n in res2.free), res2.stderr
    assert res2.info["priors"]["m"]["data_share"] < 0.05
    for n in ("Xudot", "Yvdot"):
        assert abs(res2.params[n] - TV[n]) < 3 * res2.stderr[n], (n, res2.params[n], res2.stderr[n])


def test_direction_text():
    assert direction_text({"a": 0.7, "b": -0.71}) == "−0.71·b + 0.70·a"


def test_a_parameter_on_its_bound_is_named():
    """A damping coefficient the data push onto its bound 0 is named, with the bound, in the warnings and the
    JSON; one well inside its bounds is not."""
    import numpy as np

    from diffship.fit.identifiability import identifiability
    from diffship.models import Nomoto1

    spec = Nomoto1().spec()
    names = spec.free_names
    J = np.eye(len(names))
    vals = {n: spec[n].value for n in names}
    assert not identifiability(J, spec, vals, np.eye(len(names))).on_bound
    bounded = next(n for n in names if np.isfinite(spec[n].lower) or np.isfinite(spec[n].upper))
    b = spec[bounded].lower if np.isfinite(spec[bounded].lower) else spec[bounded].upper
    ident = identifiability(J, spec, {**vals, bounded: b + 1e-4 * spec[bounded].scale * (1 if b == spec[bounded].lower else -1)},
                            np.eye(len(names)))
    assert [n for n, _, _ in ident.on_bound] == [bounded]
    assert any(f"{bounded} = " in w and "on its bound" in w for w in ident.warnings)
    assert ident.as_json()["on_bound"][0]["bound"] == b
