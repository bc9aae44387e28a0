"""The package's shape: no import cycles, models below fitting, no private names across packages; and no
import cycle among the benchmarks either.

The import graph is read from the source (``ast``), counting imports executed at import time and
inside functions alike; imports under ``if TYPE_CHECKING:`` are type hints and are skipped.
Importing ``diffship.a.b`` runs ``diffship/a/__init__.py`` first, so such an import is an edge to
both ``diffship.a`` and ``diffship.a.b``. ``__main__`` modules are entry points: nothing imports
them, but their imports count.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"
PKG = SRC / "diffship"
BENCH = ROOT / "benchmarks"


def _module_name(path: Path, base: Path = SRC) -> str:
    rel = path.relative_to(base).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _is_type_checking(node: ast.If) -> bool:
    t = node.test
    return (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or (
        isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING")


def _imports(path: Path, base: Path = SRC) -> list[tuple[str, tuple[str, ...]]]:
    """(imported module, names) for every runtime import in ``path``, resolved to absolute names."""
    mod = _module_name(path, base)
    is_pkg = path.name == "__init__.py"
    package = mod if is_pkg else mod.rpartition(".")[0]
    out = []

    def visit(node):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _is_type_checking(child):
                for c in child.orelse:
                    visit(c)
                continue
            if isinstance(child, ast.Import):
                out.extend((a.name, ()) for a in child.names)
            elif isinstance(child, ast.ImportFrom):
                if child.level:
                    base = package.split(".")
                    base = base[: len(base) - (child.level - 1)]
                    target = ".".join(base + ([child.module] if child.module else []))
                else:
                    target = child.module or ""
                out.append((target, tuple(a.name for a in child.names)))
            visit(child)

    visit(ast.parse(path.read_text()))
    return out


MODULES = {_module_name(p): p for p in PKG.rglob("*.py")}
_MODULES = MODULES
BENCH_MODULES = {_module_name(p, ROOT): p for p in BENCH.rglob("*.py") if "results" not in p.parts}


def _lazy_names(path: Path) -> dict[str, str]:
    """A package face's lazily loaded names (PEP 562 ``_LAZY = {name: submodule}``) → absolute submodule."""
    if path.name != "__init__.py":
        return {}
    for node in ast.parse(path.read_text()).body:
        if (isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "_LAZY" for t in node.targets)
                and isinstance(node.value, ast.Dict)):
            pkg = _module_name(path)
            return {k.value: f"{pkg}.{v.value}" for k, v in zip(node.value.keys, node.value.values)
                    if isinstance(k, ast.Constant) and isinstance(v, ast.Constant)}
    return {}


LAZY = {_module_name(p): _lazy_names(p) for p in PKG.rglob("__init__.py")}


def _graph(modules: dict[str, Path] | None = None, top: str = "diffship", base: Path = SRC) -> dict[str, set[str]]:
    """Module → the modules its import runs (``modules`` below ``base``, imports of the package ``top``)."""
    MODULES = _MODULES if modules is None else modules  # noqa: N806
    g: dict[str, set[str]] = {m: set() for m in MODULES}
    for mod, path in MODULES.items():
        for target, names in _imports(path, base):
            if target != top and not target.startswith(top + "."):
                continue
            parts = target.split(".")
            for k in range(1, len(parts) + 1):  # parents' __init__ run first
                parent = ".".join(parts[:k])
                inside = mod == parent or mod.startswith(parent + ".")  # its own package is already running
                if parent in MODULES and not inside:
                    g[mod].add(parent)
            for n in names:  # ``from pkg import submodule``
                sub = f"{target}.{n}"
                if n in LAZY.get(target, {}) and target != mod:
                    # a name the package face loads lazily: the import runs the face's __getattr__, even
                    # from inside the package (the face, then the submodule behind the name)
                    g[mod].add(target)
                elif sub in MODULES and sub != mod:
                    g[mod].add(sub)
    for pkg, names in LAZY.items():  # a lazy face imports its submodules when a name is first used
        if pkg in g:
            g[pkg].update(m for m in names.values() if m in MODULES)
    return g


