"""Rudder release in the turning metrics, the one first-side convention, the turn-direction check."""

import numpy as np
import pytest

from diffship import manoeuvres as M
from diffship.data import example_runs
from diffship.errors import DataError
from diffship.integrators import RK4
from diffship.models import Nomoto1
from diffship.models.mmg import kvlcc2_mmg


@pytest.fixture(scope="module")
def turn_and_release():
    kw = {"rudder_deg": 35.0, "inputs": {"n": 10.23}, "dt": 0.5, "t_execute": 1.0, "rudder_rate_deg_s": 15.8,
          "integrator": RK4(substeps=2)}
    m = kvlcc2_mmg()
    po = M.pull_out(m, {"u": 1.179}, turn_s=220.0, settle_s=100.0, **kw)
    return po


def test_release_is_detected_in_the_turning_metrics(turn_and_release):
    """A turning-circle record that continues after the rudder returns to zero: the steady diameter
    comes from the turn only (before: the straight run after release entered the circle fit)."""
    po = turn_and_release
    t_rel = po.metadata["t_release"]
    cut = M.turning_metrics(po.slice(None, t_rel), length=7.0)
    auto = M.turning_metrics(po, length=7.0)
    assert np.isfinite(cut.steady_diameter)
    assert auto.steady_diameter == pytest.approx(cut.steady_diameter, rel=1e-3)
    assert auto.tactical_diameter == pytest.approx(cut.tactical_diameter, rel=1e-9)
    blind = M.turning_metrics(po, length=7.0, detect_release=False)
    assert abs(blind.steady_diameter - cut.steady_diameter) > 0.05 * cut.steady_diameter
    assert M.turning_metrics(po, length=7.0, t_end=t_rel, detect_release=False).steady_diameter == pytest.approx(
        cut.steady_diameter, rel=1e-9)
    assert 0.0 < po.time[M.rudder_release(po)] - t_rel <= 35.0 / 15.8 + 0.5  # the rudder takes 2.2 s back


def test_first_side_accepts_names_and_signs():
    assert M.side_sign("starboard") == M.side_sign(1) == M.side_sign("S") == 1.0
    assert M.side_sign("port") == M.side_sign(-1) == M.side_sign("p") == -1.0
    assert M.side_name(-1.0) == "port"
    with pytest.raises(DataError, match="starboard' \\(\\+1\\) or 'port' \\(-1\\)"):
        M.side_sign("left")
    nom = Nomoto1(K=0.1, T1=10.0)
    a = M.zigzag(nom, {}, rudder_deg=10.0, first=-1, duration=60.0, dt=0.1)
    b = M.zigzag(nom, {}, rudder_deg=10.0, first="port", duration=60.0, dt=0.1)
    np.testing.assert_array_equal(a["psi"], b["psi"])
    assert a.metadata["first_rudder"] == "port" == M.zigzag_metrics(a).first_rudder


def test_turn_direction_check_on_the_sspa_zigzag():
    run = example_runs("sspa_zigzag")[0]  # loaded port-positive → starboard-positive: agrees
    ok = M.check_turn_direction(run)
    assert ok is not None and ok["agrees"]
    flipped = run.with_channels(delta=-np.asarray(run["delta"]))
    bad = M.check_turn_direction(flipped)
    assert bad is not None and not bad["agrees"] and "the other way" in bad["text"]
