"""What a command's output files say when it stopped without a result (nothing silent).

``python -m diffship.fit``, ``diagnose`` and ``discover`` end with one line ``error: ...`` and a non-zero exit
status where the fit cannot be carried out (every start of the model diverges: :class:`~diffship.errors.FitError`),
and ``diagnose`` where its base fit is not usable. The files the command was asked to write say the same, so that
none left there by an earlier command is taken for this one's result:

* the text report (``--out DIR``: ``report.txt``, ``diagnosis.md``) holds the error line;
* the JSON report (``--out DIR``'s and ``--json FILE``) is ``{"model", "error", "usable": false, ...}``;
* the fit file (``--out DIR/fit.json``, ``--save FILE``) is :func:`diffship.fitfile.stopped_document`: schema
  ``diffship.fit/1``, ``usable: false``, a FAILED verdict and ``error``, which ``load_fit`` and ``predict`` refuse;
* ``--html FILE`` holds the error line; the figures an earlier command left in ``--out DIR`` are removed.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

__all__ = ["stopped_command", "stopped_outputs"]


def stopped_outputs(message: str, model_name: str, *, out: str | None = None, text: str = "report.txt",
                    report: str = "report.json", fit_file: str | None = "fit.json", figures: Sequence[str] = (),
                    json_file: str | None = None, save: str | None = None, html: str | None = None,
                    title: str = "diffship", extra: Mapping[str, Any] | None = None) -> list[Path]:
    """Write what a command that stopped without a result (``message``: why) says in its outputs (module
    docstring): ``out`` the ``--out`` folder, with its ``text`` report, JSON ``report``, ``fit_file`` (``None``:
    the command writes none) and ``figures``; ``json_file``, ``save`` and ``html`` the single files asked for;
    ``extra`` further JSON entries (a base fit's verdict). Nothing is written where no output was asked for.
    Returns the paths written."""
    from .fitfile import stopped_document

    doc = {"model": model_name, "error": message, "usable": False, **dict(extra or {})}
    line = f"{title} — model {model_name}\nerror: {message}\n"
    written = []

    def put(path: Path, content: str) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(content)
        written.append(path)

    fit_doc = json.dumps(stopped_document(message, model_name), indent=2)
    if out:
        folder = Path(out)
        put(folder / text, line)
        put(folder / report, json.dumps(doc, indent=2, default=str))
        if fit_file:
            put(folder / fit_file, fit_doc)
        for name in figures:  # an earlier command's figures, not this one's
            (folder / name).unlink(missing_ok=True)
    if json_file:
        put(Path(json_file), json.dumps(doc, indent=2, default=str))
    if save:
        put(Path(save), fit_doc)
    if html:
        from .html import write_html_report

        written.append(write_html_report(html, f"{title}: {model_name}", line))
    return written


def stopped_command(args, message: str, out_files: Sequence[str], title: str, extra: Mapping[str, Any] | None = None
                    ) -> list[Path]:
    """:func:`stopped_outputs` for a command's parsed ``args`` (``model``, ``out`` and, where the command has them,
    ``json``, ``save``, ``html``) and the files its ``--out`` writes, ``out_files``: the ``.txt`` or ``.md`` one is
    the text report, ``fit.json`` the fit file, the other ``.json`` the JSON report, the ``.png`` ones figures."""
    text = next(f for f in out_files if f.endswith((".txt", ".md")))
    report = next(f for f in out_files if f.endswith(".json") and f != "fit.json")
    return stopped_outputs(message, args.model, out=args.out, text=text, report=report,
                           fit_file="fit.json" if "fit.json" in out_files else None,
                           figures=[f for f in out_files if f.endswith(".png")], json_file=getattr(args, "json", None),
                           save=getattr(args, "save", None), html=getattr(args, "html", None), title=title, extra=extra)
