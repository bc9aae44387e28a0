"""One entry point: a log file and a channel map in, runs' arrays and metadata out.

:func:`read_log` reads the map's sources (:mod:`diffship.logs.readers`), puts every channel on one
grid, splits at gaps (:mod:`diffship.logs.assemble`) and flips a port-positive rudder.
:func:`diffship.data.load_runs` turns the pieces into :class:`~diffship.data.Run` objects.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DataError
from .assemble import assemble
from .channelmap import ChannelMap, load_map
from .readers import read_tables

__all__ = ["gap_report", "log_runs", "read_log"]


def read_log(path: str | Path, channel_map: str | Path | ChannelMap | None,
             name: str | None = None) -> list[tuple[str, np.ndarray, dict[str, np.ndarray], dict[str, Any]]]:
    """``(name, time [s], channels (SI, NED/FRD), metadata)`` for each gap-free piece of the log."""
    path = Path(path)
    if channel_map is None:
        raise DataError(f"{path}: a log needs a channel map: --map FILE.toml or a bundled map "
                        "(ros2_usv, ardusub, mavlink_tlog, px4), channel_map=... in load_runs.")
    cmap = load_map(channel_map)
    wanted = {s: ((src.topic, src.clock), fields) for s, src in cmap.sources.items()
              for fields in [cmap.fields()[s]] if fields}
    tables = read_tables(path, wanted)
    pieces = assemble(path, cmap, tables, name or (path.stem if path.suffix else path.name))
    if cmap.rudder_sign == "port":
        for _, _, chans, meta in pieces:
            if "delta" in chans:
                chans["delta"] = -chans["delta"]
                meta["rudder_flipped"] = ("delta",)
    return pieces


def gap_report(pieces) -> str | None:
    """One line naming the gaps that split a log, or ``None`` when it was not split."""
    if not pieces:
        return None
    meta = pieces[0][3]
    if not meta["gaps"]:
        return None
    gaps = ", ".join(f"{g['length']:.3g} s in {g['topic']} at t = {g['start']:.4g} s" for g in meta["gaps"])
    names = ", ".join(p[0] for p in pieces)
    dropped = f"; dropped pieces too short to fit: {len(meta['dropped_pieces'])}" if meta["dropped_pieces"] else ""
    return (f"{meta['source']}: gap(s) longer than the threshold ({gaps}): split into run(s) {names}"
            f"{dropped}; the gaps are not filled")


def log_runs(path: str | Path, name: str, channel_map: str | Path | ChannelMap | None, kw: dict[str, Any],
             run_type: type) -> list:
    """The runs of one log for :func:`diffship.data.load_runs` (``run_type`` is :class:`diffship.data.Run`,
    passed in so that this package never imports the data layer). A parquet table without a map is
    read as a CSV would be (its columns, ``kw`` as for CSV); a log split at gaps warns, naming them."""
    from .readers import require_extra

    if channel_map is None and Path(path).suffix.lower() == ".parquet":
        df = require_extra("pyarrow.parquet", f"{path} (a parquet table)").read_table(path).to_pandas()
        return [run_type.from_dataframe(df, name, **{"source": str(path), **kw})]
    if kw.get("columns") or kw.get("degrees"):
        raise DataError(f"{path}: --columns/--degrees do not apply to logs; the channel map gives fields and units.")
    pieces = read_log(path, channel_map, name)
    note = gap_report(pieces)
    if note:
        warnings.warn(note, stacklevel=3)
    return [run_type(n, t, ch, meta, check_units=kw.get("check_units", True)) for n, t, ch, meta in pieces]
