"""diffship: identify ship and marine-craft dynamics from measured motion.

Data flow: ``data`` (runs) → ``models`` (JAX vector fields) → ``simulate`` → ``fit``
(output error, equation error) → ``diagnose`` → ``report``. See ``ARCHITECTURE.md``.

Importing diffship switches JAX to float64 (``jax_enable_x64``, :mod:`diffship.precision`):
identification needs it.
"""

from . import precision as precision

__version__ = "0.1.0"
__all__ = ["precision"]
