"""The sea-state check's prediction-error fit (:class:`~diffship.diagnose.sea_state.NarrowBandCheck`): where the
wave's damping reaches its bound from every start, the fit ends there with the full fit's verdict (broad, the damping
on its bound); where it does not, the fit is the full fit. Independent truths: an autopilot in a disturbance of the
wave's form (benchmarks/independent/autopilot_waves.py), overdamped (broad) or narrow-band."""

import math
import sys
from pathlib import Path

import pytest

from diffship.data import Run
from diffship.diagnose.sea_state import NarrowBandCheck
from diffship.fit import fit, fit_output_error
from diffship.fit.disturbance import CLIP
from diffship.fit.output_error import OutputErrorOptions
from diffship.fit.prediction_error import PredictionError, PredictionErrorOptions
from diffship.models import Nomoto1

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from benchmarks.independent.autopilot_waves import WaveShip, autopilot_runs  # noqa: E402

CH = ("psi", "r")


def _both(ship: WaveShip):
    g = autopilot_runs(1, n_runs=2, duration=300.0, ship=ship)
    runs = [Run(x["name"], x["time"], x["channels"], {"source": "independent"}) for x in g]
    oe = fit_output_error(Nomoto1(), runs, channels=CH)
    kw = dict(spec=oe.model.spec().only_free(oe.free), channels=CH, n_starts=2, throw=False,
              starts={"the base fit's values": {n: oe.params[n] for n in oe.free}})
    est = dict(oe=OutputErrorOptions(integrator=oe.integrator), noise=PredictionErrorOptions(disturbance="wave"))
    return fit(oe.model, runs, NarrowBandCheck(**est), **kw), fit(oe.model, runs, PredictionError(**est), **kw)


def _broad(pe) -> bool:
    return math.log(pe.info["wave_damping"] / PredictionErrorOptions().wave_damping) >= CLIP["wave_damping"][1] - 1e-6


def test_a_broad_disturbance_ends_the_fit_on_its_bound_with_the_full_fits_verdict():
    """Overdamped (ζ = 3) yaw disturbance, 0.02 rad/s² sd: measured, both fits end with the damping on its bound;
    the check's ends there, not converged, within 0.3 % of the full fit's cost."""
    check, full = _both(WaveShip(wave_damping=3.0, wave_sd=0.02))
    assert check.info["ended_at_bound"] and _broad(check) and _broad(full)
    assert check.usable and any("reached the bound of its clip" in m for m in check.messages)
    assert check.cost == pytest.approx(full.cost, rel=3e-3) and check.cost >= full.cost


def test_a_narrow_band_wave_is_the_full_fit():
    """The fixture wave of tests/fit/test_at_sea.py (8 s, ζ 0.08): the rule never fires, the fit is the full fit."""
    check, full = _both(WaveShip(wave_sd=0.008))
    assert not check.info["ended_at_bound"] and not _broad(check)
    assert check.params == full.params and check.info["wave_period"] == full.info["wave_period"]
    assert abs(check.info["wave_period"] / 8.0 - 1) < 0.1
