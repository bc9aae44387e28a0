"""The one cache of compiled programs.

Every jitted program diffship runs more than once (output-error residuals, Jacobians and solves,
batched simulations for the metrics, the diagnosis screen) is lowered and compiled ahead of
time here, once per *structure*: the function's static owner (a hashable
:class:`equinox.Module` whose fields are all static, e.g. the output-error kernel), the method
name, the pytree structure of the arguments and their shapes and dtypes. New data of the same
shape, new starts and new parameter values reuse the compiled program. Compile time is measured
and returned separately so reports can tell compiling from fitting; a program found in the
persistent cache (:mod:`diffship.cache`) is loaded instead of compiled, and :func:`loaded`
counts those.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Hashable
from typing import Any

import jax
import numpy as np

from . import cache

__all__ = ["compiled", "cache_size", "clear", "loaded"]

_CACHE: dict[Hashable, Callable] = {}
_LOADED: list[int] = [0]


def _signature(args: tuple) -> tuple:
    leaves, treedef = jax.tree_util.tree_flatten(args)
    return treedef, tuple((np.shape(x), str(getattr(x, "dtype", type(x).__name__))) for x in leaves)


def compiled(owner: Hashable, name: str, args: tuple, **static: Any) -> tuple[Callable, float]:
    """``owner.<name>(*args, **static)`` jitted and compiled for these argument shapes.

    Returns the compiled function (call it with arguments of the same structure and shapes) and
    the seconds spent compiling (0.0 when it came from the cache).
    """
    key = (owner, name, _signature(args), tuple(sorted(static.items())))
    fn = _CACHE.get(key)
    if fn is not None:
        return fn, 0.0
    t0 = time.perf_counter()
    hits = cache.hits()
    method = getattr(owner, name)
    fn = jax.jit(lambda *a: method(*a, **static)).lower(*args).compile()
    _LOADED[0] += int(cache.hits() > hits)  # this program came from the persistent cache
    _CACHE[key] = fn
    return fn, time.perf_counter() - t0


def loaded() -> int:
    """Programs that came from the persistent cache (:mod:`diffship.cache`) instead of the compiler."""
    return _LOADED[0]


def cache_size() -> int:
    """Number of compiled programs held."""
    return len(_CACHE)


def clear() -> None:
    """Forget every compiled program (tests and benchmarks that measure cold compiles)."""
    _CACHE.clear()
