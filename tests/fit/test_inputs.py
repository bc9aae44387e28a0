"""The fit command's checks of what it was given (:mod:`diffship.fit.inputs`): held-out runs without a training
run, file names taken by list options, contradictory options, outputs over inputs or where nothing can be
written, a time unit or resample step that does not fit the runs. Each stops with exit status 2 and one line
naming the option or file, before any fit (none of these tests fits)."""

import numpy as np
import pandas as pd
import pytest

from clitools import stops_with_one_line
from diffship.fit.args import build_parser, precheck
from diffship.fit.cli import main as fit_main


@pytest.fixture
def csv(tmp_path):
    t = np.arange(200) * 0.1
    path = tmp_path / "run.csv"
    pd.DataFrame({"time": t, "psi": 0.01 * t, "r": np.full(t.size, 0.01), "delta": np.full(t.size, 0.05)}).to_csv(
        path, index=False)
    return str(path)


def _stop(argv, capsys, *words, read=False, model="nomoto1"):
    """The fit's exit status 2 and its one line, which holds ``words``; unless the runs (or the model's parameters)
    must be ``read`` to find it, the JAX-free precheck says the same."""
    argv = [*argv, "--model", model, "--quiet"]
    err = stops_with_one_line(fit_main, argv, capsys, *words)
    assert read or precheck(argv) == err.removeprefix("error: "), (precheck(argv), err)
    return err


def test_held_out_runs_without_a_training_run_stop(csv, tmp_path, capsys):
    """``--validate A B``: no training file is left; the bundled example is not fitted in its place."""
    _stop(["--validate", csv, csv], capsys, "no training run given", "before --validate", "after --")
    args = build_parser().parse_args(["--validate", "held.csv", "--", "train.csv"])
    assert args.runs == ["train.csv"] and args.validate == ["held.csv"]


@pytest.mark.parametrize("option", ["--degrees", "--free"])
def test_list_options_refuse_the_file_names_they_took(option, csv, capsys):
    for words in ([option, "delta", csv], [option, "delta", "later.parquet"]):
        with pytest.raises(SystemExit) as e:
            build_parser().parse_args(words)
        err = capsys.readouterr().err
        assert e.value.code == 2 and f"argument {option}: '{words[-1]}' is a file name" in err, err
        assert "put the run files first" in err
    assert build_parser().parse_args([csv, "--degrees", "delta", "r"]).degrees == ["delta", "r"]


@pytest.mark.parametrize("argv, words", [
    (["--fix", "K=1", "--free", "K"], ("--fix K=1", "--free K")),
    (["--fix", "K=1", "--init", "K=2"], ("--fix K=1", "--init K=2")),
    (["--fix", "K=1", "--prior", "K=2±0.1"], ("--fix K=1", "--prior K=2±0.1")),
    (["--method", "equation-error", "--shooting", "multiple:5"], ("--shooting multiple:5", "--method equation-error")),
    (["--method", "prediction-error", "--shooting", "multiple"], ("--shooting multiple", "--method prediction-error")),
    (["--check-sampling"], ("--check-sampling", "--resample")),
])
def test_contradictory_options_name_both(argv, words, csv, capsys):
    _stop([csv, *argv], capsys, *words)


@pytest.mark.parametrize("option", ["--save", "--json", "--html"])
def test_an_output_over_an_input_file_stops(option, csv, tmp_path, capsys):
    before = open(csv).read()
    _stop([csv, option, csv], capsys, f"{option} {csv} is the training run", "overwrite")
    other = tmp_path / "held.csv"
    other.write_text(before)
    _stop([csv, "--validate", str(other), option, str(tmp_path / "." / "held.csv")], capsys, "the held-out run")
    assert open(csv).read() == before


def test_outputs_that_cannot_be_written_stop(csv, tmp_path, capsys):
    _stop([csv, "--out", csv], capsys, f"--out {csv} is an existing file, not a folder")
    _stop([csv, "--out", str(tmp_path / "run.csv" / "sub")], capsys, "--out", "is not a folder")
    _stop([csv, "--json", str(tmp_path)], capsys, f"--json {tmp_path} is a folder")
    _stop([csv, "--json", str(tmp_path / "a.json"), "--save", str(tmp_path / "a.json")], capsys,
          "--save and --json both name")
    prior = tmp_path / "fit.json"
    prior.write_text("{}")
    _stop([csv, "--prior-file", str(prior), "--out", str(tmp_path)], capsys, "would write fit.json over the "
          "--prior-file file")


def test_a_new_out_folder_is_checked_without_being_left_behind(tmp_path, capsys):
    """A folder ``--out`` would create is probed, and removed again when the command stops for another reason."""
    out = tmp_path / "new" / "deep"
    _stop([str(tmp_path / "missing.csv"), "--out", str(out)], capsys, "missing.csv", read=True)
    assert not (tmp_path / "new").exists()


def test_time_unit_and_resample_that_do_not_fit_the_runs_stop(csv, capsys):
    _stop([csv, "--time-unit", "ms"], capsys, "10000 Hz", "1000 Hz or slower", "--time-unit s", read=True)
    _stop([csv, "--resample", "100"], capsys, "--resample 100: run 'run' lasts 19.9 s", "at most 2.2 s", read=True)


def test_a_held_out_run_that_is_a_training_run_stops(csv, capsys):
    _stop([csv, "--validate", csv], capsys, f"--validate {csv} is also a training run", "never saw")


def test_an_init_of_a_parameter_the_fit_holds_stops(csv, capsys):
    """fossen3 holds Yr (not in its default free set) and takes m from the vessel: a start value for either would
    silently become the value the fit holds it at; freed by --free or --free-hydrodynamic, the start is taken
    (the command goes on, to the runs, which lack fossen3's channels: no fit)."""
    from diffship.models import Fossen3

    held = Fossen3().spec()["Yr"].value
    _stop([csv, "--vessel", "usv", "--init", "Yr=-0.5"], capsys, "--init Yr=-0.5: Yr is not estimated",
          f"held at {held:g}", "add --free Yr to estimate it from -0.5", "--fix Yr=-0.5 to hold it there",
          read=True, model="fossen3")
    _stop([csv, "--vessel", "usv", "--init", "m=30"], capsys, "--init m=30: m is not estimated", read=True,
          model="fossen3")
    for free in (["--free", "Yr"], ["--free-hydrodynamic"]):
        err = _stop([csv, "--vessel", "usv", *free, "--init", "Yr=-0.5"], capsys, read=True, model="fossen3")
        assert "--init" not in err, (free, err)


def test_diagnose_and_discover_refuse_an_init_of_a_held_parameter():
    """Their shared first step (:func:`diffship.vessel.model_spec`) applies the same rule, and names --fix too."""
    from diffship.errors import ModelError
    from diffship.vessel import model_spec

    with pytest.raises(ModelError, match=r"^--init Yr=-0.5: Yr is not estimated .*add --free Yr"):
        model_spec("fossen3", "usv", [], ["Yr=-0.5"], [])
    with pytest.raises(ModelError, match=r"^--fix Yr=-1 and --init Yr=-0.5: a fixed parameter is not estimated"):
        model_spec("fossen3", "usv", ["Yr=-1"], ["Yr=-0.5"], ["Yr"])
    _, spec, _, init = model_spec("fossen3", "usv", [], ["Yr=-0.5"], ["Yr"])
    assert spec["Yr"].free and init == {"Yr": -0.5}
