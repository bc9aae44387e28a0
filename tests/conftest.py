"""Test configuration: float64 everywhere and strict dtype promotion (as equinox/diffrax do)."""

import jax

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")

import diffship  # noqa: E402,F401  (imported after the config so nothing runs in float32)
