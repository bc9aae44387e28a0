"""diffship's JAX settings (float64, compilation cache) hold whichever module imports JAX first
(:mod:`diffship.jaxconfig`): importing ``diffship`` loads no numerical library."""

import subprocess
import sys

import pytest

CHECK = ("import jax, jax.numpy as jnp\n"
         "print(jax.config.jax_enable_x64, jnp.zeros(1).dtype, bool(jax.config.jax_compilation_cache_dir))\n")


@pytest.mark.parametrize("first", [
    "import diffship",  # then the user imports JAX
    "import diffship.models",  # a diffship module imports JAX
    "import jax\nimport diffship",  # JAX first, diffship after
    "import diffship.particulars, diffship.fit.args\nfrom diffship.fit import FitResult",
    "from diffship import cache",  # the module that applies the cache settings imports JAX itself
    "import diffship.precision",
])
def test_float64_and_cache_whatever_imports_jax_first(first, tmp_path):
    env = {"PATH": "/usr/bin:/bin", "DIFFSHIP_CACHE_DIR": str(tmp_path / "cache"), "HOME": str(tmp_path)}
    out = subprocess.run([sys.executable, "-c", first + "\n" + CHECK], capture_output=True, text=True,
                         timeout=120, env=env)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["True", "float64", "True"], (out.stdout, out.stderr)


def test_importing_diffship_loads_no_numerics():
    code = "import sys, diffship\nprint(sorted(m for m in ('jax', 'numpy', 'pandas') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.stdout.strip() == "[]", (out.stdout, out.stderr)
