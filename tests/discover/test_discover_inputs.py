"""The discover command's checks before any fit: outputs that cannot be written or would overwrite an input, a
held-out run that is a training run, training runs too short for the term search; and the table's held-out column
without held-out runs. Each check stops with exit status 2 and one line; none of these tests fits."""

import math

import numpy as np
import pandas as pd
import pytest

from clitools import stops_with_one_line
from diffship.discover.__main__ import main
from diffship.discover.report import _held


def _csv(path, n=600, dt=0.1):
    t = np.arange(n) * dt
    table = {"time": t, "psi": 0.01 * t, "u": np.full(n, 1.5), "v": np.zeros(n), "r": np.full(n, 0.01),
             "tau_x": np.full(n, 100.0), "tau_y": np.zeros(n), "tau_z": np.full(n, 10.0)}
    pd.DataFrame(table).to_csv(path, index=False)
    return str(path)


@pytest.fixture
def runs(tmp_path):
    return _csv(tmp_path / "train.csv"), _csv(tmp_path / "held.csv")


def _stop(argv, capsys, *words):
    stops_with_one_line(main, [*argv, "--model", "fossen3", "--vessel", "usv", "--quiet"], capsys, *words)


def test_outputs_are_checked_before_any_fit(runs, tmp_path, capsys):
    train, held = runs
    plain = tmp_path / "existing.txt"
    plain.write_text("x")
    _stop([train, "--out", str(plain)], capsys, f"--out {plain} is an existing file, not a folder")
    _stop([train, "--save", str(tmp_path)], capsys, f"--save {tmp_path} is a folder: give a file name")
    _stop([train, "--validate", held, "--json", train], capsys, f"--json {train} is the training run")
    _stop([train, "--save", str(tmp_path / "f.json"), "--json", str(tmp_path / "f.json")], capsys, "both name")


def test_a_held_out_run_that_is_a_training_run_is_refused(runs, capsys):
    train, _ = runs
    _stop([train, "--validate", train], capsys, f"--validate {train} is also a training run")


def test_training_runs_too_short_for_the_search_stop_before_the_fit(tmp_path, capsys):
    _stop([_csv(tmp_path / "short.csv", n=15)], capsys, "hold 15 samples together", "fossen3's 10 free and 4 terms",
          "280")


def test_no_held_out_score_prints_a_dash():
    assert _held(math.nan) == "—" and _held(None) == "—" and _held(0.5) == "0.500"
