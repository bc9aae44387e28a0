"""The diagnose command's checks before any fit (:func:`diffship.diagnose.__main__.input_problem` and the
run-length rule): outputs that cannot be written or would overwrite an input, a held-out run that is a training
run, an empty effects list, training runs too short for the question. Each stops with exit status 2 and one line;
none of these tests fits."""

import numpy as np
import pandas as pd
import pytest

from clitools import stops_with_one_line
from diffship.diagnose.__main__ import main


def _csv(path, n=200, dt=0.2):
    t = np.arange(n) * dt
    delta = 0.1 * np.sign(np.sin(2 * np.pi * t / 4.0) + 1e-9)
    pd.DataFrame({"time": t, "psi": 0.01 * t, "r": np.full(n, 0.01), "delta": delta}).to_csv(path, index=False)
    return str(path)


@pytest.fixture
def runs(tmp_path):
    return _csv(tmp_path / "train.csv"), _csv(tmp_path / "held.csv")


def _stop(argv, capsys, *words):
    stops_with_one_line(main, [*argv, "--model", "nomoto1", "--quiet"], capsys, *words)


def test_outputs_are_checked_before_any_fit(runs, tmp_path, capsys):
    train, held = runs
    plain = tmp_path / "existing.txt"
    plain.write_text("x")
    base = [train, "--validate", held]
    _stop([*base, "--out", str(plain)], capsys, f"--out {plain} is an existing file, not a folder")
    _stop([*base, "--json", str(tmp_path)], capsys, f"--json {tmp_path} is a folder: give a file name")
    _stop([*base, "--json", held], capsys, f"--json {held} is the held-out run", "overwrite")
    _stop([*base, "--html", str(plain / "x.html")], capsys, "--html", "is not a folder")
    _stop([*base, "--json", str(tmp_path / "a.json"), "--html", str(tmp_path / "a.json")], capsys, "both name")


def test_a_held_out_run_that_is_a_training_run_is_refused(runs, tmp_path, capsys):
    train, _ = runs
    _stop([train, "--validate", train], capsys, f"--validate {train} is also a training run", "never saw")
    other = str(tmp_path / "sub" / ".." / "train.csv")
    (tmp_path / "sub").mkdir()
    _stop([train, "--validate", other], capsys, "(the same file as", "also a training run")


def test_an_empty_effects_list_names_the_effects(runs, capsys):
    train, held = runs
    _stop([train, "--validate", held, "--effects", ""], capsys, "the effects list is empty", "input_delay", "wave")
    _stop([train, "--validate", held, "--effects", " , "], capsys, "the effects list is empty")


def test_training_runs_too_short_for_the_question_stop_before_the_fit(tmp_path, capsys):
    short, held = _csv(tmp_path / "short.csv", n=40), _csv(tmp_path / "held.csv")
    _stop([short, "--validate", held, "--effects", "input_delay,wave"], capsys,
          "hold 40 samples together", "20 samples per parameter", "nomoto1's 3 free")
