"""diffship's JAX settings, applied the moment JAX is imported: float64 and the compilation cache.

Importing :mod:`diffship` does not import JAX: the command line's checks that need no numerics
(:func:`diffship.fit.args.precheck`) answer in a fraction of a second. The settings diffship needs
(``jax_enable_x64``, :mod:`diffship.precision`; the persistent compilation cache,
:mod:`diffship.cache`) must nevertheless hold before the first array is made, whichever diffship
module (or the user) imports JAX first. So :func:`install`, run when :mod:`diffship` is imported:

* if JAX is already imported, applies them at once (import :mod:`~diffship.precision` and
  :mod:`~diffship.cache`);
* otherwise puts a finder at the front of ``sys.meta_path`` that lets the usual finders locate the
  ``jax`` package, and wraps its loader so that the settings are applied right after ``jax``'s own
  ``__init__`` has run, before control returns to the importing module. The finder then removes
  itself and restores the package's original loader; nothing else is touched.

``tests/test_jaxconfig.py`` checks, in fresh processes, that importing any diffship entry point
before or after JAX ends with float64 on and the cache configured.
"""

from __future__ import annotations

import importlib.abc
import sys
from importlib.machinery import ModuleSpec
from types import ModuleType

__all__ = ["apply", "install"]


def apply() -> None:
    """Apply diffship's JAX settings now (imports JAX)."""
    # the submodules themselves, not names of the package or of the modules: ``from . import cache``
    # would go through diffship's lazy face (``diffship.__getattr__``), and ``from .cache import
    # cache_dir`` fails when ``diffship.cache`` is the module importing JAX (it is then in
    # ``sys.modules`` but not yet initialised; it applies its settings itself once JAX is in)
    import importlib

    for name in ("cache", "precision"):  # importing the modules applies the settings
        importlib.import_module(f"{__package__}.{name}")


class _ThenApply(importlib.abc.Loader):
    """The ``jax`` package's own loader, followed by :func:`apply`."""

    def __init__(self, inner: importlib.abc.Loader):
        self.inner = inner

    def create_module(self, spec: ModuleSpec):
        return self.inner.create_module(spec)

    def exec_module(self, module: ModuleType) -> None:
        self.inner.exec_module(module)
        module.__loader__ = self.inner
        if module.__spec__ is not None:
            module.__spec__.loader = self.inner
        _remove()
        apply()

    def __getattr__(self, name: str):  # resource readers and the like: the package's own loader
        return getattr(self.inner, name)


class _OnJaxImport(importlib.abc.MetaPathFinder):
    """Finds ``jax`` with the other finders and wraps its loader (:class:`_ThenApply`)."""

    def find_spec(self, fullname, path=None, target=None):
        if fullname != "jax":
            return None
        for finder in sys.meta_path:
            if finder is self or not hasattr(finder, "find_spec"):
                continue
            spec = finder.find_spec(fullname, path, target)
            if spec is not None:
                if spec.loader is not None and hasattr(spec.loader, "exec_module"):
                    spec.loader = _ThenApply(spec.loader)
                return spec
        return None


def _remove() -> None:
    sys.meta_path[:] = [f for f in sys.meta_path if not isinstance(f, _OnJaxImport)]


def install() -> None:
    """Apply the settings now if JAX is imported, else as soon as it is (idempotent)."""
    if "jax" in sys.modules:
        apply()
    elif not any(isinstance(f, _OnJaxImport) for f in sys.meta_path):
        sys.meta_path.insert(0, _OnJaxImport())


install()
