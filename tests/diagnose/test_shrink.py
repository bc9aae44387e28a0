"""The shrink is the share of the structural (above-noise) RMS gap closed."""

import math

import pytest

import diffship  # noqa: F401
from diffship.diagnose.shrink import structural_gap, structural_shrink


def test_shrink_is_the_share_of_the_structural_rms_gap():
    # E² = 1 (noise) + S² (structure): from E0 = 1.5 to E = 1.1 only 59 % of S is gone
    # (the linear (E0 − E)/(E0 − 1) would claim 80 %)
    assert structural_gap(1.5) == pytest.approx(math.sqrt(1.25))
    assert structural_shrink(1.5, 1.5, 1.1) == pytest.approx(1 - math.sqrt(0.21) / math.sqrt(1.25))
    assert structural_shrink(1.5, 1.5, 1.1) < 0.6
    assert structural_shrink(5.0, 5.0, 1.0) == pytest.approx(1.0)
    assert structural_shrink(5.0, 5.0, 0.98) == pytest.approx(1.0)  # below the floor: all of it
    # steps add up to the whole path
    assert structural_shrink(4.0, 4.0, 2.0) + structural_shrink(4.0, 2.0, 1.2) == pytest.approx(
        structural_shrink(4.0, 4.0, 1.2))
    assert structural_shrink(0.9, 0.9, 0.8) == 0.0  # no structural gap
