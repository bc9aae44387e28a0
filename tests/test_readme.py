"""Every example in README.md runs as written and prints what the text says (:mod:`docexamples`).

The set-up line (``python3 -m venv ... && pip install ... && python -m diffship.fit``) runs its last part,
the main job; the blocks on ``../shared/data`` and the discovery example run with ``-m slow``. The README
stays short: at most 10 KB.
"""

from __future__ import annotations

import pytest

from diffship.data import shared_data_dir
from docexamples import ROOT, blocks, commands, run_block, workdir_for

README = ROOT / "README.md"
BLOCKS = blocks(README)


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    return workdir_for(tmp_path_factory, shared_data_dir())


def test_readme_is_short_and_has_the_workflow():
    text = README.read_text()
    assert len(text.encode()) <= 10_000, len(text.encode())
    cmds = [c.text for b in BLOCKS if b.lang == "bash" for c in commands(b.body)[0]]
    setup = commands(BLOCKS[0].body)
    assert setup[0][0].text == "python -m diffship.fit" and setup[1][-1].startswith("pip install -e")
    for tool in ("fit", "predict", "diagnose", "discover"):
        assert any(c.startswith(f"python -m diffship.{tool}") for c in cmds), tool
    assert "python -m pytest -q" in text  # the test command CI runs, exactly
    assert "mkdocs build --strict" in text  # the documentation's build command
    assert "zz_20_20.csv" not in text  # a file that never existed


@pytest.mark.parametrize("block", [pytest.param(b, marks=pytest.mark.slow) if b.slow else b for b in BLOCKS],
                         ids=[b.id for b in BLOCKS])
def test_readme_example_runs(block, workdir):
    if "../shared/data" in block.body and shared_data_dir() is None:
        pytest.skip(f"{block.id}: needs ../shared/data (the KVLCC2 model tests), absent here")
    run_block(block, workdir)