def _cycle(g: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def dfs(v):
        state[v] = 1
        stack.append(v)
        for w in sorted(g[v]):
            if state.get(w) == 1:
                return stack[stack.index(w):] + [w]
            if w not in state:
                found = dfs(w)
                if found:
                    return found
        stack.pop()
        state[v] = 2
        return None

    for v in sorted(g):
        if v not in state:
            found = dfs(v)
            if found:
                return found
    return None


def _top(mod: str) -> str:
    parts = mod.split(".")
    return ".".join(parts[:2]) if len(parts) > 1 else mod


def test_no_import_cycle_between_modules():
    cycle = _cycle(_graph())
    assert cycle is None, " -> ".join(cycle)


def test_no_import_cycle_between_packages():
    """The same at the level of diffship's top-level modules and subpackages (fit, models, ...)."""
    g: dict[str, set[str]] = {}
    for mod, deps in _graph().items():
        if mod == "diffship":
            continue
        g.setdefault(_top(mod), set())
        g[_top(mod)].update(_top(d) for d in deps if _top(d) not in (_top(mod), "diffship"))
    for v in list(g):
        for w in g[v]:
            g.setdefault(w, set())
    cycle = _cycle(g)
    assert cycle is None, " -> ".join(cycle)


def test_lazy_faces_count_as_imports():
    """A lazily re-exported name is an import of its submodule by the face; ``from pkg import name`` of
    such a name is an import of the face (a cycle through it is a cycle)."""
    g = _graph()
    assert "diffship.fitfile" in g["diffship"]
    assert "diffship.fit.driver" in g["diffship.fit"]


def test_no_import_cycle_in_the_benchmarks():
    """The benchmarks import each other only one way (a case never imports the suite that runs it); the
    entry point ``benchmarks/__main__.py`` reaches a benchmark by the registry's module names, at run time."""
    g = _graph(BENCH_MODULES, "benchmarks", ROOT)
    assert "benchmarks.suite" in g and "benchmarks.timing.cold" in g and g["benchmarks.timing.cold"]
    cycle = _cycle(g)
    assert cycle is None, " -> ".join(cycle)


def test_benchmark_files_stay_readable():
    """The benchmarks keep the package's file-size rule (one concept per module)."""
    long = {str(p.relative_to(ROOT)): n for p in BENCH_MODULES.values() if (n := len(p.read_text().splitlines())) > 520}
    assert not long, long


def test_the_cycle_detector_finds_a_cycle():
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": set()}) is None


@pytest.mark.parametrize("mod", sorted(m for m in MODULES if m.startswith("diffship.models")))
def test_models_describe_physics_only(mod):
    """A model depends on params, errors and other models: never on data, preprocess or fitting."""
    allowed = ("diffship.models", "diffship.params", "diffship.errors", "diffship.particulars")  # particulars: a plain table
    bad = [t for t, _ in _imports(MODULES[mod]) if t.startswith("diffship") and not t.startswith(allowed)]
    assert not bad, f"{mod} imports {bad}"


def test_equation_error_names_no_concrete_model():
    import diffship.models as models

    src = MODULES["diffship.fit.equation_error"].read_text()
    names = [n for n in dir(models) if isinstance(getattr(models, n), type) and n != "AbstractModel"]
    tree = ast.parse(src)
    used = sorted({node.id for node in ast.walk(tree) if isinstance(node, ast.Name) and node.id in names}
                  | {a.name for node in ast.walk(tree) if isinstance(node, ast.ImportFrom) for a in node.names
                     if a.name in names and a.name != "AbstractModel"})
    assert not used, used
    assert "isinstance" not in src, "equation error dispatches on the model's declared interface, not its class"


def test_no_private_name_imported_across_packages():
    bad = []
    for mod, path in MODULES.items():
        for target, names in _imports(path):
            if not target.startswith("diffship") or _top(target) == _top(mod):
                continue
            private = [n for n in names if n.startswith("_") and not n.startswith("__")]
            private_mod = [p for p in target.split(".") if p.startswith("_") and not p.startswith("__")]
            if private or private_mod:
                bad.append(f"{mod}: from {target} import {', '.join(names)}")
    assert not bad, bad


def test_package_faces_only_import():
    """``__init__`` files hold imports, ``__all__`` and a docstring, nothing else; or, for a package
    whose names load on first use (PEP 562), a ``_LAZY`` table with ``__getattr__`` and ``__dir__``."""
    for path in PKG.rglob("__init__.py"):
        tree = ast.parse(path.read_text())
        for node in tree.body:
            lazy = (isinstance(node, ast.FunctionDef) and node.name in ("__getattr__", "__dir__")) or (
                isinstance(node, ast.Assign) and [getattr(t, "id", None) for t in node.targets] == ["_LAZY"])
            ok = lazy or isinstance(node, (ast.Import, ast.ImportFrom)) or (
                isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant)) or (
                isinstance(node, (ast.Assign, ast.AnnAssign)) and any(
                    getattr(t, "id", None) in ("__all__", "__version__") for t in getattr(node, "targets", [getattr(node, "target", None)])))
            assert ok, f"{path.relative_to(SRC)} line {node.lineno}: {ast.dump(node)[:80]}"


def test_files_stay_readable():
    """No source file over about 500 lines (one concept per module; data.py, 511, is the loader of every format)."""
    long = {str(p.relative_to(SRC)): n for p in PKG.rglob("*.py") if (n := len(p.read_text().splitlines())) > 520}
    assert not long, long
