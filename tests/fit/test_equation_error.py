import numpy as np
import pytest

from diffship.errors import DataError
from diffship.fit import fit_equation_error
from diffship.models import Fossen3, Nomoto1
from diffship.preprocess import Filter
from diffship.synthetic import nomoto_runs, usv_runs, usv_truth


def test_nomoto1_equation_error_noise_free():
    truth = Nomoto1(K=0.2, T1=8.0, delta0=0.01)
    runs = nomoto_runs(truth, n_runs=2, duration=60.0, dt=0.05, noise="none")
    res = fit_equation_error(Nomoto1(), runs, flt=Filter("none"))
    for n, v in truth.param_values().items():
        assert res.params[n] == pytest.approx(v, rel=2e-3), n


def test_fossen3_inverse_dynamics_is_linear_least_squares():
    truth = usv_truth()
    runs = usv_runs(2, 60.0, 0.05, noise="none", seed=4)
    res = fit_equation_error(Fossen3(), runs, flt=Filter("savgol", window=0.5))
    rel = {n: abs(res.params[n] / truth.param_values()[n] - 1) for n in res.free}
    assert max(rel.values()) < 0.02, rel  # only derivative discretisation error remains
    assert res.converged and res.iterations <= 6


def test_equation_error_needs_velocities():
    run = usv_runs(1, 30.0, 0.1, noise="none")[0]
    no_v = run.to_dataframe().drop(columns=["v"])
    from diffship.data import Run

    with pytest.raises(DataError, match="v"):
        fit_equation_error(Fossen3(), [Run.from_dataframe(no_v, name="no_v")])
    assert np.isfinite(run["u"]).all()
