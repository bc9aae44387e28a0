"""Physical admissibility of a fitted model outside its training envelope."""

import pytest

from diffship.admissibility import admissibility
from diffship.models.mmg import kvlcc2_mmg

KW = dict(initial={"u": 1.179}, inputs={"n": 10.23}, helm_rate_deg_s=15.8, turn_s=100.0, zigzag_s=80.0, n_grid=5)


@pytest.fixture(scope="module")
def ref():
    return kvlcc2_mmg()


def test_published_kvlcc2_is_admissible(ref):
    a = admissibility(ref, reference=ref, **KW)
    assert a.ok, a.summary()
    # the 35° turn reaches a drift and yaw rate well beyond a zigzag: the envelope covers it
    assert a.envelope["r"][1] > 0.05 and a.envelope["v"][1] > 0.1
    assert {"turning 35° starboard", "zigzag 20/20", "pull-out 20°"} <= set(a.runs)


def test_destabilising_cubic_yaw_damping_is_caught_and_named(ref):
    # N_rrr > 0 (the sign a zigzag-only fit can produce) makes yaw damping negative at large r'
    bad = ref.with_params({**ref.param_values(), "Nrrr": 0.3})
    a = admissibility(bad, reference=ref, free=("Yv", "Nr", "Nvvr", "Nrrr"), **KW)
    assert not a.ok
    damp = next(c for c in a.checks if c.name.startswith("r-motion"))
    assert not damp.passed and damp.offending[0] == "Nrrr"
    assert "Nrrr" in a.offending
    assert "NOT ADMISSIBLE" in a.summary() and a.as_json()["ok"] is False
