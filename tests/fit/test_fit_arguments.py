"""The fit driver refuses bad arguments at once, naming the argument or parameter (nothing is fitted)."""

import numpy as np
import pytest

from diffship.data import example_runs, resample_runs
from diffship.errors import DataError, FitError, ModelError
from diffship.fit import fit_output_error
from diffship.models import Nomoto1


@pytest.fixture(scope="module")
def runs():
    return resample_runs(example_runs(), 0.2)


@pytest.mark.parametrize("kw, pattern", [
    ({"init": {"T1": float("nan")}}, "init: parameter T1: value nan is not finite"),
    ({"init": {"K": float("inf")}}, "init: parameter K: value inf is not finite"),
    ({"starts": [{"T1": float("nan")}]}, "start 1: parameter T1: value nan is not finite"),
    ({"starts": {"mine": {"T1": "x"}}}, "start 'mine': parameter T1: value 'x' is not a number"),
    ({"starts": [{"T9": 1.0}]}, "start 1: unknown parameter 'T9'"),
])
def test_bad_start_values_and_names(runs, kw, pattern):
    with pytest.raises(ModelError, match=pattern):
        fit_output_error(Nomoto1(), runs, **kw)


def test_a_start_for_a_fixed_parameter(runs):
    m = Nomoto1()
    with pytest.raises(ModelError, match="parameter delta0 is fixed"):
        fit_output_error(m, runs, spec=m.spec().fix(["delta0"]), starts=[{"delta0": 0.01}])


def test_an_init_of_a_fixed_parameter_is_refused(runs):
    """``init`` gives start values: for a fixed parameter it would silently replace the value the fit holds it at."""
    from diffship.fit import fit_both

    m = Nomoto1()
    spec = m.spec().fix({"delta0": 0.0})
    with pytest.raises(ModelError, match=r"^init: parameter delta0 is fixed \(at 0\)"):
        fit_output_error(m, runs, spec=spec, init={"T1": 5.0, "delta0": 0.01})
    with pytest.raises(ModelError, match=r"^init: parameter delta0 is fixed"):  # before equation error runs
        fit_both(m, runs, spec=spec, init={"delta0": 0.01})


@pytest.mark.parametrize("n", [0, -3, 2.5, True])
def test_n_starts_must_be_a_whole_number_at_least_1(runs, n):
    with pytest.raises(FitError, match=f"n_starts={n!r}"):
        fit_output_error(Nomoto1(), runs, n_starts=n)


def test_runs_must_be_a_list_of_runs(runs):
    with pytest.raises(DataError, match=r"a single Run .*pass a list of runs, e.g. \[run\]"):
        fit_output_error(Nomoto1(), runs[0])
    with pytest.raises(DataError, match=r"runs: item 0 \(ndarray\) not a diffship Run"):
        fit_output_error(Nomoto1(), [np.zeros(5)])


def test_channels_must_be_a_sequence_of_names(runs):
    with pytest.raises(DataError, match=r"channels='psi': a single string.*\('psi',\)"):
        fit_output_error(Nomoto1(), runs, channels="psi")
