"""The checks of runs against a model before any compute (diffship.checks): inputs that move, motion that
changes, the columns a run lacking a channel has."""

import numpy as np
import pytest

from diffship.checks import check_excitation, check_motion, check_runs
from diffship.data import Run
from diffship.errors import DataError, DiffshipError
from diffship.models import Decay1, Nomoto1

T = np.arange(100) * 0.1


def _run(name, **channels):
    return Run(name, T, {"psi": 0.01 * T, "r": np.full(T.size, 0.01), **channels}, {"source": f"{name}.csv"})


def test_a_rudder_that_never_moves_in_any_training_run_stops():
    still = [_run("a", delta=np.full(T.size, 0.1)), _run("b", delta=np.full(T.size, 0.1))]
    with pytest.raises(DataError) as e:
        check_excitation(Nomoto1(), still)
    msg = str(e.value)
    for part in ("model nomoto1", "no excitation for delta", "delta holds one value", "a.csv (run 'a')", "run 'b'"):
        assert part in msg, msg
    with pytest.raises(DataError, match="delta is 0 in every sample"):
        check_excitation(Nomoto1(), [_run("z", delta=np.zeros(T.size))])
    check_excitation(Nomoto1(), still + [_run("c", delta=0.1 * np.sin(T))])  # one run moves it: enough
    check_excitation(Nomoto1(), [_run("d", delta=np.full(T.size, 0.1)), _run("e", delta=np.full(T.size, 0.2))])


def test_a_model_without_a_needed_input_is_not_checked():
    check_excitation(Decay1(), [Run("decay", T, {"velocity": np.exp(-T), "tau": np.zeros(T.size)})])


def test_a_run_whose_motion_never_changes_stops_in_training_and_validation():
    moving = _run("ok", delta=0.1 * np.sin(T))
    still = Run("still", T, {"psi": np.zeros(T.size), "r": np.zeros(T.size), "delta": 0.1 * np.sin(T),
                             "x0": 2.0 * T}, {"source": "still.csv"})
    for runs in ([still], [moving, still]):
        with pytest.raises(DataError) as e:
            check_motion(Nomoto1(), runs)
        msg = str(e.value)
        assert "still.csv (run 'still'): psi = 0, r = 0 in every sample" in msg and "run 'ok'" not in msg, msg
    check_motion(Nomoto1(), [moving])
    check_motion(Nomoto1(), [still], channels=["psi", "x0"])  # the positions asked for change


def test_missing_input_message_lists_the_columns_the_file_has():
    with pytest.raises(DiffshipError) as e:
        check_runs(Nomoto1(), [_run("nodelta")])
    msg = str(e.value)
    assert "nodelta.csv (run 'nodelta') lacks delta (its columns: time, psi, r)" in msg, msg
    assert "inputs here: )" not in msg and "no input channel" in msg, msg
