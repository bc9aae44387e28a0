"""Fleet fits on Dask ``distributed``: grouping, scheduling, progress, rerun, the results table.

Why Dask rather than Ray: the work is a bag of independent, coarse, CPU-bound Python tasks with
small inputs (file paths) and small outputs (a row); both engines do that. ``distributed`` is
pure Python on PyPI (one wheel, installs in seconds next to JAX, no separate object store or
raylet daemons), spawns its worker processes (``spawn``, not ``fork``: a forked JAX runtime is not
safe), restarts a killed worker through its nanny and reports the lost task as ``KilledWorker``,
and connects to an existing cluster by address (``dask scheduler`` / ``dask worker`` on any
machines, or a Dask-Jobqueue / Kubernetes deployment). Ray would add a heavier runtime for
features this does not use (actors, a shared-memory object store, GPUs).

Scheduling: jobs are grouped by (model, vessel file, channel map, run length rounded up to
:data:`PAD` samples) — the grouping the batched solver pads by — and each group is cut into
batches of at most ``batch`` vessel-runs, one task each. Workers are long-lived processes that run
one task at a time (``threads_per_worker=1``; BLAS threads set to one), so a compiled
program is compiled once per worker and reused for every later fit of the same shape. A fit's
starts run in threads (:meth:`diffship.fit.kernel.Kernel.solve_many`); each local worker gets its
share of the cores for them (``cores // workers``, at least one), so that the workers together do not
oversubscribe the machine (the answers do not depend on it). A task
writes each vessel-run's fit file and row as it finishes (:mod:`diffship.fleet.worker`); a rerun
skips every vessel-run whose row says ``ok``, ``not converged`` or ``not usable``, holds a verdict and whose fit
file exists (the same data give the same fit: a rerun retries the vessel-runs without one, and refits rows
written without a verdict).

The results table ``results.parquet`` has one row per vessel-run: ``key``, ``vessel``, ``run``, ``model``;
``status``: ``ok`` (fitted, usable), ``not converged`` (fitted, usable, the solver at its step limit),
``not usable`` (fitted, its verdict FAILED) or ``failed`` (no fit: ``error`` says why); the fit's verdict as
``python -m diffship.fit`` gives it (:func:`diffship.usability.verdict`): ``verdict`` (``usable``, ``FAILED``,
``not converged``, ``unidentifiable``; ``FAILED`` for a vessel-run without a fit), ``usable`` (boolean),
``reason`` (the verdict's first reason, or the error), ``unidentified`` and ``on_bound`` (the names of the
parameters the data do not determine and of those on one of their bounds, comma-separated, ``""`` when none:
``df[df.unidentified != ""]``); then ``solver_status``, ``converged``, ``cost``, ``samples``, ``pieces``,
``fit_file``, ``seconds``, ``cpu_seconds``, the parameters ``p_*`` and their standard errors ``se_*``, and the
worker's ``worker_pid``, ``worker_fit_index``, ``cache_hits``. The summary (:class:`FleetSummary`) counts
the verdicts of every vessel-run of the manifest (those skipped as done included) and names those that are not
usable and those usable with a warning.
A task lost with a killed worker (``--retries 0``) records its unfinished vessel-runs as failed
("worker lost"), unless it had not started (a marker file says when it did): then it was only
queued on that worker, and is submitted once more to the workers left.
"""

from __future__ import annotations

import json
import os
import sys
import time
from collections import defaultdict
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from .manifest import FleetJob, read_manifest

__all__ = ["LABELS", "PAD", "FleetSummary", "group_jobs", "run_fleet", "verdicts"]

PAD = 256  # [samples] run-length bucket of a group
_DONE = ("ok", "not converged", "not usable")  # fitted: a rerun would give the same fit
LABELS = ("usable", "FAILED", "not converged", "unidentifiable")  # diffship.usability.Verdict.label


