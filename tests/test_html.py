"""``--html FILE``: one self-contained file with the report text and every figure embedded.

Default run: the HTML parses, every image is an embedded PNG that decodes, nothing is fetched from
outside. Slow (where Debian's chromium is installed): a real headless browser loads the file and
reports every image loaded with a non-zero size, and takes a screenshot."""

from __future__ import annotations

import base64
import shutil
import struct
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from diffship.html import write_html_report


class _Collect(HTMLParser):
    def __init__(self):
        super().__init__()
        self.imgs, self.links, self.pre = [], [], 0

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "img":
            self.imgs.append(a)
        if tag in ("link", "script") or (tag == "a" and "href" in a):
            self.links.append((tag, a))
        if tag == "pre":
            self.pre += 1


def _report(tmp_path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    def figures(folder):
        paths = []
        for k in range(2):
            fig, ax = plt.subplots(figsize=(6, 3))
            t = np.linspace(0, 10, 200)
            ax.plot(t, np.sin(t + k), label="measured")
            ax.set_xlabel("time [s]")
            fig.savefig(folder / f"fig_{k}.png", dpi=60)
            plt.close(fig)
            paths.append(folder / f"fig_{k}.png")
        (folder / "notes.json").write_text("{}")  # not a figure: ignored
        return [*paths, folder / "notes.json"]

    return write_html_report(tmp_path / "r.html", "diffship fit: <fossen3>", "Xu = -70 ± 7 N s/m\n  a < b", figures)


def test_html_is_self_contained_and_every_figure_decodes(tmp_path):
    path = _report(tmp_path)
    text = path.read_text()
    p = _Collect()
    p.feed(text)
    assert len(p.imgs) == 2 and p.links == [] and p.pre == 1
    assert "&lt;fossen3&gt;" in text and "a &lt; b" in text  # escaped, not markup
    for img in p.imgs:
        head, _, b64 = img["src"].partition(",")
        assert head == "data:image/png;base64"
        data = base64.b64decode(b64, validate=True)
        assert data[:8] == b"\x89PNG\r\n\x1a\n"
        w, h = struct.unpack(">II", data[16:24])  # IHDR
        assert w == 360 and h == 180  # 6 x 3 in at 60 dpi


def _embedded_pngs(path) -> list[bytes]:
    p = _Collect()
    p.feed(path.read_text())
    assert p.links == [] and p.pre == 1
    out = []
    for img in p.imgs:
        head, _, b64 = img["src"].partition(",")
        assert head == "data:image/png;base64"
        out.append(base64.b64decode(b64, validate=True))
        assert out[-1][:8] == b"\x89PNG\r\n\x1a\n"
    return out


def _predict_html(tmp_path) -> Path:
    """``python -m diffship.predict FIT --html``: a Nomoto fit file (K = 0.25 1/s, T = 6 s), one zigzag."""
    from diffship.fit import FitResult
    from diffship.fitfile import save_fit
    from diffship.models import Nomoto1
    from diffship.predict.__main__ import main

    model = Nomoto1(K=0.25, T1=6.0, delta0=0.0)
    res = FitResult(method="output_error", model=model, params=model.param_values(), stderr={"K": 0.005, "T1": 0.12},
                    free=("K", "T1"), converged=True, status="converged", iterations=1, cost=0.0, fit_seconds=0.0,
                    compile_seconds=0.0, channels=("psi", "r"), covariance=np.diag([0.005**2, 0.12**2]))
    fit = save_fit(res, tmp_path / "fit.json")
    html_path = tmp_path / "prediction.html"
    assert main([str(fit), "--manoeuvre", "zigzag:10/10", "--speed", "1.2", "--length", "4", "--scale", "16", "--samples", "0",
                 "--html", str(html_path), "--quiet"]) == 0
    return html_path


def test_predict_html_has_the_table_and_the_figure(tmp_path, capsys):
    path = _predict_html(tmp_path)
    pngs = _embedded_pngs(path)
    assert len(pngs) == 1 and len(pngs[0]) > 10_000  # prediction.png
    assert "10/10 zigzag" in path.read_text() and "first overshoot" in path.read_text()


def test_non_png_figure_is_refused(tmp_path):
    bad = tmp_path / "x.png"
    bad.write_bytes(b"GIF89a....")
    with pytest.raises(ValueError, match="not a PNG"):
        write_html_report(tmp_path / "r.html", "t", "text", [bad])


CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="no chromium here (Debian: apt-get install -y chromium)")
def test_headless_chromium_shows_every_figure(tmp_path):
    for path, n in ((_report(tmp_path), 2), (_predict_html(tmp_path), 1)):
        _check_in_chromium(tmp_path, path, n)


def _check_in_chromium(tmp_path, path, n):
    probe = tmp_path / "probe.html"  # the same document with a script that reports what the browser loaded
    probe.write_text(path.read_text().replace("</body>", "<script>document.body.setAttribute('data-loaded', "
                     "[...document.images].filter(i => i.complete && i.naturalWidth > 0).length + '/' + "
                     "document.images.length)</script></body>"))
    flags = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--virtual-time-budget=5000"]
    dom = subprocess.run([*flags, "--dump-dom", probe.as_uri()], capture_output=True, text=True, timeout=120, check=False).stdout
    assert f'data-loaded="{n}/{n}"' in dom
    shot = tmp_path / "shot.png"
    subprocess.run([*flags, f"--screenshot={shot}", "--window-size=1200,1400", path.as_uri()],
                   capture_output=True, timeout=120, check=False)
    assert shot.is_file() and shot.stat().st_size > 10_000
