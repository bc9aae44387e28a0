"""A command that stopped without a result says so in every file it was asked to write (diffship.stopped)."""

import json
from argparse import Namespace

from diffship.stopped import stopped_command

DIAGNOSE_FILES = ("diagnosis.md", "diagnosis.json", "residuals.png", "overlay.png")


def test_the_files_asked_for_hold_the_error_and_no_earlier_result(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "overlay.png").write_bytes(b"an earlier figure")
    args = Namespace(model="nomoto1", out=str(out), json=str(tmp_path / "d.json"), html=str(tmp_path / "d.html"))
    written = stopped_command(args, "model nomoto1 diverges from every start", DIAGNOSE_FILES, "diffship diagnose",
                              extra={"base_verdict": {"label": "FAILED"}})
    assert (out / "diagnosis.md").read_text().splitlines() == ["diffship diagnose — model nomoto1",
                                                               "error: model nomoto1 diverges from every start"]
    doc = json.loads((out / "diagnosis.json").read_text())
    assert doc == json.loads((tmp_path / "d.json").read_text())
    assert doc["usable"] is False and doc["base_verdict"] == {"label": "FAILED"} and "diverges" in doc["error"]
    assert not (out / "overlay.png").exists() and not (out / "fit.json").exists()  # diagnose writes no fit file
    assert "diverges from every start" in (tmp_path / "d.html").read_text() and len(written) == 4


def test_nothing_is_written_where_no_output_was_asked_for(tmp_path):
    args = Namespace(model="nomoto1", out=None)
    assert stopped_command(args, "why", ("report.txt", "report.json", "fit.json"), "diffship fit") == []
    assert list(tmp_path.iterdir()) == []
