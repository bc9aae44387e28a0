"""diffship: identify ship and marine-craft dynamics from measured motion.

Data flow: ``data`` (runs) → ``models`` (JAX vector fields) → ``simulate`` → ``fit``
(output error, equation error) → ``diagnose`` → ``report``. See ``ARCHITECTURE.md``.

diffship computes in float64 (``jax_enable_x64``, :mod:`diffship.precision`): identification needs
it; and keeps compiled programs between processes in a persistent cache (:mod:`diffship.cache`;
``DIFFSHIP_CACHE_DIR`` moves it, ``DIFFSHIP_CACHE_DIR=off`` disables it). Both are applied the moment
JAX is imported, by whichever module (:mod:`diffship.jaxconfig`): importing ``diffship`` itself
loads no numerical library, so the command line's first checks answer at once.
A saved fit (``python -m diffship.fit ... --out DIR`` writes ``DIR/fit.json``) is read back with
:func:`diffship.load_fit` (:mod:`diffship.fitfile`); the names below load their modules on first use.
"""

from . import jaxconfig as jaxconfig

__version__ = "0.3.0"
__all__ = ["cache", "precision", "load_fit", "save_fit", "LoadedFit"]

# lazily loaded names (PEP 562): name -> module that defines it
_LAZY = {"cache": "cache", "precision": "precision", "load_fit": "fitfile", "save_fit": "fitfile",
         "LoadedFit": "fitfile"}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        module = importlib.import_module(f"{__name__}.{_LAZY[name]}")
        return module if _LAZY[name] == name else getattr(module, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