class FleetSummary(dict):
    """``{"done", "failed", "skipped", "total", "seconds", "table"}`` of a fleet run (``done``: fitted,
    ``failed``: without a fit, in this run), and the verdicts of every vessel-run of the manifest: ``verdicts``
    (``{label: count}``, :data:`LABELS`; a vessel-run without a fit counts as FAILED), ``no_fit`` (how many of
    the FAILED have no fit), ``not_usable`` (``[(key, label, reason)]``) and ``warned`` (``[(key, text)]``:
    usable, but not converged, with unidentified parameters or parameters on a bound)."""


def _length(job: FleetJob) -> int:
    """A cheap size of the job's data (bytes of its files) for grouping; the exact length is not needed."""
    return sum(Path(f).stat().st_size if Path(f).is_file() else 0 for f in job.runs)


def group_jobs(jobs: Sequence[FleetJob], batch: int) -> list[list[FleetJob]]:
    """Groups of at most ``batch`` jobs with the same model, vessel, map and similar data size."""
    buckets: dict[tuple, list[FleetJob]] = defaultdict(list)
    for j in jobs:
        size = _length(j)
        buckets[(j.model, j.vessel_file, j.channel_map, size.bit_length())].append(j)
    groups = []
    for key in sorted(buckets, key=str):
        b = buckets[key]
        groups.extend(b[i:i + batch] for i in range(0, len(b), batch))
    return groups


def _rows(out: Path) -> dict[str, dict]:
    rows = {}
    for f in sorted((out / "rows").glob("*.json")):
        try:
            row = json.loads(f.read_text())
        except (OSError, ValueError):
            continue
        rows[row.get("key", f.stem)] = row
    return rows


def _done_keys(out: Path) -> set[str]:
    return {k for k, row in _rows(out).items()
            if row.get("status") in _DONE and "verdict" in row and Path(row.get("fit_file", "")).is_file()}


def verdicts(out: str | Path, jobs: Sequence[FleetJob]) -> dict[str, Any]:
    """The verdict entries of :class:`FleetSummary` for ``jobs`` from the rows in ``out``."""
    rows = _rows(Path(out))
    counts, no_fit, bad, warned = dict.fromkeys(LABELS, 0), 0, [], []
    for job in jobs:
        row = rows.get(job.key, {"status": "failed", "reason": "no result row"})
        label = row.get("verdict") or "FAILED"
        counts[label] = counts.get(label, 0) + 1
        no_fit += row.get("status") == "failed"
        if row.get("status") == "failed" or row.get("usable") is not True:
            bad.append((job.key, label if row.get("status") != "failed" else "no fit",
                        row.get("reason") or row.get("error") or ""))
            continue
        what = [label] if label != "usable" else []
        what += [f"{k.replace('_', ' ')}: {row[k]}" for k in ("unidentified", "on_bound") if row.get(k)]
        if what:
            warned.append((job.key, "; ".join(what)))
    return {"verdicts": counts, "no_fit": no_fit, "not_usable": bad, "warned": warned}


def _bar(done: int, failed: int, total: int, t0: float, stream) -> None:
    width = 30
    k = int(width * (done + failed) / max(total, 1))
    rate = done / max(time.perf_counter() - t0, 1e-9)
    stream.write(f"\r[{'#' * k}{'.' * (width - k)}] done {done}  failed {failed}  left {total - done - failed}"
                 f"  ({rate:.2f} fits/s)")
    stream.flush()


def _write_table(out: Path) -> Path:
    import pandas as pd

    df = pd.DataFrame(list(_rows(out).values()))
    for c, kind in (("usable", "boolean"), ("converged", "boolean"), ("verdict", "string"), ("reason", "string"),
                    ("unidentified", "string"), ("on_bound", "string")):
        if c in df:  # one type per column, missing where a row has no entry (a row written without a verdict)
            df[c] = df[c].astype(kind)
    path = out / "results.parquet"
    df.to_parquet(path, index=False)
    return path


