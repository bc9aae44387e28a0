"""The fleet manifest: one row per vessel-run (a CSV or parquet table).

Columns: ``vessel`` (name), ``runs`` (one or more run files or logs, ``;``-separated, relative to
the manifest's folder), ``model`` (registry name), optional ``map`` (channel map for logs),
``vessel_file`` (a vessel JSON or bundled vessel name, for models that need particulars) and
``run`` (the vessel-run's id; default: the first file's stem). Each vessel-run is one fit; its key
``<vessel>__<run>`` names its fit file and its row in the results.
"""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

from ..errors import DataError

__all__ = ["FleetJob", "read_manifest"]

_REQUIRED = ("vessel", "runs", "model")


@dataclasses.dataclass(frozen=True)
class FleetJob:
    """One vessel-run to fit."""

    vessel: str
    run: str
    runs: tuple[str, ...]
    model: str
    channel_map: str | None = None
    vessel_file: str | None = None

    @property
    def key(self) -> str:
        return re.sub(r"[^A-Za-z0-9_.-]+", "_", f"{self.vessel}__{self.run}")


def _cell(row, col):
    v = row.get(col)
    if v is None or (isinstance(v, float) and math.isnan(v)) or str(v).strip() == "":
        return None
    return str(v).strip()


def read_manifest(path: str | Path) -> list[FleetJob]:
    """The manifest's jobs; a clear error naming the row for a missing column or file."""
    import pandas as pd

    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: manifest not found.")
    if path.suffix.lower() == ".parquet":
        from ..logs import require_extra

        df = require_extra("pyarrow.parquet", f"{path} (a parquet manifest)").read_table(path).to_pandas()
    else:
        df = pd.read_csv(path, dtype=str, keep_default_na=False)
    missing = [c for c in _REQUIRED if c not in df.columns]
    if missing:
        raise DataError(f"{path}: manifest lacks column(s) {missing}; it needs {list(_REQUIRED)} "
                        "(optional: run, map, vessel_file).")
    jobs, keys = [], set()
    for i, row in enumerate(df.to_dict("records")):
        where = f"{path}, row {i + 2}"
        vessel, runs, model = (_cell(row, c) for c in _REQUIRED)
        if not (vessel and runs and model):
            raise DataError(f"{where}: vessel, runs and model must be filled in.")
        files = []
        for f in runs.split(";"):
            p = Path(f.strip())
            p = p if p.is_absolute() else path.parent / p
            if not p.exists():
                raise DataError(f"{where}: run file {p} not found.")
            files.append(str(p))
        m = _cell(row, "map")
        if m and not Path(m).is_absolute() and (path.parent / m).is_file():
            m = str(path.parent / m)
        vf = _cell(row, "vessel_file")
        if vf and not Path(vf).is_absolute() and (path.parent / vf).is_file():
            vf = str(path.parent / vf)
        job = FleetJob(vessel, _cell(row, "run") or Path(files[0]).stem, tuple(files), model, m, vf)
        if job.key in keys:
            raise DataError(f"{where}: vessel-run {job.key} appears twice; give each a distinct 'run' id.")
        keys.add(job.key)
        jobs.append(job)
    if not jobs:
        raise DataError(f"{path}: the manifest has no rows.")
    return jobs
