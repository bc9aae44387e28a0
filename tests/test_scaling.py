"""Froude scaling and the scale-aware helm rate."""

import math

import numpy as np
import pytest

from diffship import manoeuvres as M
from diffship.errors import ModelError
from diffship.models import Nomoto1
from diffship.models.mmg import kvlcc2_mmg
from diffship.scaling import IMO_HELM_RATE_DEG_S, FroudeScale, helm_rate


def test_froude_scale_kvlcc2():
    s = FroudeScale(45.714)
    assert s.length(7.0) == pytest.approx(320.0, abs=0.01)
    assert s.speed(1.179) == pytest.approx(7.971, abs=1e-3)  # 15.5 kn, the KVLCC2 design speed
    assert s.time(10.0) == pytest.approx(67.61, abs=0.01)
    assert s.rate(10.23) == pytest.approx(10.23 / math.sqrt(45.714))
    assert s.force(1.0) == pytest.approx(45.714**3 * 1.025)
    t, ch = s.channels(np.array([0.0, 1.0]), {"psi": np.array([0.1, 0.2]), "x0": np.array([1.0, 2.0])})
    np.testing.assert_allclose(t, [0.0, math.sqrt(45.714)])
    np.testing.assert_allclose(ch["psi"], [0.1, 0.2])
    np.testing.assert_allclose(ch["x0"], [45.714, 91.428])
    with pytest.raises(ModelError, match="positive"):
        FroudeScale(-1.0)


def test_helm_rate_follows_the_scale():
    assert IMO_HELM_RATE_DEG_S == pytest.approx(2.32, abs=0.005)
    rate, why = helm_rate(kvlcc2_mmg(), scale=45.714)
    assert rate == pytest.approx(15.7, abs=0.05) and "√λ" in why  # HSVA used 15.8°/s
    assert helm_rate(kvlcc2_mmg(), rudder_rate_deg_s=15.8)[0] == 15.8
    with pytest.raises(ModelError, match="L = 7 m long.*--helm-rate.*--scale"):
        helm_rate(kvlcc2_mmg())
    rate, why = helm_rate(Nomoto1())
    assert rate == pytest.approx(2.32, abs=0.005) and "no length" in why
    with pytest.raises(ModelError, match="L = 3 m"):
        helm_rate(Nomoto1(), length=3.0)


def test_manoeuvre_on_a_model_scale_ship_needs_a_rate():
    """zigzag() on the 7 m KVLCC2 model once silently used the full-scale 2.32°/s (6.8× slow)."""
    with pytest.raises(ModelError, match="model scale"):
        M.zigzag(kvlcc2_mmg(), {"u": 1.179}, inputs={"n": 10.23}, duration=5.0)
    run = M.zigzag(Nomoto1(K=0.1, T1=10.0), {}, rudder_deg=10.0, duration=20.0, dt=0.1, scale=16.0)
    assert run.metadata["rudder_rate_deg_s"] == pytest.approx(4 * 65 / 28)
    d = np.degrees(np.asarray(run["delta"]))
    assert np.max(np.diff(d)) / 0.1 == pytest.approx(4 * 65 / 28, rel=1e-6)
