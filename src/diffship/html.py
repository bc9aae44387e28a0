"""One self-contained HTML report: the command's text report and its figures, embedded.

Figures are PNG files produced by the command's own plotting functions (the same ones ``--out``
writes), embedded as ``data:image/png;base64,...`` so the one file opens anywhere, offline, with
no other file beside it. Text is escaped and kept preformatted (the tables line up in a monospace
font). Used by ``--html FILE`` of ``python -m diffship.fit``, ``diagnose`` and ``predict``.
"""

from __future__ import annotations

import base64
import datetime
import html
import tempfile
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

__all__ = ["html_document", "write_html_report"]

_STYLE = """body{font-family:system-ui,sans-serif;max-width:1200px;margin:2em auto;padding:0 1em;color:#222}
pre{background:#f6f8fa;padding:1em;overflow-x:auto;font-size:12px;line-height:1.35}
figure{margin:1.5em 0}img{max-width:100%;height:auto;border:1px solid #ddd}
figcaption{font-size:13px;color:#555}h1{font-size:1.5em}h2{font-size:1.2em;border-bottom:1px solid #ddd}"""


def _png_tag(data: bytes, caption: str) -> str:
    if not data.startswith(b"\x89PNG\r\n\x1a\n"):
        raise ValueError(f"figure {caption!r} is not a PNG image")
    b64 = base64.b64encode(data).decode("ascii")
    cap = html.escape(caption)
    return (f'<figure><img alt="{cap}" src="data:image/png;base64,{b64}">'
            f"<figcaption>{cap}</figcaption></figure>")


def html_document(title: str, sections: Sequence[tuple[str, str | None, Sequence[tuple[str, bytes]]]]) -> str:
    """The HTML text: ``sections`` of ``(heading, preformatted text or None, [(caption, PNG bytes)])``."""
    parts = [f"<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>{html.escape(title)}</title>"
             f"<style>{_STYLE}</style></head><body><h1>{html.escape(title)}</h1>",
             f"<p>diffship report, written {datetime.datetime.now(datetime.UTC):%Y-%m-%d %H:%M UTC}. "
             "Units: SI and degrees for display; axes NED/FRD, heading clockwise.</p>"]
    for heading, text, figures in sections:
        parts.append(f"<section><h2>{html.escape(heading)}</h2>")
        if text:
            parts.append(f"<pre>{html.escape(text)}</pre>")
        parts.extend(_png_tag(data, cap) for cap, data in figures)
        parts.append("</section>")
    parts.append("</body></html>")
    return "\n".join(parts)


def write_html_report(path: str | Path, title: str, text: str,
                      figures: Callable[[Path], Iterable[str | Path]] | Iterable[str | Path] = ()) -> Path:
    """Write ``text`` and the PNG figures to one HTML file at ``path``.

    ``figures`` is a list of PNG paths, or a function that writes the figures into the temporary
    folder it is given and returns their paths (e.g. a command's ``write_report(result, folder)``);
    files that are not PNGs are ignored (their content is in ``text``).
    """
    path = Path(path)
    with tempfile.TemporaryDirectory() as tmp:
        files = list(figures(Path(tmp)) if callable(figures) else figures)
        pngs = [(Path(f).stem.replace("_", " "), Path(f).read_bytes()) for f in files if str(f).endswith(".png")]
        doc = html_document(title, [("Report", text, []), ("Figures", None, pngs)] if pngs
                            else [("Report", text, [])])
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(doc, encoding="utf-8")
    return path
