"""Equivalent explanations: the probe manoeuvre that separates two structures."""

import math
from types import SimpleNamespace

import pytest

from diffship.discover.separate import GAINS, probe_runs, separating_manoeuvre
from diffship.integrators import Diffrax
from diffship.models.terms import with_terms
from diffship.synthetic import usv_runs, usv_truth

NOISE = {"psi": math.radians(0.5), "u": 0.05, "v": 0.05, "r": math.radians(0.2)}


def _fit(model):  # what separating_manoeuvre reads of a FitResult
    return SimpleNamespace(model=model, channels=("psi", "u", "v", "r"), integrator=Diffrax())


@pytest.fixture(scope="module")
def runs():
    return usv_runs(2, duration=60.0, dt=0.2, noise="none", seed=3)


def test_probes_scale_only_the_inputs(runs):
    probes = probe_runs(runs, usv_truth().input_names)
    assert len(probes) == len(runs) * len(GAINS)
    label, hard = probes[1]
    assert "×1.5" in label
    r0 = runs[0]
    for c in r0.channels:
        scale = 1.5 if c in usv_truth().input_names else 1.0
        assert hard[c] == pytest.approx(scale * r0[c])
    assert r0["tau_z"] is not hard["tau_z"]  # the user's run is not changed in place


def test_a_cubic_yaw_term_is_told_apart_by_the_harder_manoeuvre(runs):
    base = usv_truth()
    cubic = with_terms(base, ["N_r_r_r"], {"N_r_r_r": -2000.0})
    sep = separating_manoeuvre([_fit(base), _fit(cubic)], runs, NOISE)
    assert sep is not None
    # a cubic term grows faster than the linear ones: the inputs ×1.5 separate the two more than as logged
    for r in runs:
        assert sep.per_probe[f"{r.name} with its inputs ×1.5"] > sep.per_probe[f"{r.name} as logged"]
    assert "×1.5" in sep.manoeuvre and sep.difference > 1.0 and sep.heading_deg > 0.1
    # the same model twice: no difference anywhere
    same = separating_manoeuvre([_fit(base), _fit(base)], runs, NOISE)
    assert max(same.per_probe.values()) < 1e-9


def test_the_noise_defaults_to_the_logged_runs_sensor_noise(runs):
    noisy = usv_runs(2, duration=60.0, dt=0.2, noise="realistic", seed=3)
    base = usv_truth()
    cubic = with_terms(base, ["N_r_r_r"], {"N_r_r_r": -2000.0})
    own = separating_manoeuvre([_fit(base), _fit(cubic)], noisy)
    # the same differences over a noise level estimated from the runs: realistic sensors are near NOISE's levels
    given = separating_manoeuvre([_fit(base), _fit(cubic)], noisy, NOISE)
    assert own.manoeuvre == given.manoeuvre
    assert own.heading_deg == given.heading_deg
    assert 0.5 < own.difference / given.difference < 2.0