def run_fleet(manifest: str | Path, out: str | Path, *, workers: int = 2, address: str | None = None,
              batch: int = 8, retries: int = 0, progress: bool = True, threads: int | None = None,
              on_result: Callable[[Any, list[dict]], None] | None = None) -> FleetSummary:
    """Fit every vessel-run of ``manifest`` into ``out`` (see the module docstring).

    ``workers``: local worker processes (ignored with ``address``, a running scheduler). ``retries``:
    how many times a task whose worker died is tried again elsewhere (0: its vessel-runs are recorded
    as failed and left for the rerun). ``threads``: threads per worker for a fit's starts (default: the
    cores shared out among the local workers, ``max(1, cores // workers)``, so that the workers do not
    oversubscribe the cores; with ``address``, one per core of the worker's machine). ``on_result(client,
    rows)`` is called after every finished task.
    """
    from ..logs import require_extra

    require_extra("distributed", "python -m diffship.fleet (Dask distributed; pip install 'diffship[fleet]')")
    import dask
    from distributed import Client, LocalCluster, as_completed

    from .worker import failed_row, fit_group

    out = Path(out)
    (out / "rows").mkdir(parents=True, exist_ok=True)
    for f in (out / "started").glob("*.group") if (out / "started").is_dir() else ():
        f.unlink()  # markers of an earlier run
    jobs = read_manifest(manifest)
    done = _done_keys(out)
    todo = [j for j in jobs if j.key not in done]
    t0 = time.perf_counter()
    summary = FleetSummary(total=len(jobs), skipped=len(jobs) - len(todo), done=0, failed=0)
    stream = sys.stderr
    if not todo:
        summary.update(seconds=0.0, table=str(_write_table(out)), **verdicts(out, jobs))
        return summary
    for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(k, "1")  # spawned workers inherit it: one BLAS thread per worker (XLA_FLAGS are left
        # alone: they enter the persistent compilation cache's key, and a changed flag recompiles everything)
    with dask.config.set({"distributed.scheduler.allowed-failures": retries,
                          "distributed.scheduler.worker-saturation": 1.0,  # a worker holds only the task it runs:
                          # a killed worker loses that task alone, the rest wait on the scheduler
                          "distributed.worker.multiprocessing-method": "spawn",
                          "distributed.worker.daemon": False}):
        cluster = None
        if address is None:
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=40)
        client = Client(address or cluster)
        try:
            groups = group_jobs(todo, batch)
            if threads is None and address is None:
                threads = max(1, (os.cpu_count() or 1) // workers)
            futures = {client.submit(fit_group, g, str(out), threads, pure=False, key=f"fleet-{i}-{g[0].key}"): g
                       for i, g in enumerate(groups)}
            if progress:
                _bar(0, 0, len(todo), t0, stream)
            pending = as_completed(list(futures))
            resubmitted: set[str] = set()
            for fut in pending:
                group = futures[fut]
                try:
                    rows = fut.result()
                except Exception as exc:  # noqa: BLE001 (KilledWorker, a lost connection: these vessel-runs only)
                    started = (out / "started" / f"{group[0].key}.group").is_file()
                    if not started and group[0].key not in resubmitted:  # assigned to the dead worker, never run:
                        resubmitted.add(group[0].key)  # not its fits; once more, on the workers left
                        new = client.submit(fit_group, group, str(out), threads, pure=False,
                                            key=f"fleet-again-{group[0].key}")
                        futures[new] = group
                        pending.add(new)
                        continue
                    finished, written = _done_keys(out), _rows(out)
                    rows = []
                    for job in group:
                        if job.key in finished:
                            rows.append(written[job.key])
                            continue
                        row = failed_row(job, out, f"worker lost: {type(exc).__name__}: {exc}".splitlines()[0][:500])
                        (out / "rows" / f"{job.key}.json").write_text(json.dumps(row))
                        rows.append(row)
                summary["done"] += sum(r["status"] in _DONE for r in rows)
                summary["failed"] += sum(r["status"] not in _DONE for r in rows)
                if progress:
                    _bar(summary["done"], summary["failed"], len(todo), t0, stream)
                if on_result is not None:
                    on_result(client, rows)
            if progress:
                stream.write("\n")
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    summary.update(seconds=time.perf_counter() - t0, table=str(_write_table(out)), **verdicts(out, jobs))
    return summary
