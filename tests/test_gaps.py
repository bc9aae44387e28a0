"""The gap rule of diffship.gaps: a step over 5 median steps and over 1 s stops with the run, the time and the fix."""

import numpy as np
import pytest

from diffship.errors import DataError
from diffship.gaps import check_gaps


def _times(dt: float, step: float) -> np.ndarray:
    """20 samples ``dt`` apart, one step of ``step`` s, 20 more."""
    a = np.arange(20) * dt
    return np.r_[a, a[-1] + step + a]


@pytest.mark.parametrize("dt, fine, gap", [(1.0, 5.0, 5.5), (0.02, 1.0, 1.2), (10.0, 50.0, 55.0)])
def test_a_gap_is_over_five_median_steps_and_over_one_second(dt, fine, gap):
    check_gaps("f.csv, run 'a'", _times(dt, fine))
    with pytest.raises(DataError) as e:
        check_gaps("f.csv, run 'a'", _times(dt, gap))
    msg = str(e.value)
    assert msg.startswith("f.csv, run 'a': no samples for ") and f"{gap:.3g} s between t=" in msg, msg
    assert "rows 19 and 20" in msg and "split the run there into two runs" in msg, msg
