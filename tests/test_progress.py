"""Progress of long solves (:mod:`diffship.progress`): heard while running, and the fit is the same
with and without it."""

import time

import numpy as np

from diffship.fit import OutputErrorOptions, fit_output_error
from diffship.models import Nomoto1
from diffship.progress import heartbeat
from diffship.synthetic import nomoto_runs


def test_heartbeat_reports_while_the_block_runs_and_stops_after():
    heard = []
    with heartbeat(heard.append, "solve", every=0.05):
        time.sleep(0.32)
    n = len(heard)
    time.sleep(0.15)
    assert 3 <= n <= 7 and len(heard) == n, heard  # one beat per 0.05 s, none after the block
    assert heard[0].startswith("solve: still running")


def test_each_start_reports_steps_cost_and_time_per_step_and_the_fit_is_unchanged():
    runs = nomoto_runs(Nomoto1(K=0.2, T1=8.0), n_runs=1, duration=30.0, dt=0.1, noise="none")
    heard = []
    loud = fit_output_error(Nomoto1(), runs, options=OutputErrorOptions(weights="spread"), progress=heard.append,
                            n_starts=3)
    quiet = fit_output_error(Nomoto1(), runs, options=OutputErrorOptions(weights="spread"), n_starts=3)
    done = [h for h in heard if "done (" in h]
    assert len(done) == 3 and all("steps, cost" in h and "ms/step" in h for h in done), heard
    assert loud.params == quiet.params and loud.stderr == quiet.stderr and loud.cost == quiet.cost
    assert abs(loud.params["K"] - 0.2) < 1e-4
