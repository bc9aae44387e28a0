"""diffship: identify ship and marine-craft dynamics from measured motion.

Data flow: ``data`` (runs) → ``models`` (JAX vector fields) → ``simulate`` → ``fit``
(output error, equation error) → ``report``.

Importing diffship switches JAX to float64 (``jax_enable_x64``): identification needs it.
"""

import jax as _jax

_jax.config.update("jax_enable_x64", True)

__version__ = "0.1.0"
