"""The problem every timing mode measures, and the commands that solve it.

* data: the USV truth of :func:`diffship.synthetic.usv_truth`, ``usv_runs(2, duration, dt=0.1,
  noise="realistic", seed=0)``, written to CSV with ``Run.to_dataframe().to_csv``;
* model :class:`diffship.models.Fossen3`, the 10 free parameters of its spec, fixed ones at the truth
  (= the model's defaults); start: the truth ×0.5 / ×1.5 alternately;
* fitted channels psi, u, v, r; residual ``(sim − meas)/spread`` (``--weights spread``), heading error
  wrapped; initial states = first samples (``--filter none``) plus per-run offsets of psi, u, v, r
  estimated with the parameters (``--x0 estimate``): 10 + 8 = 18 unknowns; no prior rows
  (``--no-prior``: CasADi's residual has none); RK4, one step per sample, first-order-hold inputs;
* batches: starts log-uniform ×0.5…×2 around the truth (rng seed 0); the LM tolerances of
  ``fit_output_error`` (:data:`LM`).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from diffship.models import Fossen3
from diffship.synthetic import usv_runs, usv_truth

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "benchmarks" / "results"
CHANNELS = ("psi", "u", "v", "r")
#: the CasADi peer (:mod:`benchmarks.common.casadi_peer`), run as a process by its path
PEER = ROOT / "benchmarks" / "common" / "casadi_peer.py"
#: "reached the best cost": within this relative distance
SAME_COST = 1e-6
#: ``fit_output_error``'s Levenberg–Marquardt tolerances
LM = dict(max_steps=200, rtol=1e-6, atol=1e-6)


def write_runs(work: Path, duration: float = 300.0) -> tuple[list, list[str]]:
    """The runs and the CSV files they were written to (in ``work``)."""
    runs = usv_runs(2, duration, 0.1, noise="realistic", seed=0)
    csvs = []
    for r in runs:
        path = work / f"{r.name}.csv"
        r.to_dataframe().to_csv(path, index=False)
        csvs.append(str(path))
    return runs, csvs


def start_values() -> tuple[dict, dict]:
    """``(truth, start)``: the truth's parameter values and the start (free parameters ×0.5 / ×1.5)."""
    truth = usv_truth().param_values()
    start = {n: truth[n] * 1.5 if i % 2 else truth[n] * 0.5 for i, n in enumerate(Fossen3().spec().free_names)}
    return truth, start


def init_args(start: dict) -> list[str]:
    """``--init`` items of ``start``, exact (``repr``)."""
    return [f"{n}={v!r}" for n, v in start.items()]


def fit_command(csvs: list[str], start: dict) -> list[str]:
    """``python -m diffship.fit`` on the problem from ``start`` (add ``--json F`` to read its result)."""
    return [sys.executable, "-m", "diffship.fit", *csvs, "--model", "fossen3", "--vessel", "usv", "--method",
            "output-error", "--weights", "spread", "--filter", "none", "--channels", *CHANNELS, "--x0", "estimate",
            "--no-prior", "--init", *init_args(start), "--quiet"]


def peer_command(csvs: list[str], start: dict) -> list[str]:
    """The CasADi peer's process on the same files and start (add ``--mode``, ``--json``)."""
    return [sys.executable, str(PEER), *csvs, "--init", *init_args(start)]


def random_starts(spec, truth: dict, n_unknowns: int, n: int, seed: int = 0) -> np.ndarray:
    """``n`` scaled start vectors: free parameters log-uniform ×0.5…×2 around the truth, zero offsets."""
    rng = np.random.default_rng(seed)
    free = spec.free_names
    Z = np.zeros((n, n_unknowns))
    for b in range(n):
        f = np.exp(rng.uniform(math.log(0.5), math.log(2.0), len(free)))
        Z[b, :len(free)] = spec.to_z({k: truth[k] * fi for k, fi in zip(free, f)})
    return Z
