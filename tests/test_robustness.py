"""The robustness matrix's quick subset (``benchmarks/robustness.py --quick``): one fit, one answer.

On an independent first-order Nomoto truth (closed-loop zigzags, sensor noise on every sample) and on the
bundled SSPA zigzag, the default fit lands on the best point sixteen whole-run starts find (within 0.5 of the
likelihood and one standard error in every parameter), and so do the fit without the warm-up and, on the real
zigzag, a fit at half the sample rate. The two variants that change the problem say why they do not land
(``x0 data``: the first sample held as exact; ``starts 1``: no search)."""

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_the_quick_matrix_lands_every_default_and_names_why_the_others_do_not(tmp_path):
    sys.path.insert(0, str(ROOT))
    try:
        from benchmarks import robustness as rb
    finally:
        sys.path.remove(str(ROOT))
    rows = []
    for case in rb.cases(quick=True).values():
        rows += rb.run_case(case, rb.QUICK_VARIANTS, lambda s: None)
    cell = {(r["case"], r["variant"]): r for r in rows}
    for name in ("nomoto1", "sspa"):
        for v in ("default", "no warm-up"):
            r = cell[(name, v)]
            assert r["lands"], (name, v, r["delta_objective"], r["max_abs_z"])
            assert r["usable"], (name, v, r["status"])
    assert cell[("sspa", "rate")]["lands"], cell[("sspa", "rate")]
    for r in rows:
        assert r["lands"] or r["why"] != "DOES NOT LAND" or r["variant"] == "rate", r
    # the first sample held exactly costs the likelihood more than a standard error on both
    assert cell[("nomoto1", "x0 data")]["delta_objective"] > 0.5 and cell[("sspa", "x0 data")]["delta_objective"] > 0.5
    rb.write(rows, rb.cases(quick=True), tmp_path, "robustness_quick")
    text = (tmp_path / "robustness_quick.md").read_text()
    assert "## nomoto1" in text and "## sspa" in text
    assert all(line.split("|")[2].strip() == "yes" for line in text.splitlines() if line.startswith("| default"))
