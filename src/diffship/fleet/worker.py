"""What a fleet worker runs: one group of vessel-runs (same model, similar length), fitted one after
the other in a long-lived process, so that every compiled program is compiled once per worker and
reused (the persistent compilation cache makes later workers of the same machine type cheaper).

Every vessel-run is isolated: an error is recorded in its own row and the group goes on. Each
finished vessel-run writes its fit file ``fits/<key>.json`` and its row ``rows/<key>.json`` at once,
so a worker killed mid-group loses only the vessel-runs it had not finished.
"""

from __future__ import annotations

import json
import math
import os
import time
import traceback
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from .manifest import FleetJob

__all__ = ["fit_group", "fit_one"]

_STATE: dict[str, Any] = {}  # per worker process: how many fits it has made (1 = the one that compiled)


def _cache_hits() -> int:
    from .. import cache

    return int(cache.hits())


def fit_one(job: FleetJob, out: Path) -> dict[str, Any]:
    """Fit one vessel-run by output error (the defaults of ``python -m diffship.fit --method
    output-error``); write its fit file; return its results row."""
    from ..data import load_runs
    from ..fit import OutputErrorOptions, fit_both
    from ..fitfile import save_fit
    from ..integrators import get_integrator
    from ..models import get_model
    from ..vessel import load_vessel, require_particulars

    t0, c0 = time.perf_counter(), time.process_time()
    runs = load_runs(list(job.runs), channel_map=job.channel_map)
    model = get_model(job.model)
    vessel = load_vessel(job.vessel_file) if job.vessel_file else None
    model, _ = require_particulars(model, vessel)
    options = OutputErrorOptions(integrator=get_integrator("diffrax-rk4"), weights="noise")
    # the defaults of python -m diffship.fit (every run's initial state estimated within its noise)
    res = fit_both(model, runs, spec=model.spec(), methods=("output_error",), options=options)["output_error"]
    fit_path = save_fit(res, out / "fits" / f"{job.key}.json", runs, registry=job.model,
                        extra={"fleet": {"vessel": job.vessel, "run": job.run, "files": list(job.runs)}})
    row = {"key": job.key, "vessel": job.vessel, "run": job.run, "model": job.model,
           "status": "ok" if res.converged else "not converged", "error": "", "solver_status": res.status,
           "converged": bool(res.converged), "cost": float(res.cost), "samples": int(sum(r.n for r in runs)),
           "pieces": len(runs), "fit_file": str(fit_path), "seconds": time.perf_counter() - t0,
           "cpu_seconds": time.process_time() - c0}  # the worker process's CPU (one task at a time)
    row.update({f"p_{n}": float(res.params[n]) for n in res.free})
    row.update({f"se_{n}": float(res.stderr.get(n, math.nan)) for n in res.free})
    return row


def fit_group(jobs: Sequence[FleetJob], out: str, threads: int | None = None) -> list[dict[str, Any]]:
    """Fit each job of a group; every job's failure is its own row. Returns the rows.

    ``threads``: this worker's threads for a fit's starts (``$DIFFSHIP_THREADS``,
    :func:`diffship.fit.kernel.default_threads`): its share of the machine's cores; ``None`` leaves the
    default (one per core). The answers do not depend on it."""
    if threads:
        os.environ["DIFFSHIP_THREADS"] = str(int(threads))  # this worker process only
    out = Path(out)
    (out / "rows").mkdir(parents=True, exist_ok=True)
    (out / "started").mkdir(exist_ok=True)
    (out / "started" / f"{jobs[0].key}.group").write_text(str(os.getpid()))  # the driver tells lost from unstarted
    rows = []
    for job in jobs:
        try:
            row = fit_one(job, out)
        except Exception as exc:  # noqa: BLE001 (one vessel's failure never stops the others)
            last = traceback.extract_tb(exc.__traceback__)[-1] if exc.__traceback__ else None
            row = {"key": job.key, "vessel": job.vessel, "run": job.run, "model": job.model, "status": "failed",
                   "error": f"{type(exc).__name__}: {exc}".splitlines()[0][:500]
                   + (f" ({Path(last.filename).name}:{last.lineno})" if last else ""),
                   "converged": False}
        _STATE["fits"] = _STATE.get("fits", 0) + 1
        row.update(worker_pid=os.getpid(), worker_fit_index=_STATE["fits"], cache_hits=_cache_hits())
        tmp = out / "rows" / f"{job.key}.json.tmp"
        tmp.write_text(json.dumps(row))
        tmp.replace(out / "rows" / f"{job.key}.json")  # atomic: a row is whole or absent
        rows.append(row)
    return rows
