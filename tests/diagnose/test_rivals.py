"""Rivals the runs cannot rank: a current and a force fixed to the hull on runs about one course."""

import math
from types import SimpleNamespace

import numpy as np

from diffship.diagnose.rivals import SEPARATING_TURN, collinear_rivals, heading_turn


def _batch(headings_deg):
    """A batch-like stand-in: runs of heading series (deg), padded and masked as a Batch is."""
    n = max(len(h) for h in headings_deg)
    ys = np.zeros((len(headings_deg), n, 2))
    mask = np.zeros((len(headings_deg), n), dtype=bool)
    for k, h in enumerate(headings_deg):
        ys[k, :len(h), 0] = np.radians(h)
        mask[k, :len(h)] = True
    return SimpleNamespace(channels=("psi", "r"), ys=ys, mask=mask)


def test_the_turn_is_measured_from_each_runs_start_through_the_wrap():
    zigzag = 10.0 + 25.0 * np.sin(np.linspace(0, 6 * np.pi, 300))  # ±25° about 10°
    assert abs(math.degrees(heading_turn(_batch([zigzag]))) - 25.0) < 0.1
    # a turning circle logged in (−180°, 180°]: 270° of turn, not the 360° jump of the wrap
    circle = (np.linspace(0.0, 270.0, 500) + 180.0) % 360.0 - 180.0
    assert abs(math.degrees(heading_turn(_batch([zigzag, circle]))) - 270.0) < 0.5
    # the padding of a shorter run is not read as heading
    assert abs(math.degrees(heading_turn(_batch([zigzag[:100], circle]))) - 270.0) < 0.5
    assert heading_turn(SimpleNamespace(channels=("r",), ys=np.zeros((1, 3, 1)), mask=np.ones((1, 3)))) == math.inf


def test_a_current_and_a_constant_force_are_rivals_only_without_a_large_turn():
    said = []
    small, large = math.radians(26.0), SEPARATING_TURN + 0.1
    assert collinear_rivals("constant_force", ["current", "damping_vr"], small, said.append) == ["current"]
    assert "26°" in said[0]
    assert collinear_rivals("current", ["constant_force"], small) == ["constant_force"]
    assert collinear_rivals("constant_force", ["current"], large) == []
    assert collinear_rivals("damping_vr", ["current", "actuator_lag"], small) == []
