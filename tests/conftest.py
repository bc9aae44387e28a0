"""Test configuration: float64 everywhere, strict dtype promotion (as equinox/diffrax do), and a
compilation cache of the session's own."""

import atexit
import os
import shutil
import tempfile

# A compilation cache of this test session's own (shared with the subprocesses the CLI tests start):
# the suite never depends on programs left in the home folder by another run, jaxlib or machine.
# Set DIFFSHIP_CACHE_DIR to reuse a folder between sessions.
if "DIFFSHIP_CACHE_DIR" not in os.environ:
    os.environ["DIFFSHIP_CACHE_DIR"] = tempfile.mkdtemp(prefix="diffship-test-cache-")
    atexit.register(shutil.rmtree, os.environ["DIFFSHIP_CACHE_DIR"], ignore_errors=True)

# One thread per process for XLA's CPU kernels: pytest-xdist runs one worker per core, and each worker's own
# thread pool would only contend with the others' (measured on 2 cores: 4-6 % less time for the same tests).
os.environ.setdefault("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1")

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")

import diffship  # noqa: E402,F401  (imported after the config so nothing runs in float32)


import pytest  # noqa: E402


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """Programs compiled by one test module are released after it where the process's memory maps
    crowd the kernel's limit (:func:`diffship.compiled.release_if_crowded`): the whole suite runs
    in one process."""
    yield
    from diffship.compiled import release_if_crowded

    release_if_crowded()
