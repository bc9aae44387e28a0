"""The persistent compilation cache: compiled programs are kept between processes.

Without it every new process (each ``python -m diffship.fit``) recompiles the same programs,
and compilation dominates small fits. diffship turns JAX's persistent compilation cache on when
it is imported:

* folder: ``$DIFFSHIP_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/diffship/jax/<machine>`` or
  ``~/.cache/diffship/jax/<machine>``, where ``<machine>`` fingerprints the processor and jaxlib
  (machine code compiled for one CPU is never loaded on another);
* ``DIFFSHIP_CACHE_DIR=off`` (or ``0``, ``none``, empty) disables it;
* every program is cached, however quick to compile (``jax_persistent_cache_min_compile_time_secs
  = 0``), unless the user configured JAX's cache already (then diffship leaves it alone).

Entries are keyed by the program, the jax/jaxlib version and the machine, so a stale entry is
never used. :func:`hits` counts the programs loaded from the cache in this process (reports say
whether a fit was compiled or loaded).
"""

from __future__ import annotations

import os
from pathlib import Path

import jax

__all__ = ["cache_dir", "enable", "hits"]

_STATE = {"dir": None, "hits": 0}


def _machine() -> str:
    """A short fingerprint of this processor and jaxlib: the default folder holds one sub-folder per
    fingerprint, so a home folder shared by machines of different processors (a CI pool, a cluster)
    never loads machine code compiled for another CPU (XLA aborts the process on such an entry)."""
    import hashlib
    import platform

    text = [platform.machine(), platform.processor()]
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith(("model name", "flags", "Features", "CPU part")):
                    text.append(line.strip())
                if line.strip() == "":  # the first processor says it all
                    break
    except OSError:
        pass
    try:
        import importlib.metadata

        text.append(importlib.metadata.version("jaxlib"))
    except Exception:  # noqa: BLE001 — a source build without metadata: the processor alone
        pass
    return hashlib.sha256("\n".join(text).encode()).hexdigest()[:12]


def _default_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "diffship" / "jax" / _machine()


def enable(path: str | os.PathLike | None = None) -> Path | None:
    """Turn the persistent cache on at ``path`` (default: see the module docstring); ``None`` if off."""
    setting = os.environ.get("DIFFSHIP_CACHE_DIR") if path is None else str(path)
    if setting is not None and setting.strip().lower() in ("", "0", "off", "none", "false"):
        _STATE["dir"] = None
        return None
    if jax.config.jax_compilation_cache_dir and path is None and setting is None:
        _STATE["dir"] = Path(jax.config.jax_compilation_cache_dir)  # the user's own setting wins
        return _STATE["dir"]
    folder = Path(setting) if setting else _default_dir()
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        _STATE["dir"] = None  # read-only home: run without a persistent cache
        return None
    jax.config.update("jax_compilation_cache_dir", str(folder))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", -1)
    _STATE["dir"] = folder
    return folder


def cache_dir() -> Path | None:
    """The folder in use, or ``None`` when the persistent cache is off."""
    return _STATE["dir"]


def hits() -> int:
    """Programs loaded from the persistent cache in this process so far."""
    return _STATE["hits"]


def _on_event(event: str, **kwargs) -> None:
    if event == "/jax/compilation_cache/cache_hits":
        _STATE["hits"] += 1


jax.monitoring.register_event_listener(_on_event)
enable()
