"""What a fleet worker runs: one group of vessel-runs (same model, similar length), fitted one after
the other in a long-lived process, so that every compiled program is compiled once per worker and
reused (the persistent compilation cache makes later workers of the same machine type cheaper).

Every vessel-run is isolated: an error is recorded in its own row and the group goes on. Each
finished vessel-run writes its fit file ``fits/<key>.json`` and its row ``rows/<key>.json`` at once,
so a worker killed mid-group loses only the vessel-runs it had not finished.

Each fit is judged here, as ``python -m diffship.fit`` judges it (:func:`diffship.usability.verdict`, no
held-out runs): its training runs simulated once over their whole horizon from the fit's own initial states
(the one initial-state rule, :mod:`diffship.initial`) give the evaluation; the verdict goes into the fit file
(``usable``, ``verdict``, ``metrics``, as the fit command writes them, so that ``predict`` warns) and into the
row (``verdict``, ``usable``, ``reason``, ``unidentified``, ``on_bound``; :mod:`diffship.fleet.engine`). A
vessel-run that cannot be fitted writes :func:`diffship.fitfile.stopped_document` as its fit file (no earlier
fit file is left to be taken for this one's) and a row whose verdict is FAILED with the error as its reason.
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

__all__ = ["failed_row", "fit_group", "fit_one", "judge"]

_STATE: dict[str, Any] = {}  # per worker process: how many fits it has made (1 = the one that compiled)


def _cache_hits() -> int:
    from .. import cache

    return int(cache.hits())


def judge(res, runs) -> tuple[Any, Any]:
    """``(verdict, evaluation)`` of an output-error fit ``res`` on its training ``runs`` (no held-out runs):
    the runs simulated once from the fit's initial states (those the fit estimated by the one initial-state
    rule; the rule itself, with the parameters held, where the fit's runs are not these), the fit's integrator,
    channels and channel scales, as :func:`diffship.fit.cli.evaluate_all` scores them. A fit with no estimate
    (every start diverged) is FAILED without a simulation."""
    from ..metrics import evaluate
    from ..usability import verdict

    if not res.usable:
        return verdict(res, None, runs), None
    same = tuple(res.run_names) == tuple(r.name for r in runs) and len(res.initial_states) == len(runs)
    ev = evaluate(res.model, runs, list(res.initial_states) if same else None, integrator=res.integrator,
                  fitted=res.channels, scales=res.channel_scales)
    return verdict(res, ev, runs), ev


def _names(items: Sequence[str]) -> str:
    """``"K,T1"`` of a verdict's ``unidentified`` or ``on_bound`` sentences (``"K = 0.2 ± 9: ..."``)."""
    return ",".join(w.split(" = ")[0] for w in items)


def _metrics(ev) -> dict[str, Any]:
    """The fit file's ``metrics`` (as the fit command writes them; no held-out runs)."""
    from ..report import metrics_json

    return {"train": metrics_json(ev), "validation": metrics_json(None), "validation_runs": []}


def fit_one(job: FleetJob, out: Path) -> dict[str, Any]:
    """Fit one vessel-run by output error (the defaults of ``python -m diffship.fit --method
    output-error``); judge it (:func:`judge`); write its fit file with the verdict; return its results row."""
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
    v, ev = judge(res, runs)
    fit_path = save_fit(res, out / "fits" / f"{job.key}.json", runs, registry=job.model,
                        extra={"fleet": {"vessel": job.vessel, "run": job.run, "files": list(job.runs)},
                               "metrics": _metrics(ev), "usable": v.usable, "verdict": v.as_json()})
    status = ("ok" if res.converged else "not converged") if v.usable else "not usable"
    row = {"key": job.key, "vessel": job.vessel, "run": job.run, "model": job.model, "status": status, "error": "",
           "verdict": v.label, "usable": v.usable, "reason": v.reasons[0] if v.reasons else "",
           "unidentified": _names(v.weak), "on_bound": _names(v.bound), "solver_status": res.status,
           "converged": bool(res.converged), "cost": float(res.cost), "samples": int(sum(r.n for r in runs)),
           "pieces": len(runs), "fit_file": str(fit_path), "seconds": time.perf_counter() - t0,
           "cpu_seconds": time.process_time() - c0}  # the worker process's CPU (one task at a time)
    row.update({f"p_{n}": float(res.params[n]) for n in res.free})
    row.update({f"se_{n}": float(res.stderr.get(n, math.nan)) for n in res.free})
    return row


def failed_row(job: FleetJob, out: Path, error: str) -> dict[str, Any]:
    """The row of a vessel-run without a fit (``error``: why); its fit file becomes
    :func:`diffship.fitfile.stopped_document`, which ``predict`` refuses naming the error."""
    from ..fitfile import stopped_document

    path = out / "fits" / f"{job.key}.json"
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(stopped_document(error, job.model), indent=2))
    except OSError:
        path = None
    return {"key": job.key, "vessel": job.vessel, "run": job.run, "model": job.model, "status": "failed",
            "error": error, "verdict": "FAILED", "usable": False, "reason": error, "unidentified": "",
            "on_bound": "", "converged": False, **({"fit_file": str(path)} if path else {})}


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
            row = failed_row(job, out, f"{type(exc).__name__}: {exc}".splitlines()[0][:500]
                             + (f" ({Path(last.filename).name}:{last.lineno})" if last else ""))
        _STATE["fits"] = _STATE.get("fits", 0) + 1
        row.update(worker_pid=os.getpid(), worker_fit_index=_STATE["fits"], cache_hits=_cache_hits())
        tmp = out / "rows" / f"{job.key}.json.tmp"
        tmp.write_text(json.dumps(row))
        tmp.replace(out / "rows" / f"{job.key}.json")  # atomic: a row is whole or absent
        rows.append(row)
    return rows
