"""KVLCC2 real-data study: MMG output-error fit on some HSVA zigzags, overshoots of the others."""

import jax.numpy as jnp
import numpy as np
import pytest

from diffship.data import kvlcc2_runs
from diffship.errors import DataError
from diffship.models.mmg import kvlcc2_mmg
from diffship.manoeuvres.drive import turning_circle
from diffship.manoeuvres.imo import turning_metrics
from diffship.studies.kvlcc2 import (
    AUTOPILOT_DELAY_S,
    HELM_RATE_DEG_S,
    autopilot_delays,
    kvlcc2_study,
    predict_zigzags,
)


@pytest.fixture(scope="module")
def runs():
    try:
        return {r.name.replace("KVLCC2_", ""): r for r in kvlcc2_runs()}
    except DataError as exc:
        pytest.skip(f"KVLCC2 HSVA data not available (../shared/data/kvlcc2_hsva): {exc}")


def test_hsva_autopilot_delay(runs):
    """The rudder starts to reverse about 0.28 s after the heading reaches ±ψ_s (every reversal
    but the first, where the rudder may still be moving). Measured: median 0.28 s, all within
    0.13–0.38 s; the spread comes from the runs with small switch angles, where an error of
    0.1° in the initial heading shifts the crossings by ±0.1 s alternately."""
    later = np.array([d for r in runs.values() for d in autopilot_delays(r)[1:]])
    assert len(later) > 50
    assert 0.1 <= later.min() and later.max() <= 0.45
    assert np.mean((later >= 0.2) & (later <= 0.4)) > 0.85
    assert np.median(later) == pytest.approx(AUTOPILOT_DELAY_S, abs=0.03)


def _straight_speed(model, n=10.23):
    def du(u):
        return float(model.vector_field(0.0, jnp.array([0.0, 0.0, 0.0, u, 0.0, 0.0]), jnp.array([0.0, n]))[3])

    lo, hi = 0.5, 2.0
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if du(mid) > 0 else (lo, mid)
    return lo


def test_study_predicts_validation_first_overshoots_within_2deg(runs):
    """The default study (MMG, 10 free parameters, fitted on 10/5, 20/5, 35/5 and 20/10-S, first
    100 s at 5 Hz), reduced to four validation zigzags (10/10 both sides, 20/10 port-first, 15/5),
    flown by the fitted model with the autopilot.

    Default study: 33 coefficients free (hull, added masses, rudder interaction, manoeuvring
    wake), each with its published value as a ±50 % prior, data weighted by their effective
    sample size. Measured: first-overshoot errors −0.85° (10/10-S), −0.39° (10/10-P), −0.82°
    (20/10-P), −0.76° (15/5); second overshoots −3.0°, −1.0°, +0.8°, −1.4°. The 35° turning
    circle, a manoeuvre type not in the training data, has a tactical diameter of 3.17 L
    (starboard) and 3.10 L (port); free-running measurements give 3.1–3.3 L. Without the priors,
    ten parameters free, it was 5.6–6.5 L: the zigzags bend N_vvr and flip N_rrr. The published
    coefficients miss the 10/10-S first overshoot by 4.5°; straight-run speed at 10.23 rps:
    fitted 1.18 m/s, published 1.02 m/s.
    """
    validate = ("Z_10_10_S", "Z_10_10_P", "Z_20_10_P", "Z_15_05")
    st = kvlcc2_study(validate=validate)
    assert st.fit.converged, st.fit.status
    v = st.table[st.table.role == "validate"].set_index("test")
    assert list(v.index) == list(validate)
    assert st.max_first_overshoot_error("cl") < 1.0  # first overshoots within 1°
    # predictive: a 35° turn, a manoeuvre type not in the training data
    for side in ("starboard", "port"):
        tc = turning_circle(st.fit.model, {"u": 1.179}, inputs={"n": 10.23}, duration=120.0,
                            rudder_rate_deg_s=HELM_RATE_DEG_S, first=side)
        td = turning_metrics(tc, length=7.0).in_lengths()["tactical_diameter"]
        assert td == pytest.approx(3.2, rel=0.05), (side, td)  # measured 3.1–3.3 L; no priors: 5.6–6.5 L
    assert v.loc["Z_10_10_S", "first_meas"] == pytest.approx(9.7, abs=0.2)  # data README
    # the fit is what makes the prediction good: the published coefficients miss by far more
    pub, _, _ = predict_zigzags(kvlcc2_mmg(), [runs[k] for k in validate])
    assert np.max(np.abs(pub.err_first_cl)) > 3.0
    assert _straight_speed(st.fit.model) == pytest.approx(1.179, rel=0.03)
    assert abs(st.fit.params["delta0"]) < 0.02  # a small neutral rudder angle [rad]
    # the report names the directions zigzags cannot see instead of pretending to know them
    assert st.fit.info["identifiability"]["weak_directions"]


@pytest.mark.slow
def test_study_fit_moves_the_rudder_neutral_angle_by_an_injected_zero_error(runs):
    """``study_fit`` on given runs (as ``benchmarks/withheld_real.py --base study`` calls it): a
    rudder indicator zero error of 1° (δ_log = δ − 1°) is exactly a shift of MMG's rudder neutral
    angle (d = δ + δ_0, no prior on δ_0: its reference value is 0), so the fitted δ_0 moves by
    1° whatever the rest of the real gap. Two zigzags, 40 s at 0.5 s, δ_0 alone free."""
    from diffship.data import Run
    from diffship.studies.kvlcc2 import study_fit

    prep = [runs[k].resample(0.5).slice(None, runs[k].t0 + 40.0) for k in ("Z_10_05", "Z_20_05")]
    zero = np.deg2rad(1.0)
    shifted = [Run(r.name, r.time, {**{c: np.asarray(r[c]) for c in r.channels}, "delta": np.asarray(r["delta"]) - zero},
                   dict(r.metadata)) for r in prep]
    clean, injected = (study_fit(rr, free=("delta0",), max_steps=30) for rr in (prep, shifted))
    assert clean.converged and injected.converged
    moved = injected.params["delta0"] - clean.params["delta0"]
    assert np.rad2deg(moved) == pytest.approx(1.0, abs=0.02)
