"""The fit's batch of runs and its default channels (:mod:`diffship.fit.problem`)."""

import numpy as np

from diffship.data import Run
from diffship.fit.problem import default_channels, unfitted_positions
from diffship.models import Fossen3, Nomoto1


def _run(name, channels):
    t = np.arange(0.0, 20.0, 0.1)
    return Run(name, t, {c: np.sin(0.1 * t + k) for k, c in enumerate(channels)})


def test_positions_measured_in_every_run_are_left_out_by_default_and_the_report_says_how_to_add_them():
    model = Fossen3()
    full = ("x0", "y0", "psi", "u", "v", "r", "tau_x", "tau_y", "tau_z")
    runs = [_run("a", full), _run("b", full)]
    assert default_channels(model, runs) == ("psi", "u", "v", "r")
    note = unfitted_positions(model, runs, None)
    assert len(note) == 1 and "x0, y0" in note[0] and "--channels x0 y0 psi u v r" in note[0]
    assert unfitted_positions(model, runs, ("psi", "u", "v", "r")) == []  # the user chose the channels
    # a run without positions: nothing left out, nothing said
    assert unfitted_positions(model, [runs[0], _run("c", full[2:])], None) == []
    assert unfitted_positions(Nomoto1(), [_run("d", ("psi", "r", "delta"))], None) == []
