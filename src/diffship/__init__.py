"""diffship: identify ship and marine-craft dynamics from measured motion.

Data flow: ``data`` (runs) → ``models`` (JAX vector fields) → ``simulate`` → ``fit``
(output error, equation error) → ``diagnose`` → ``report``. See ``ARCHITECTURE.md``.

Importing diffship switches JAX to float64 (``jax_enable_x64``, :mod:`diffship.precision`):
identification needs it; and keeps compiled programs between processes in a persistent cache
(:mod:`diffship.cache`; ``DIFFSHIP_CACHE_DIR`` moves it, ``DIFFSHIP_CACHE_DIR=off`` disables it).
A saved fit (``python -m diffship.fit ... --out DIR`` writes ``DIR/fit.json``) is read back with
:func:`diffship.load_fit` (:mod:`diffship.fitfile`).
"""

from . import cache as cache, precision as precision
from .fitfile import LoadedFit as LoadedFit, load_fit as load_fit, save_fit as save_fit

__version__ = "0.1.0"
__all__ = ["cache", "precision", "load_fit", "save_fit", "LoadedFit"]
