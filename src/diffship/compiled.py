"""The one cache of compiled programs.

Every jitted program diffship runs more than once (output-error residuals, Jacobians and solves,
batched simulations for the metrics, the diagnosis screen) is lowered and compiled ahead of
time here, once per *structure*: the function's static owner (a hashable
:class:`equinox.Module` whose fields are all static, e.g. the output-error kernel), the method
name, the pytree structure of the arguments and their shapes and dtypes. New data of the same
shape, new starts and new parameter values reuse the compiled program. Compile time is measured
and returned separately so reports can tell compiling from fitting.

**Between processes** two stores work together when the persistent cache is on
(:mod:`diffship.cache`):

1. the program's StableHLO, exported with :func:`jax.export.export` and serialised to
   ``<cache folder>/exported/<key>.bin``, so that a new process does not trace the Python
   (diffrax's and optimistix's loops) again: tracing and lowering the output-error solve takes
   about 0.6 s, deserialising it about 0.02 s;
2. JAX's persistent compilation cache, which turns the StableHLO into machine code without
   running XLA again (:func:`loaded` counts those programs).

The export key is a hash of everything the program depends on: the owner's and arguments'
structure as :func:`equinox.tree_pformat` prints it (static fields included, arrays as shapes
and dtypes), the method name and static keywords, the float64 flag, the backend, the versions
of jax/jaxlib/diffrax/optimistix/equinox/lineax and the bytes of every diffship source file
(so an edited diffship never loads a stale program). Programs built from code the key cannot
see — a model, steering law or effect class written outside diffship (a notebook, a test, a
benchmark's truth), or a callable in a static field — are never exported; neither are programs
whose outputs are not plain arrays and containers, or that hold host callbacks. Those are
traced in every process as before, and still reach JAX's persistent cache when they can.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib.metadata
import os
import threading
import time
from collections.abc import Callable, Hashable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import equinox as eqx
import jax
import numpy as np

from . import cache

__all__ = ["Prefetch", "cache_size", "clear", "compiled", "compiled_many", "compiler_options", "exported", "loaded",
           "prefetch", "release_if_crowded"]

#: Share of the kernel's limit on a process's memory maps (``vm.max_map_count``, 65 530 by default)
#: above which the programs held here and in JAX's caches are released before compiling more.
MAP_SHARE = 0.4

_CACHE: dict[Hashable, Callable] = {}
_STATE = threading.Lock()  # guards _INFLIGHT (programs being compiled, by key)
_INFLIGHT: dict[Hashable, threading.Event] = {}
_FOREGROUND = {"active": 0, "last": 0.0}  # compiles of callers other than a prefetch, and when the last ended
_PREFETCH = threading.local()
_LOADED: list[int] = [0]
_EXPORTED = {"loaded": 0, "saved": 0}
_SOURCE: list[str] = []


def _signature(args: tuple) -> tuple:
    leaves, treedef = jax.tree_util.tree_flatten(args)
    return treedef, tuple((np.shape(x), str(getattr(x, "dtype", type(x).__name__))) for x in leaves)


def _source_hash() -> str:
    """Hash of the installed diffship sources and of the libraries a program is built from."""
    if not _SOURCE:
        h = hashlib.sha256()
        for lib in ("jax", "jaxlib", "diffrax", "optimistix", "equinox", "lineax"):
            try:
                h.update(f"{lib}={importlib.metadata.version(lib)};".encode())
            except importlib.metadata.PackageNotFoundError:
                h.update(f"{lib}=?;".encode())
        root = Path(__file__).parent
        for path in sorted(root.rglob("*.py")):
            h.update(str(path.relative_to(root)).encode())
            h.update(path.read_bytes())
        _SOURCE.append(h.hexdigest())
    return _SOURCE[0]


#: Top-level packages whose code an export key covers (diffship's bytes, the others' versions).
_KNOWN = frozenset({"diffship", "jax", "jaxlib", "equinox", "diffrax", "optimistix", "lineax", "numpy", "builtins",
                    "jaxtyping", "functools", "math", "operator"})


def _known_code(obj, depth: int = 0) -> bool:
    """Whether every class and function reachable from ``obj`` (fields of modules and
    dataclasses, containers, static fields) is defined in diffship or a versioned library.

    A model, law or effect written by the user (a notebook, a test, a benchmark's truth) is
    code the key cannot see: editing it would not change the key, so such programs are never
    exported (they are traced in every process, and still reach JAX's own cache, which is
    keyed by the program itself)."""
    if depth > 30:
        return False
    if obj is None or isinstance(obj, (bool, int, float, complex, str, bytes, np.ndarray, jax.Array, np.generic)):
        return True
    if isinstance(obj, (tuple, list, frozenset, set)):
        return all(_known_code(x, depth + 1) for x in obj)
    if isinstance(obj, dict):
        return all(_known_code(k, depth + 1) and _known_code(v, depth + 1) for k, v in obj.items())
    owner_module = getattr(obj, "__module__", None) if callable(obj) and not isinstance(obj, type) else None
    module = owner_module or type(obj).__module__
    if isinstance(obj, type):
        module = obj.__module__
    if (module or "").split(".")[0] not in _KNOWN:
        return False
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return all(_known_code(getattr(obj, f.name, None), depth + 1) for f in dataclasses.fields(obj))
    return True


def _export_key(owner: Hashable, name: str, args: tuple, static: dict) -> str:
    text = "\n".join([
        _source_hash(), name, repr(sorted(static.items())), str(jax.config.jax_enable_x64), jax.default_backend(),
        eqx.tree_pformat(owner, short_arrays=True), eqx.tree_pformat(args, short_arrays=True),
        repr([(np.shape(x), str(getattr(x, "dtype", ""))) for x in jax.tree_util.tree_leaves(args)]),
    ])
    return hashlib.sha256(text.encode()).hexdigest()[:40]


def _exported(owner: Hashable, name: str, method: Callable, args: tuple, static: dict):
    """The program's :class:`jax.export.Exported` (loaded from the cache folder, or exported and
    saved now); ``None`` where exporting does not apply (cache off, non-array arguments, host
    callbacks)."""
    folder = cache.cache_dir()
    leaves, treedef = jax.tree_util.tree_flatten(args)
    if folder is None or not all(isinstance(x, (jax.Array, np.ndarray)) for x in leaves):
        return None
    if not (_known_code(owner) and _known_code(args) and _known_code(static)):
        return None
    path = folder / "exported" / f"{_export_key(owner, name, args, static)}.bin"
    if path.is_file():
        try:
            exp = jax.export.deserialize(bytearray(path.read_bytes()))
            _EXPORTED["loaded"] += 1
            return exp
        except Exception:  # a damaged or foreign file: export again
            pass

    def flat(*lv):
        return method(*jax.tree_util.tree_unflatten(treedef, lv), **static)
    try:
        exp = jax.export.export(jax.jit(flat))(*leaves)
    except Exception:  # e.g. host callbacks: not exportable
        return None
    try:
        blob = exp.serialize()
    except Exception:  # outputs with custom pytree nodes: use the export in this process only
        return exp
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".tmp{os.getpid()}")
        tmp.write_bytes(blob)
        tmp.replace(path)  # atomic: a concurrent process never reads half a file
        _EXPORTED["saved"] += 1
        return jax.export.deserialize(blob)  # compile what the next process will compile
    except OSError:
        return exp


def _lowered(owner: Hashable, name: str, args: tuple, static: dict):
    """``(lowered program, wrap)``: ``wrap(compiled)`` is the function to call with ``args``."""
    method = getattr(owner, name)
    exp = _exported(owner, name, method, args, static)
    if exp is None:
        return jax.jit(lambda *a: method(*a, **static)).lower(*args), lambda program: program
    lowered = jax.jit(exp.call).lower(*jax.tree_util.tree_leaves(args))
    return lowered, lambda program: (lambda *a: program(*jax.tree_util.tree_leaves(a)))


def _key(owner, name, args, static):
    return (owner, name, _signature(args), tuple(sorted(static.items())))


def compiled(owner: Hashable, name: str, args: tuple, **static: Any) -> tuple[Callable, float]:
    """``owner.<name>(*args, **static)`` jitted and compiled for these argument shapes.

    Returns the compiled function (call it with arguments of the same structure and shapes) and
    the seconds spent compiling (0.0 when it came from the cache).
    """
    fns, seconds = compiled_many([(owner, name, args, static)])
    return fns[0], seconds


def compiled_many(requests: list[tuple[Hashable, str, tuple, dict]]) -> tuple[list[Callable], float]:
    """Several programs at once: each ``(owner, name, args, static)`` as in :func:`compiled`.

    Tracing is Python and runs one program after the other; XLA's compilation releases the
    interpreter, so the programs not yet compiled are compiled in parallel threads (one per
    core). A fit that needs its residuals and its solve from an empty cache waits for the
    slowest of them instead of their sum. Returns the functions, in order,
    and the wall seconds spent (0.0 when all came from this process's cache).

    A program another thread is compiling (a refit beside another, :func:`prefetch`) is waited
    for, not compiled twice; programs of different keys compile side by side, so a caller never
    waits behind a queue of programs it does not need.
    """
    t0 = time.perf_counter()
    keys = [_key(*r) for r in requests]
    if all(k in _CACHE for k in keys):
        return [_CACHE[k] for k in keys], 0.0
    with _STATE:
        mine, theirs = {}, []
        for k, r in zip(keys, requests):
            if k in _CACHE or k in mine:
                continue
            if k in _INFLIGHT:
                theirs.append(_INFLIGHT[k])
            else:
                mine[k] = r
        if mine and not _INFLIGHT:  # nobody compiling: programs may be released safely
            release_if_crowded()
        for k in mine:
            _INFLIGHT[k] = threading.Event()
        fore = bool(mine) and not getattr(_PREFETCH, "on", False)  # a caller's own compile, not a prefetch
        _FOREGROUND["active"] += int(fore)
    try:
        if mine:
            _compile(mine)
    finally:
        with _STATE:
            for k in mine:
                _INFLIGHT.pop(k).set()
            if fore:
                _FOREGROUND["active"] -= 1
                _FOREGROUND["last"] = time.perf_counter()
    for ev in theirs:
        ev.wait()
    left = [r for k, r in zip(keys, requests) if k not in _CACHE]
    if left:  # another thread's compile failed or was released meanwhile: compile it here
        compiled_many(left)
    return [_CACHE[k] for k in keys], time.perf_counter() - t0


#: XLA's optimisation level for the machine code of diffship's programs on a CPU (LLVM's -O1; XLA's
#: own default is 3). See :func:`compiler_options`.
CPU_OPT_LEVEL = 1


def compiler_options() -> dict[str, Any]:
    r"""The XLA options every program of this module is compiled with.

    On a CPU, ``xla_backend_optimization_level`` = :data:`CPU_OPT_LEVEL` (1) instead of XLA's
    default 3. diffship's programs are long time-step loops (``while`` over the samples, RK4
    stages inside) of small fused kernels on state-sized arrays (6–10 states × 10–40 tangent
    columns); LLVM's -O3 unrolls and vectorises those kernels for sizes they never have. Measured
    in one process on the same lowered program, calls interleaved (``python
    benchmarks/compile_options.py``, two runs on the 2-core CI-like machine): the fossen3
    output-error Jacobian (2 runs × 240 s) 24 % faster at level 1 (median 49 → 37 ms, 52 → 40 ms;
    results identical), the diagnosis workspace's solve program (11 effects, 3 runs × 240 s)
    11–16 % (results equal to 2·10⁻¹⁰ after six LM steps), the KVLCC2 MMG Jacobian 7–10 %
    (equal to 4·10⁻¹⁶); compile times equal within noise. Level 2 is about level 1; level 0 is
    ten to twenty times slower. ``jax.jit`` programs built outside this module keep XLA's default
    (the equation-error solve is this module's: it runs at level 1 too).
    ``$DIFFSHIP_XLA_OPT_LEVEL`` overrides the level (``default``: XLA's own); other backends
    (GPU) keep XLA's defaults.
    """
    setting = os.environ.get("DIFFSHIP_XLA_OPT_LEVEL", "").strip().lower()
    if setting in ("default", "xla", "none"):
        return {}
    level = CPU_OPT_LEVEL
    if setting:
        if setting not in ("0", "1", "2", "3"):
            raise ValueError(f"DIFFSHIP_XLA_OPT_LEVEL={setting!r}: give a level 0–3, or 'default' for XLA's own")
        level = int(setting)
    if jax.default_backend() != "cpu":
        return {}
    return {"xla_backend_optimization_level": level}


def _compile(todo: dict) -> None:
    """Lower and compile the requests ``{key: (owner, name, args, static)}`` into the cache
    (with :func:`compiler_options`)."""
    hits = cache.hits()
    items = [(k, _lowered(*r)) for k, r in todo.items()]
    workers = min(len(items), os.cpu_count() or 1)
    opts = compiler_options()
    if workers > 1:
        with ThreadPoolExecutor(workers) as pool:
            programs = list(pool.map(lambda item: item[1][0].compile(compiler_options=opts), items))
    else:
        programs = [lowered.compile(compiler_options=opts) for _, (lowered, _) in items]
    for (k, (_, wrap)), program in zip(items, programs):
        _CACHE[k] = wrap(program)
    _LOADED[0] += min(cache.hits() - hits, len(items))  # programs that came from the persistent cache


class Prefetch:
    """Programs compiled in a background thread, one after the other (:func:`prefetch`)."""

    def __init__(self, requests: list[tuple[Hashable, str, tuple, dict]], first_wait: float = 1.0):
        self._requests = list(requests)
        self._first_wait = float(first_wait)
        self._stop = threading.Event()
        self.compiled = 0
        self.failed: list[str] = []
        self._thread = threading.Thread(target=self._work, name="diffship-prefetch", daemon=False)
        self._thread.start()

    def _quiet(self) -> None:
        """Wait while a caller's own compile runs (and briefly after it: it may ask for more).
        Two compiles side by side on two cores take longer than one after the other (two
        13-effect diagnosis solves with jax 0.10: 31 s side by side, 29 s in turn); a compile
        beside a running program slows neither much."""
        while not self._stop.is_set():
            with _STATE:
                busy = _FOREGROUND["active"] > 0 or time.perf_counter() - _FOREGROUND["last"] < 0.5
            if not busy:
                return
            time.sleep(0.05)

    def _work(self) -> None:
        _PREFETCH.on = True
        self._stop.wait(self._first_wait)  # the caller's own first compile goes first
        for owner, name, args, static in self._requests:
            self._quiet()
            if self._stop.is_set():
                return
            try:
                compiled_many([(owner, name, args, static)])
                self.compiled += 1
            except Exception as exc:  # noqa: BLE001 - the caller compiles it again and sees the error there
                self.failed.append(f"{type(owner).__name__}.{name}: {exc}")

    def cancel(self) -> None:
        """Compile no further program (the one being compiled finishes)."""
        self._stop.set()

    def join(self, timeout: float | None = None) -> None:
        self._thread.join(timeout)


def prefetch(requests: list[tuple[Hashable, str, tuple, dict]], first_wait: float = 1.0) -> Prefetch:
    """Compile ``requests`` (as in :func:`compiled_many`) in a background thread, in order, while
    the caller goes on — e.g. a diagnosis compiles its workspace's programs while the base fit
    runs: XLA's compile and a running program use different cores. The thread starts after
    ``first_wait`` seconds and gives way to the caller's own compiles (it starts no program while
    one runs). A later :func:`compiled` of the same program waits for it or finds it done. Call
    :meth:`Prefetch.cancel` when leaving early (the process then waits only for the program being
    compiled)."""
    return Prefetch(requests, first_wait)


def _maps() -> tuple[int, int] | None:
    """``(memory maps of this process, the kernel's limit)``; ``None`` where /proc does not tell."""
    try:
        with open("/proc/sys/vm/max_map_count") as f:
            limit = int(f.read())
        with open("/proc/self/maps", "rb") as f:
            return sum(1 for _ in f), limit
    except (OSError, ValueError):
        return None


def release_if_crowded(share: float = MAP_SHARE) -> bool:
    """Release every compiled program nobody holds when the process's memory maps pass ``share`` of
    the kernel's limit; returns whether it did.

    Each XLA CPU executable maps its machine code in several pieces (about 20 memory maps for a
    small program, hundreds for a fit's solve). A long session — a notebook fitting many models, a
    diagnosis or discovery refitting many structures, a test suite — that keeps every program it
    ever compiled reaches Linux's ``vm.max_map_count`` and the next compile dies with a
    segmentation fault inside LLVM. Released programs are compiled again (from the persistent
    cache when it is on) if they are needed again.
    """
    m = _maps()
    if m is None or m[0] <= share * m[1]:
        return False
    import gc

    clear()
    jax.clear_caches()
    gc.collect()
    return True


def loaded() -> int:
    """Programs that came from the persistent cache (:mod:`diffship.cache`) instead of the compiler."""
    return _LOADED[0]


def exported() -> dict[str, int]:
    """Programs whose StableHLO was loaded from / saved to the export store in this process."""
    return dict(_EXPORTED)


def cache_size() -> int:
    """Number of compiled programs held."""
    return len(_CACHE)


def clear() -> None:
    """Forget every compiled program (tests and benchmarks that measure cold compiles)."""
    _CACHE.clear()
