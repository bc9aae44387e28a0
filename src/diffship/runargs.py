"""Checks of what a :class:`~diffship.data.Run` is built from, before the run checks the values themselves.

A run's channels and metadata must be mappings, every column real numbers, and
:meth:`~diffship.data.Run.from_dataframe` needs a pandas DataFrame; a time column of timedeltas is read as
the timedeltas' own seconds. Each check stops with a :class:`~diffship.errors.DataError` naming the run and
the argument or column at fault.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from .errors import DataError

__all__ = ["as_column", "check_containers", "check_frame", "timedelta_seconds"]


def as_column(values: Any, where: str, column: str) -> np.ndarray:
    """A private float64 copy of one column's values; complex or non-numeric values stop."""
    try:
        raw = np.asarray(values)
        if np.iscomplexobj(raw):
            raise DataError(f"{where}: column '{column}' holds complex numbers; diffship needs real values: "
                            "pass the real part (np.real) or the magnitude (np.abs), whichever the data mean.")
        return np.array(raw, dtype=np.float64, copy=True)
    except (TypeError, ValueError) as exc:
        if isinstance(exc, DataError):
            raise
        raise DataError(f"{where}: column '{column}' is not numeric ({exc}); "
                        "convert it to numbers or leave it out.") from None


def check_containers(name: Any, channels: Any, metadata: Any) -> None:
    """Stop unless ``channels`` is a mapping channel name -> values and ``metadata`` a mapping (or None)."""
    where = f"run {name!r}"
    if not isinstance(channels, (Mapping, pd.DataFrame)):
        raise DataError(f"{where}: channels must be a mapping of channel name -> values, e.g. "
                        f"{{'r': r, 'delta': delta}}, got {type(channels).__name__}.")
    if metadata is not None and not isinstance(metadata, Mapping):
        raise DataError(f"{where}: metadata must be a mapping (e.g. {{'source': 'tank test 3'}}) or None, "
                        f"got {type(metadata).__name__}.")


def check_frame(df: Any, where: str) -> None:
    """Stop unless ``df`` is a pandas DataFrame."""
    if not isinstance(df, pd.DataFrame):
        raise DataError(f"{where}: Run.from_dataframe needs a pandas DataFrame, got {type(df).__name__}; pass "
                        "pd.DataFrame(data), or build the run directly: Run(name, time, {channel: values}).")


def timedelta_seconds(s: pd.Series, where: str, time_unit: str) -> pd.Series:
    """A time column of timedeltas in seconds: each timedelta's own seconds, not shifted to start at 0 (as a
    numeric time column keeps its first time); ``time_unit`` other than ``"s"`` stops, the unit being known."""
    if time_unit != "s":
        raise DataError(f"{where}: the time column holds timedeltas (read as their seconds); "
                        f"time_unit={time_unit!r} does not apply, drop it.")
    return s.dt.total_seconds()
