"""The code blocks of README.md and of the documentation's guides, and how the tests run them.

Fenced ``bash`` blocks are command lines: each line (a line ending in ``\\`` continues on the next; each
``&&``-joined part apart) runs as a process, in order, in one working directory per document whose parent
holds ``shared`` → the real data folder (so ``../shared/data/...`` resolves as it does beside the
repository), with ``python`` the test's interpreter. Not run, and said so: creating/activating a virtual
environment and ``pip install`` (what ``.ci/run`` itself does before the tests) and ``python -m pytest``
(this suite). Fenced ``python`` blocks are executed in the same directory. Plain fenced blocks are synopses
and trees, not examples.

**What a command prints.** Comment lines ``#   → ...`` after a command say what it prints: every decimal
number in them (``0.4749``, ``19.91``) must appear in the command's output.

**Slow blocks.** A block that reads ``../shared/data`` (the KVLCC2 model tests, not redistributable), or one
whose preceding line is ``<!-- slow -->``, runs with ``python -m pytest -m slow``.
"""

from __future__ import annotations

import dataclasses
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SETUP = (r"^python3? -m venv\b", r"^\. \S*activate$", r"^source \S*activate$", r"^pip install\b",
         r"^python -m pytest\b")
_NUMBER = re.compile(r"(?<![\w.])-?\d+\.\d+")


@dataclasses.dataclass(frozen=True)
class Block:
    """One fenced ``bash`` or ``python`` block of a document."""

    path: Path
    lang: str
    body: str
    line: int
    slow: bool

    @property
    def id(self) -> str:
        return f"{self.path.relative_to(ROOT)}:{self.line}"


def blocks(path: Path) -> list[Block]:
    text = path.read_text()
    out = []
    for m in re.finditer(r"^```(\w*)\n(.*?)^```", text, flags=re.DOTALL | re.MULTILINE):
        lang, body = m.group(1), m.group(2)
        if lang not in ("bash", "python"):
            continue
        before = text[: m.start()].rstrip().splitlines()
        marked = bool(before) and before[-1].strip() == "<!-- slow -->"
        out.append(Block(path, lang, body, text[: m.start()].count("\n") + 1,
                         marked or "../shared/data" in body))
    return out


@dataclasses.dataclass(frozen=True)
class Command:
    """A command line of a bash block and the numbers its ``→`` comments say it prints."""

    text: str
    prints: tuple[str, ...]


def commands(body: str) -> tuple[list[Command], list[str]]:
    """``(commands to run, set-up commands not run)`` of a bash block."""
    lines, joined = [], ""
    for raw in body.splitlines():
        joined += raw.rstrip()
        if joined.endswith("\\"):
            joined = joined[:-1] + " "
            continue
        lines.append(joined.strip())
        joined = ""
    run: list[Command] = []
    skipped: list[str] = []
    for line in lines:
        if not line:
            continue
        if line.startswith("#"):
            if "→" in line and run:
                last = run[-1]
                run[-1] = Command(last.text, last.prints + tuple(_NUMBER.findall(line.split("→", 1)[1])))
            continue
        for part in (p.strip() for p in line.split("&&")):
            if any(re.match(s, part) for s in SETUP):
                skipped.append(part)
            else:
                run.append(Command(part, ()))
    return run, skipped


def run_block(block: Block, workdir: Path) -> None:
    """Run ``block`` in ``workdir``; an assertion error names the document, line and command."""
    if block.lang == "python":
        cwd = os.getcwd()
        os.chdir(workdir)
        try:
            exec(compile(block.body, block.id, "exec"), {"__name__": "__doc_example__"})  # noqa: S102 (the document's own example)
        finally:
            os.chdir(cwd)
        return
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", ""),
           "MPLBACKEND": "Agg"}
    for cmd in commands(block.body)[0]:
        argv = shlex.split(cmd.text)
        assert argv[0] == "python", f"{block.id}: unexpected command {cmd.text!r}"
        proc = subprocess.run([sys.executable, *argv[1:]], capture_output=True, text=True, cwd=workdir, env=env,
                              timeout=900, check=False)
        assert proc.returncode == 0, f"{block.id}: {cmd.text}\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
        assert "Traceback" not in proc.stderr, proc.stderr[-3000:]
        said = proc.stdout + proc.stderr
        missing = [n for n in cmd.prints if n not in said]
        assert not missing, (f"{block.id}: {cmd.text[:120]}… does not print {missing}, which the text says it "
                             f"prints:\n{proc.stdout[-4000:]}")


def workdir_for(tmp_path_factory, shared: Path | None) -> Path:
    """A fresh working directory whose parent holds ``shared`` → the real data folder."""
    base = tmp_path_factory.mktemp("doc")
    work = base / "work"
    work.mkdir()
    if shared is not None:
        (base / "shared").symlink_to(shared.parent, target_is_directory=True)
    return work
