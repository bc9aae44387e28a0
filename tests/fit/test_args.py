"""The fit command's arguments and its JAX-free first checks (a fit that lacks the vessel's
particulars stops at once, with one line naming them)."""

import re
import subprocess
import sys

import pytest

from diffship.fit.args import INTEGRATOR_NAMES, build_parser, precheck
from diffship.fit.cli import main as fit_main
from diffship.integrators import INTEGRATORS
from diffship.models import MODELS, get_model
from diffship.particulars import MODEL_PARTICULARS

NEEDY = [k for k, n in MODEL_PARTICULARS.items() if n.particulars]


def test_tables_agree_with_the_models():
    """The plain-Python tables the command line reads are the models' own declarations."""
    assert tuple(MODEL_PARTICULARS) == tuple(MODELS)
    assert INTEGRATOR_NAMES == tuple(INTEGRATORS)
    for key, needs in MODEL_PARTICULARS.items():
        m = get_model(key)
        assert (needs.name, dict(needs.particulars), needs.reference_vessel) == (
            m.name, dict(m.PARTICULARS), m.REFERENCE_VESSEL), key
    assert build_parser().parse_args(["--model", "mmg"]).solver == INTEGRATOR_NAMES[0]
    from diffship.integrators import HOLDS

    assert build_parser().parse_args(["--model", "mmg"]).input_hold == HOLDS[0] == "linear"
    assert build_parser().parse_args(["--input-hold", "zero"]).input_hold == "zero"
    with pytest.raises(SystemExit):
        build_parser().parse_args(["--input-hold", "cubic"])


@pytest.mark.parametrize("key", NEEDY)
def test_precheck_says_what_the_full_command_says(key, capsys, tmp_path):
    """Same line, with and without the JAX-free path; ``--fix``/``--free`` cover particulars."""
    argv = [str(tmp_path / "run.csv"), "--model", key, "--quiet"]
    line = precheck(argv)
    assert line is not None and line.startswith(f"model {get_model(key).name} needs the vessel's particulars")
    assert fit_main(argv) == 2
    assert capsys.readouterr().err.strip() == f"error: {line}"
    names = list(MODEL_PARTICULARS[key].particulars)
    fixed = [f"{n}=1.0" for n in names[:-1]]
    partial = precheck(argv + ["--fix", *fixed])
    assert partial is not None and re.findall(r"(?:: |; )(\w+) \(", partial) == names[-1:], partial
    assert precheck(argv + ["--fix", *fixed, "--free", names[-1]]) is None  # nothing missing: the full command goes on
    assert precheck(argv + ["--vessel", "some.json"]) is None  # a vessel file: read by the full command


def test_no_jax_before_the_particulars_stop(tmp_path):
    """``python -m diffship.fit RUN --model vmm_simple`` (no vessel) exits 2 with one line naming the twelve
    particulars, and JAX (and NumPy) were never imported: what makes it a fraction of a second."""
    code = (
        "import runpy, sys\n"
        f"sys.argv = ['diffship.fit', {str(tmp_path / 'run.csv')!r}, '--model', 'vmm_simple']\n"
        "try:\n    runpy.run_module('diffship.fit', run_name='__main__', alter_sys=True)\n"
        "except SystemExit as e:\n    print('exit', e.code)\n"
        "print('loaded', sorted(m for m in ('jax', 'numpy', 'equinox', 'diffrax') if m in sys.modules))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert "exit 2" in out.stdout and "loaded []" in out.stdout, (out.stdout, out.stderr)
    err = out.stderr.strip()
    assert err.count("\n") == 0 and err.startswith("error: model vmm_simple needs the vessel's particulars"), err
    for n in ("m", "Iz", "xG", "L", "rho", "U0", "XT", "Xudot", "Yvdot", "Yrdot", "Nvdot", "Nrdot"):
        assert f" {n} (" in err or f": {n} (" in err, n
