"""Every example in README.md runs as written.

Fenced ``bash`` blocks are command lines: each line (and each ``&&``-joined part) runs through a
shell, in order, in one working directory whose parent holds ``shared`` → the real data folder
(so ``../shared/data/...`` resolves as it does beside the repository), with ``python`` the test's
interpreter. Not run, and said so: creating/activating a virtual environment and ``pip install``
(what ``.ci/run`` itself does before the tests) and ``python -m pytest`` (this suite). Blocks
reading ``../shared/data`` are skipped where that folder is absent. Fenced ``python`` blocks are
executed in the same directory. Plain fenced blocks are synopses and trees, not examples.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from diffship.data import shared_data_dir

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
SETUP = (r"^python3? -m venv\b", r"^\. \S*activate$", r"^source \S*activate$", r"^pip install\b",
         r"^python -m pytest\b")


def _blocks() -> list[tuple[str, str, int]]:
    text = README.read_text()
    out = []
    for m in re.finditer(r"^```(\w*)\n(.*?)^```", text, flags=re.DOTALL | re.MULTILINE):
        lang, body = m.group(1), m.group(2)
        if lang in ("bash", "python"):
            out.append((lang, body, text[: m.start()].count("\n") + 1))
    return out


BLOCKS = _blocks()


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    base = tmp_path_factory.mktemp("readme")
    work = base / "work"
    work.mkdir()
    shared = shared_data_dir()
    if shared is not None:
        (base / "shared").symlink_to(shared.parent, target_is_directory=True)
    return work


def _commands(body: str) -> tuple[list[str], list[str]]:
    run, skipped = [], []
    for line in body.splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        for part in (p.strip() for p in line.split("&&")):
            (skipped if any(re.match(s, part) for s in SETUP) else run).append(part)
    return run, skipped


def test_readme_has_the_workflow_examples():
    langs = [b[0] for b in BLOCKS]
    assert langs.count("python") >= 1 and langs.count("bash") >= 3
    cmds = [c for lang, body, _ in BLOCKS if lang == "bash" for c in _commands(body)[0]]
    assert any(c.startswith("python -m diffship.predict") for c in cmds)
    assert any(c.startswith("python -m diffship.fit") and "--out" in c for c in cmds)
    assert "zz_20_20.csv" not in README.read_text()  # a file that never existed


# the KVLCC2 blocks (MMG fit of four real zigzags, prediction with intervals: a minute on 2 cores) run with
# ``-m slow``; the notebooks and tests/studies check the same path in the default run
@pytest.mark.parametrize("lang,body,line", [pytest.param(*b, marks=pytest.mark.slow) if "../shared/data" in b[1] else b
                                            for b in BLOCKS], ids=[f"line{b[2]}-{b[0]}" for b in BLOCKS])
def test_readme_example_runs(lang, body, line, workdir, monkeypatch):
    if "../shared/data" in body and shared_data_dir() is None:
        pytest.skip(f"README line {line}: needs ../shared/data (the KVLCC2 model tests), absent here")
    monkeypatch.chdir(workdir)
    if lang == "python":
        exec(compile(body, f"README.md:{line}", "exec"), {"__name__": "__readme__"})  # noqa: S102 (the README's own example)
        return
    run, _ = _commands(body)
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", ""),
           "MPLBACKEND": "Agg"}
    for cmd in run:
        argv = shlex.split(cmd)
        assert argv[0] == "python", f"README line {line}: unexpected command {cmd!r}"
        proc = subprocess.run([sys.executable, *argv[1:]], capture_output=True, text=True, cwd=workdir, env=env,
                              timeout=900, check=False)
        assert proc.returncode == 0, f"README line {line}: {cmd}\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
        assert "Traceback" not in proc.stderr, proc.stderr[-3000:]
