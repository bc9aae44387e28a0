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

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")

import diffship  # noqa: E402,F401  (imported after the config so nothing runs in float32)

import pytest  # noqa: E402


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """Drop the compiled programs after each test module. Every XLA CPU executable holds memory
    mappings; one process that keeps every program of the suite reached the kernel's limit of
    65 530 mappings (``vm.max_map_count``: measured 64 972 just before XLA aborted in a cache read,
    at tests/predict/test_cross.py once issue 27's tests were added). Later modules load what they
    need from the session's persistent cache."""
    yield
    from diffship import compiled

    compiled.clear()
    jax.clear_caches()
