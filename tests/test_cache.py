"""The persistent compilation cache: a second process loads the programs the first compiled."""

import pytest
import os
import subprocess
import sys

CODE = """
import time, diffship
from diffship import cache, compiled
from diffship.fit import OutputErrorOptions, fit_output_error
from diffship.models import Nomoto1
from diffship.synthetic import nomoto_runs
runs = nomoto_runs(Nomoto1(K=0.2, T1=8.0), n_runs=1, duration=30.0, dt=0.1, noise="none")
res = fit_output_error(Nomoto1(), runs, options=OutputErrorOptions(weights="spread"))
e = compiled.exported()
print(cache.cache_dir(), compiled.loaded(), res.compile_seconds, res.converged, e["saved"], e["loaded"],
      res.params["K"])
"""


def _run(env):
    out = subprocess.run([sys.executable, "-c", CODE], capture_output=True, text=True, env=env, check=True)
    d, loaded, compile_s, ok, saved, exp_loaded, k = out.stdout.split()
    return d, int(loaded), float(compile_s), ok == "True", int(saved), int(exp_loaded), float(k)


@pytest.mark.slow  # CI time budget: run with python -m pytest -m slow
def test_second_process_loads_instead_of_compiling(tmp_path):
    env = {**os.environ, "DIFFSHIP_CACHE_DIR": str(tmp_path / "jax")}
    d1, loaded1, c1, ok1, saved1, exp1, k1 = _run(env)
    d2, loaded2, c2, ok2, saved2, exp2, k2 = _run(env)
    assert ok1 and ok2 and d1 == d2 == str(tmp_path / "jax")
    assert loaded1 == 0 and loaded2 >= 2, (loaded1, loaded2)
    # the second process neither traces (StableHLO from the export store) nor compiles (XLA cache)
    assert saved1 >= 2 and exp1 == 0 and saved2 == 0 and exp2 == saved1, (saved1, exp1, saved2, exp2)
    assert k1 == k2 and abs(k1 - 0.2) < 2e-4  # the loaded programs reach the same optimum, near the truth
    assert any((tmp_path / "jax" / "exported").iterdir())


@pytest.mark.slow  # CI time budget: run with python -m pytest -m slow
def test_cache_can_be_switched_off(tmp_path):
    env = {**os.environ, "DIFFSHIP_CACHE_DIR": "off"}
    d, loaded, _, ok, saved, exp, _ = _run(env)
    assert d == "None" and loaded == 0 and ok and saved == exp == 0


USER_MODEL = """
import sys
from diffship import compiled
from diffship.fit import OutputErrorOptions, fit_output_error
from diffship.models import Nomoto1
from diffship.synthetic import nomoto_runs

class Mine(Nomoto1):  # user code: the export key cannot see it
    pass

runs = nomoto_runs(Nomoto1(K=0.2, T1=8.0), n_runs=1, duration=30.0, dt=0.1, noise="none")
fit_output_error(Mine() if sys.argv[1] == "mine" else Nomoto1(), runs, options=OutputErrorOptions(weights="spread"))
print(compiled.exported()["saved"])
"""


@pytest.mark.slow  # CI time budget: run with python -m pytest -m slow
def test_programs_of_user_defined_models_are_never_exported(tmp_path):
    """A model class written outside diffship could be edited without changing any export key,
    so its programs must not be kept as StableHLO (they are traced again in every process)."""
    env = {**os.environ, "DIFFSHIP_CACHE_DIR": str(tmp_path / "jax")}
    saved = {which: int(subprocess.run([sys.executable, "-c", USER_MODEL, which], capture_output=True, text=True,
                                       env=env, check=True).stdout.split()[-1]) for which in ("mine", "library")}
    assert saved["mine"] == 0 and saved["library"] >= 2, saved
