"""diffship computes in float64: importing diffship switches JAX to 64-bit (``jax_enable_x64``).

Identification needs it: hydrodynamic coefficients span eight orders of magnitude, and
Levenberg–Marquardt on normal equations squares the condition number.
"""

import jax

jax.config.update("jax_enable_x64", True)

__all__: list[str] = []
