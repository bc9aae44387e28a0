"""The benchmark suite cannot rot: run its quick Nomoto case end to end and check what it measured.

Runs ``python -m benchmarks suite --quick --cases nomoto`` (the cheapest case that still produces every
headline row: speed ratio vs the scipy peer, equation-/output-error parameter-error ratio,
batched time per fit) in a subprocess; about 1–2 minutes on a loaded 2-core machine.
"""

import pytest
import csv
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _numbers(path):
    with open(path) as fh:
        return {(r["case"], r["variant"], r["method"], r["metric"]): float(r["value"]) for r in csv.DictReader(fh)}


@pytest.mark.slow  # CI time budget: run with python -m pytest -m slow
def test_quick_benchmark_nomoto(tmp_path):
    env = {"PYTHONPATH": str(ROOT / "src"), "PATH": "/usr/bin:/bin", "MPLBACKEND": "Agg"}
    proc = subprocess.run([sys.executable, "-m", "benchmarks", "suite", "--quick", "--cases", "nomoto",
                           "--out", str(tmp_path)], capture_output=True, text=True, timeout=600, env=env, cwd=ROOT)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    report = (tmp_path / "report_quick.md").read_text()
    assert report.index("## Headline") < report.index("## Nomoto")  # headline table first
    for row in ("Speed ratio scipy/diffship OE at equal final cost, warm", "incl. compilation",
                "Parameter-error ratio EE/OE at realistic noise", "Batched OE time per fit", "GPU run"):
        assert row in report, row
    assert list(tmp_path.glob("fig_quick_*.png")), "no figures written"
    n = _numbers(tmp_path / "all_numbers_quick.csv")
    c = "nomoto_linear"
    # noise-free data: output error recovers K, T1, delta0 to round-off; equation error only to the
    # accuracy of the filtered derivative (still well under 1 %)
    assert n[(c, "noise=none", "diffship_oe", "max_rel_param_err")] < 1e-5
    assert n[(c, "noise=none", "diffship_ee", "max_rel_param_err")] < 1e-2
    # the NumPy peer solves the identical problem: same residual at diffship's solution, same final cost
    assert n[(c, "noise=realistic", "scipy_lm_numpy_rk4", "cost_check_rel_diff")] < 1e-8
    oe_cost = n[(c, "noise=realistic", "diffship_oe", "cost")]
    assert abs(n[(c, "noise=realistic", "scipy_lm_numpy_rk4", "cost")] - oe_cost) <= 0.01 * oe_cost
    # realistic noise: K and T1 within 10 % for both diffship methods; 3x noise is worse than none
    for m in ("diffship_oe", "diffship_ee"):
        assert n[(c, "noise=realistic", m, "rel_err_K")] < 0.10
        assert n[(c, "noise=realistic", m, "rel_err_T1")] < 0.10
    assert n[(c, "noise=high", "diffship_oe", "max_rel_param_err")] > n[(c, "noise=none", "diffship_oe", "max_rel_param_err")]
    # an unmodelled 0.5 s rudder delay biases the fit (a 0.5 s delay is 6 % of T = 8 s)
    assert n[(c, "delay=0.5", "diffship_oe", "max_rel_param_err")] > n[(c, "delay=0", "diffship_oe", "max_rel_param_err")]
    # the vmapped fixed-iteration LM reaches the best cost from most random starts
    assert n[(c, "batch", "diffship_oe", "vmap_lm_converged_rate")] >= 0.5
    assert n[(c, "batch", "diffship_oe", "vmap_lm_time_per_fit_s")] > 0


def test_every_benchmark_is_registered_and_importable_by_name():
    """``python -m benchmarks`` lists every benchmark of the registry; each registered module exists and
    defines ``main`` (read from the source: importing a benchmark may need its optional peers)."""
    import ast
    import importlib.util

    sys.path.insert(0, str(ROOT))
    try:
        from benchmarks.registry import BENCHMARKS

        for name, (module, _) in BENCHMARKS.items():
            spec = importlib.util.find_spec(module)
            assert spec is not None and spec.origin, (name, module)
            tree = ast.parse(Path(spec.origin).read_text())
            assert any(isinstance(n, ast.FunctionDef) and n.name == "main" for n in tree.body), (name, module)
    finally:
        sys.path.remove(str(ROOT))
    proc = subprocess.run([sys.executable, "-m", "benchmarks"], capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert proc.returncode == 0 and all(n in proc.stdout for n in BENCHMARKS), proc.stdout + proc.stderr


def test_the_rudder_offset_a_zigzag_asks_is_the_one_it_was_made_with():
    """``benchmarks/kvlcc2_rudder_offset.py`` finds the rudder offset a zigzag asks of a model: a 20°/5° zigzag
    flown by the KVLCC2 MMG with a 1° offset asks +1° of the same model without it, and then simulates its heading
    to a small fraction of a degree."""
    import math

    from diffship.manoeuvres import zigzag
    from diffship.models.mmg import kvlcc2_mmg

    sys.path.insert(0, str(ROOT))
    try:
        from benchmarks.kvlcc2_rudder_offset import best_offset
    finally:
        sys.path.remove(str(ROOT))
    run = zigzag(kvlcc2_mmg(delta0=math.radians(1.0)), {"u": 1.179}, rudder_deg=20.0, switch_deg=5.0, duration=80.0,
                 dt=0.2, inputs={"n": 10.23}, rudder_rate_deg_s=15.8)
    d, rmse, base = best_offset(kvlcc2_mmg(), run)
    assert abs(math.degrees(d) - 1.0) < 0.05, math.degrees(d)
    assert math.degrees(rmse) < 0.2 < math.degrees(base), (math.degrees(rmse), math.degrees(base))
