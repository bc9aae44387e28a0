"""The documentation: every guide's example runs as written and prints what the text says
(:mod:`docexamples`), every public name of the documented packages is in the API reference, the version is
reported in one way everywhere, and the development's words stay out of the product.

The long examples (``../shared/data``, discovery, the fleet, prediction error) run with ``-m slow``.
``mkdocs build --strict`` (``.ci/run``) checks links, references and docstrings.
"""

from __future__ import annotations

import importlib
import inspect
import re
import subprocess

import pytest

from diffship.data import shared_data_dir
from docexamples import ROOT, blocks, run_block, workdir_for

DOCS = ROOT / "docs"
PAGES = sorted(p for p in DOCS.rglob("*.md") if p.parts[len(DOCS.parts)] not in ("api", "results", "notebooks"))
BLOCKS = [b for p in PAGES for b in blocks(p)]


@pytest.fixture(scope="module")
def workdirs(tmp_path_factory):
    shared = shared_data_dir()
    made = {}

    def get(path):
        if path not in made:
            made[path] = workdir_for(tmp_path_factory, shared)
        return made[path]

    return get


def test_the_guides_have_examples():
    names = {p.stem for p in PAGES}
    for guide in ("fitting", "estimators", "validation", "prediction", "diagnosis", "discovery", "logs", "fleets",
                  "conventions"):
        assert guide in names, guide
        assert any(b.path.stem == guide for b in BLOCKS), f"{guide}: no runnable example"


@pytest.mark.parametrize("block", [pytest.param(b, marks=pytest.mark.slow) if b.slow else b for b in BLOCKS],
                         ids=[b.id for b in BLOCKS])
def test_guide_example_runs(block, workdirs):
    if "../shared/data" in block.body and shared_data_dir() is None:
        pytest.skip(f"{block.id}: needs ../shared/data (the KVLCC2 model tests), absent here")
    run_block(block, workdirs(block.path))


API = {"diffship.fit": "fit", "diffship.diagnose": "diagnose", "diffship.discover": "discover",
       "diffship.predict": "predict", "diffship.logs": "logs"}


@pytest.mark.parametrize("package", sorted(API))
def test_every_public_name_is_in_the_api_reference(package):
    """Each name of the package's ``__all__`` is rendered from its docstring (``::: module.name`` where it is
    defined), so the reference cannot fall behind the package."""
    page = (DOCS / "api" / f"{API[package]}.md").read_text()
    documented = set(re.findall(r"^::: (\S+)$", page, flags=re.MULTILINE))
    mod = importlib.import_module(package)
    missing = []
    for name in mod.__all__:
        obj = getattr(mod, name)
        home = obj.__module__ if inspect.isclass(obj) or inspect.isfunction(obj) else None
        if not any(d.endswith(f".{name}") and (home is None or d == f"{home}.{name}") for d in documented):
            missing.append(name)
    assert not missing, f"docs/api/{API[package]}.md lacks {missing}"


def test_one_version_everywhere():
    import diffship

    pyproject = (ROOT / "pyproject.toml").read_text()
    version = re.search(r'^version = "([^"]+)"', pyproject, flags=re.MULTILINE).group(1)
    assert diffship.__version__ == version
    changelog = (ROOT / "CHANGELOG.md").read_text()
    assert f"## [{version}]" in changelog and "## [Unreleased]" in changelog


def test_no_development_diary_in_the_product():
    """Comments, docstrings, docs, tests and result names say what the software does; the history of its
    development is in git and CHANGELOG.md, not in the product."""
    words = re.compile(r"\b(st" r"op|iss" r"ue)[ -]?[0-9]+\b", flags=re.IGNORECASE)
    try:
        files = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout.split()
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout")
    hits = []
    for name in files:
        path = ROOT / name
        if name == "CHANGELOG.md" or not path.is_file() or path.suffix in (".png", ".parquet", ".pdf"):
            continue
        if words.search(name):
            hits.append(name)
        try:
            text = path.read_text()
        except (UnicodeDecodeError, OSError):
            continue
        hits += [f"{name}:{text[:m.start()].count(chr(10)) + 1}" for m in words.finditer(text)]
    assert not hits, hits[:20]
