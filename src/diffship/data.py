"""Measured runs: loading, checking and simple resampling of manoeuvring data.

Conventions used everywhere inside diffship
------------------------------------------
* SI units and radians: time [s], positions [m], speeds [m/s], angles [rad], angular
  rates [rad/s], forces [N], moments [N m]. Data given in degrees must be declared
  (``degrees=["delta"]``, CLI ``--degrees delta``) and are converted on load.
* Axes: x forward, y to starboard, z down. The heading ``psi`` is positive clockwise
  seen from above, in an earth-fixed NED-like frame (``x0`` north / ``y0`` east, or the
  tank axes). ``u``, ``v`` (and ``r``) are body-fixed.
* Rudder sign: internally **starboard-positive**, i.e. a positive ``delta`` turns the
  ship to starboard (``r > 0``). Data declared ``rudder_sign="port"`` (positive delta =
  rudder to port, port turn; e.g. the SSPA and KVLCC2 data) are flipped on load
  (``delta *= -1``) and the declaration is kept in ``Run.metadata``.

A :class:`Run` is immutable: its arrays are private read-only float64 copies, checked
on construction (ordering, gaps, NaN/inf, lengths and - conservatively - units).
"""

from __future__ import annotations

import dataclasses
import io
import os
import re
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from diffship.errors import DataError

from .channels import check_header, check_near_misses
from .frozen import FrozenDict as _FrozenDict
from .gaps import check_gaps
from .hold import held_means
from .runargs import as_column as _as_array
from .runargs import check_containers, check_frame, timedelta_seconds
from .units import TIME_UNITS, UnitsError, psi_unwrap
from .units import check_units as check_column_units

__all__ = [
    "ANGLE_CHANNELS", "CANONICAL_COLUMNS", "CHANNEL_UNITS", "MIN_SAMPLES", "RUDDER_CHANNELS", "Run", "TIME_UNITS",
    "UnitsError", "example_path", "example_runs", "kvlcc2_runs", "load_runs", "resample_runs", "shared_data_dir",
]

CANONICAL_COLUMNS = ("time", "x0", "y0", "psi", "u", "v", "r", "delta", "tau_x", "tau_y", "tau_z")
#: Angles or angular rates (rad or rad/s inside diffship).
ANGLE_CHANNELS = {"psi", "delta", "r", "phi", "theta", "p", "q", "nozzle", "delta_n"}
#: Display unit of every channel of every model (outputs and inputs): name -> (label, factor from SI/rad).
CHANNEL_UNITS: dict[str, tuple[str, float]] = {
    **dict.fromkeys(("x0", "y0", "z0"), ("m", 1.0)), **dict.fromkeys(("u", "v", "w"), ("m/s", 1.0)),
    **dict.fromkeys(("psi", "phi", "theta", "delta", "delta_n", "nozzle", "angle"), ("deg", 180.0 / np.pi)),
    **dict.fromkeys(("r", "p", "q", "rate"), ("deg/s", 180.0 / np.pi)), "velocity": ("m/s or rad/s", 1.0),
    **dict.fromkeys(("tau_x", "tau_y", "tau_z", "thrust"), ("N", 1.0)), **dict.fromkeys(("tau_k", "tau_m", "tau_n"),
    ("N m", 1.0)), "tau": ("N or N m", 1.0), "n": ("1/s", 1.0), "rpm": ("rev/min", 1.0)}
#: Channels negated when the source declares ``rudder_sign="port"``.
RUDDER_CHANNELS = ("delta",)
MIN_SAMPLES = 10

_EXAMPLES_DIR = Path(__file__).parent / "examples"
_DEG = np.pi / 180.0
_EXAMPLES = {
    "sspa_zigzag": {
        "description": "Free-running zigzag 20/20 of a ship model tested at SSPA, 50 Hz.",
        "attribution": "martinlarsalbert/blog, _notebooks/example_zigzag.csv (Apache-2.0)",
        "licence": "Apache-2.0",
    },
}


def _where(name: str, source: Any) -> str:
    return f"{source}, run '{name}'" if source else f"run '{name}'"


@dataclasses.dataclass(frozen=True, eq=False, repr=False)
class Run:
    """One measured (or simulated) run.

    Parameters
    ----------
    name : str
        Run name, used in messages and reports.
    time : array_like, shape (N,)
        Time [s], finite and strictly increasing, at least ``MIN_SAMPLES`` samples, without gaps
        (:mod:`diffship.gaps`: no step over 5 median steps and over 1 s).
    channels : Mapping[str, array_like]
        Channel name -> values, shape (N,), SI units and radians, starboard-positive rudder.
    metadata : Mapping[str, Any]
        Free-form description (``source``, ``rudder_sign_in_source``, ``degrees_converted``,
        ``column_map``, ...). ``metadata["source"]`` is quoted in error messages.
    check_units : bool
        Run the unit-sanity heuristics (:func:`diffship.units.check_units`: degrees passed as radians,
        radians declared degrees, time stamps in another unit than stated). Structural checks always run.

    Raises
    ------
    DataError
        If the data are unusable; the message names the run, column and first bad row.
    """

    name: str
    time: np.ndarray
    channels: Mapping[str, np.ndarray]
    metadata: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    check_units: bool = True

    def __post_init__(self) -> None:
        check_containers(self.name, self.channels, self.metadata)
        meta = dict(self.metadata or {})
        if not isinstance(self.name, str) or not self.name:
            raise DataError(f"{meta.get('source') or 'Run'}: the run name must be a non-empty string.")
        where = _where(self.name, meta.get("source"))
        t = _as_array(self.time, where, "time")
        if t.ndim != 1:
            raise DataError(f"{where}: time must be one-dimensional, got shape {t.shape}.")
        if t.size < MIN_SAMPLES:
            raise DataError(f"{where}: too few samples: {t.size} (need at least {MIN_SAMPLES}).")
        bad = ~np.isfinite(t)
        if bad.any():
            raise DataError(f"{where}: column 'time' has {int(bad.sum())} NaN/inf value(s), first "
                            f"at row {int(np.argmax(bad))}; drop these rows before loading.")
        d = np.diff(t)
        if np.any(d <= 0):
            i = int(np.argmax(d <= 0)) + 1
            what = (f"repeated time stamp at row {i} (t={t[i]:.6g} s)" if d[i - 1] == 0 else
                    f"time goes backwards at row {i} (t={t[i]:.6g} s after {t[i - 1]:.6g} s)")
            raise DataError(f"{where}: {what}; sort the rows by time and drop duplicate time "
                            "stamps (df.sort_values('time').drop_duplicates('time')).")
        chans: dict[str, np.ndarray] = {}
        for c, values in dict(self.channels).items():
            if not isinstance(c, str) or not c or c == "time":
                raise DataError(f"{where}: invalid channel name {c!r} (time is given separately).")
            a = _as_array(values, where, c)
            if a.shape != t.shape:
                raise DataError(f"{where}: column '{c}' has shape {a.shape} but time has {t.shape}; "
                                "every channel needs one value per time stamp.")
            bad = ~np.isfinite(a)
            if bad.any():
                i = int(np.argmax(bad))
                raise DataError(f"{where}: column '{c}' has {int(bad.sum())} NaN/inf value(s), first "
                                f"at row {i} (t={t[i]:.6g} s); drop or fill these rows before loading.")
            chans[c] = a
        if self.check_units:
            check_column_units(where, t, chans, str(meta.get("time_unit_in_source", "s")),
                               degrees=tuple(meta.get("degrees_converted", ())))
        check_gaps(where, t)
        for a in (t, *chans.values()):
            a.flags.writeable = False
        object.__setattr__(self, "time", t)
        object.__setattr__(self, "channels", _FrozenDict(chans))
        object.__setattr__(self, "metadata", _FrozenDict(meta))

    # --- basic access -------------------------------------------------------------------
    def __repr__(self) -> str:
        return (f"Run({self.name!r}, n={self.n}, t={self.t0:.4g}..{self.time[-1]:.4g} s, "
                f"channels={list(self.channels)})")

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.time.size)

    @property
    def t0(self) -> float:
        """First time stamp [s]."""
        return float(self.time[0])

    @property
    def duration(self) -> float:
        """Last minus first time stamp [s]."""
        return float(self.time[-1] - self.time[0])

    @property
    def dt(self) -> float:
        """Median time step [s]."""
        return float(np.median(np.diff(self.time)))

    @property
    def channel_names(self) -> tuple[str, ...]:
        """Names of the channels (without ``time``)."""
        return tuple(self.channels)

    @property
    def _loc(self) -> str:
        return _where(self.name, self.metadata.get("source"))

    def __getitem__(self, name: str) -> np.ndarray:
        """Read-only array of channel ``name`` (``"time"`` gives the time stamps)."""
        if name == "time":
            return self.time
        try:
            return self.channels[name]
        except KeyError:
            raise DataError(f"{self._loc} has no channel '{name}'; it has "
                            f"{['time', *self.channels]}.") from None

    def has(self, *names: str) -> bool:
        """True if every one of ``names`` is a channel (or ``time``)."""
        return all(n == "time" or n in self.channels for n in names)

    def require(self, names: str | Iterable[str], purpose: str) -> None:
        """Raise :class:`DataError` unless all ``names`` are present (needed for ``purpose``)."""
        names = [names] if isinstance(names, str) else list(names)
        missing = [n for n in names if not self.has(n)]
        if missing:
            m = missing[0]
            raise DataError(f"{self._loc} lacks channel(s) {missing} needed for {purpose}; it has "
                            f"{list(self.channels)}. If the data hold it under another name, map it: "
                            f"columns={{'{m}': '<column>'}} (CLI: --columns {m}=<column>).")

    # --- derived runs -------------------------------------------------------------------
    def _derive(self, time: np.ndarray, channels: Mapping[str, np.ndarray], **note: Any) -> Run:
        return Run(self.name, time, channels, {**self.metadata, **note}, check_units=False)

    def resample(self, dt: float, held: Sequence[str] = ()) -> Run:
        """Linear interpolation onto the uniform grid ``t0, t0 + dt, ...`` up to the last time; the inputs
        ``held`` over each sample (``--input-hold zero``) as their means over the new intervals
        (:func:`diffship.hold.held_means`). ``psi`` is unwrapped before interpolation and stays unwrapped."""
        if not (np.isfinite(dt) and dt > 0):
            raise DataError(f"{self._loc}: resample step dt must be positive and finite, got {dt}.")
        k = int(np.floor(self.duration / dt + 1e-9))
        t = self.t0 + dt * np.arange(k + 1)
        end = float(self.time[-1] + np.median(np.diff(self.time)))
        chans = {c: held_means(self.time, a, t, end) if c in held else
                 np.interp(t, self.time, psi_unwrap(a)[0] if c == "psi" else a) for c, a in self.channels.items()}
        return self._derive(t, chans, resampled_dt=float(dt))

    def slice(self, t_start: float | None = None, t_end: float | None = None) -> Run:
        """Samples with ``t_start <= time <= t_end`` [s] (absolute times are kept)."""
        lo = -np.inf if t_start is None else t_start
        hi = np.inf if t_end is None else t_end
        keep = (self.time >= lo) & (self.time <= hi)
        return self._derive(self.time[keep], {c: a[keep] for c, a in self.channels.items()},
                            sliced=(t_start, t_end))

    def with_channels(self, **arrays: Any) -> Run:
        """Copy of the run with channels added or replaced (SI units, radians)."""
        if "time" in arrays:
            raise DataError(f"{self._loc}: with_channels cannot replace time; build a new Run.")
        return Run(self.name, self.time, {**self.channels, **arrays}, self.metadata,
                   check_units=self.check_units)

    def to_dataframe(self) -> pd.DataFrame:
        """DataFrame with a ``time`` column followed by the channels (writable copies)."""
        return pd.DataFrame({"time": self.time, **self.channels}).copy()

    # --- construction -------------------------------------------------------------------
    @classmethod
    def from_dataframe(cls, df: pd.DataFrame, name: str = "run", *,
                       columns: Mapping[str, str] | None = None, degrees: Sequence[str] = (),
                       rudder_sign: str = "starboard", time_column: str = "time",
                       source: str | None = None, metadata: Mapping[str, Any] | None = None,
                       check_units: bool = True, time_unit: str = "s") -> Run:
        """Build a run from a DataFrame (which is never modified).

        Parameters
        ----------
        columns : Mapping[str, str], optional
            Channel name -> column name in ``df``, e.g. ``{"psi": "heading_deg"}``.
            Unmapped columns keep their own (whitespace-stripped) names.
        degrees : sequence of str
            Channels (names after mapping, or original column names) in degrees or deg/s;
            multiplied by pi/180.
        rudder_sign : {"starboard", "port"}
            Sign of the rudder in the source; ``"port"`` negates ``RUDDER_CHANNELS``.
        time_column : str
            Name of the time column [s] (``columns["time"]`` takes precedence).
        source : str, optional
            File path or description, quoted in messages and kept in the metadata.
        metadata : Mapping, optional
            Extra metadata merged into the run's metadata.
        time_unit : str
            Unit of a numeric time column: ``"s"`` (default), ``"ms"`` or ``"us"`` (converted to s).
            Date-time stamps (text or datetime64) are read as seconds from the first; timedelta64 as their seconds.
        """
        where = _where(name, source or "DataFrame")
        check_frame(df, where)
        if rudder_sign not in ("starboard", "port"):
            raise DataError(f"{where}: rudder_sign must be 'starboard' or 'port', got {rudder_sign!r}.")
        if len(df) == 0:
            raise DataError(f"{where}: no rows.")
        df = df.copy()
        df.columns = [str(c).strip() for c in df.columns]
        dup = df.columns[df.columns.duplicated()]
        if len(dup):
            raise DataError(f"{where}: duplicate column name(s) {list(dup)}; rename them.")
        cmap = {str(k): str(v).strip() for k, v in (columns or {}).items()}
        cmap.setdefault("time", str(time_column).strip())
        mapped = set(cmap.values())
        present = {ch for ch, col in cmap.items() if col in df.columns} | set(df.columns) - mapped
        check_near_misses(where, [c for c in df.columns if c not in mapped], present)
        for ch, col in cmap.items():
            if col in df.columns:
                continue
            if ch == "time":
                raise DataError(f"{where}: no time column '{col}'; available columns: {list(df.columns)}. "
                                "Map it with columns={'time': '<column>'} (CLI: --columns time=<column>).")
            raise DataError(f"{where}: column '{col}' (for channel '{ch}') not found; "
                            f"available columns: {list(df.columns)}.")
        ignored = [c for c in df.columns if c not in mapped and c in cmap]
        cmap.update({c: c for c in df.columns if c not in mapped and c not in cmap})
        arrays: dict[str, np.ndarray] = {}
        for ch, col in cmap.items():
            s = df[col]
            if ch == "time" and pd.api.types.is_timedelta64_dtype(s):
                s = timedelta_seconds(s, where, time_unit)
            if ch == "time" and not pd.api.types.is_datetime64_any_dtype(s) and not pd.api.types.is_numeric_dtype(s):
                stamps = pd.to_datetime(s, errors="coerce", format="mixed") if s.notna().all() else None
                if stamps is not None and stamps.notna().all():
                    s = stamps  # date-time stamps: seconds from the first
            if ch == "time" and pd.api.types.is_datetime64_any_dtype(s):
                s = (s - s.iloc[0]).dt.total_seconds()
                if time_unit != "s":
                    raise DataError(f"{where}: the time column holds date-times (read as seconds from the first); "
                                    f"time_unit={time_unit!r} does not apply, drop it")
            elif not pd.api.types.is_numeric_dtype(s) or pd.api.types.is_complex_dtype(s):
                num = pd.to_numeric(s, errors="coerce")
                bad = num.isna().to_numpy() & s.notna().to_numpy()
                if bad.any() or pd.api.types.is_complex_dtype(s):
                    i = int(np.argmax(bad))
                    raise DataError(f"{where}: column '{col}' is not numeric (first bad value "
                                    f"{s.iloc[i]!r} at row {i}); fix or drop that column.")
                s = num
            arrays[ch] = s.to_numpy(dtype=np.float64, na_value=np.nan)
        by_col = {col: ch for ch, col in cmap.items()}
        converted = []
        for d in [degrees] if isinstance(degrees, str) else list(degrees):
            ch = d if d in arrays and d != "time" else by_col.get(d)
            if ch is None or ch == "time":
                raise DataError(f"{where}: degrees names unknown channel '{d}'; channels: "
                                f"{[c for c in arrays if c != 'time']}.")
            if ch not in converted:
                arrays[ch] = arrays[ch] * _DEG
                converted.append(ch)
        flipped = [c for c in RUDDER_CHANNELS if c in arrays] if rudder_sign == "port" else []
        for c in flipped:
            arrays[c] = -arrays[c]
        if time_unit not in TIME_UNITS:
            raise DataError(f"{where}: time_unit must be one of {', '.join(TIME_UNITS)}, got {time_unit!r}.")
        time = arrays.pop("time") * TIME_UNITS[time_unit]
        meta = {"source": source or "DataFrame", "rudder_sign_in_source": rudder_sign,
                "rudder_flipped": tuple(flipped), "degrees_converted": tuple(converted),
                "column_map": dict(cmap), "ignored_columns": tuple(ignored), "time_unit_in_source": time_unit,
                **(metadata or {})}
        return cls(name, time, arrays, meta, check_units=check_units)

    @classmethod
    def from_csv(cls, path: str | os.PathLike, name: str | None = None, **kw: Any) -> Run:
        """Read a CSV file (separator ``;``, ``,``, tab or whitespace detected from the header).

        ``name`` defaults to the file stem; other keywords go to :meth:`from_dataframe`.
        """
        path = Path(path)
        name = name or path.stem
        where = _where(name, path)
        try:
            raw = path.read_bytes()
        except FileNotFoundError:
            raise DataError(f"{path}: file not found; check the path.") from None
        except OSError as exc:
            raise DataError(f"{path}: cannot read the file ({exc.strerror or exc}).") from None
        if b"\x00" in raw[:4096]:
            raise DataError(f"{path}: not a text CSV file (binary content); export the run as CSV.")
        try:
            text = raw.decode("utf-8-sig")
        except UnicodeDecodeError:
            text = raw.decode("latin-1")
        if not text.strip():
            raise DataError(f"{path}: empty file.")
        header = next(line for line in text.splitlines() if line.strip())
        counts = {s: header.count(s) for s in (";", ",", "\t")}
        sep = max(counts, key=counts.get) if max(counts.values()) else r"\s+"

        def read(decimal: str) -> pd.DataFrame:
            try:
                return pd.read_csv(io.StringIO(text), sep=sep, decimal=decimal, skipinitialspace=True)
            except (pd.errors.ParserError, pd.errors.EmptyDataError, ValueError) as exc:
                raise DataError(f"{where}: cannot parse as CSV ({str(exc).strip()}).") from None

        df = read(".")
        head = pd.read_csv(io.StringIO(text), sep=sep, header=None, nrows=1, dtype=str, skipinitialspace=True)
        check_header(where, head.iloc[0].fillna("").tolist())  # the names as written: pandas renames copies
        comma = re.compile(r"^\s*[-+]?\d*,\d+([eE][-+]?\d+)?\s*$")
        text_cols = [df[c].dropna().astype(str) for c in df.columns
                     if not pd.api.types.is_numeric_dtype(df[c]) and df[c].notna().any()]
        if sep != "," and any(s.str.match(comma).all() for s in text_cols):
            df = read(",")
        kw.setdefault("source", str(path))
        return cls.from_dataframe(df, name, **kw)


def load_runs(paths: str | os.PathLike | Iterable[os.PathLike | str], *, channel_map: Any = None, **kw) -> list[Run]:
    """Load CSV files or logs (``channel_map``, :mod:`diffship.logs`) alike; names are file stems made unique."""
    from .logs import is_log, log_runs  # robot logs, parquet; logs never import data: Run is passed
    paths = [paths] if isinstance(paths, (str, os.PathLike)) else list(paths)
    if not paths:
        raise DataError("load_runs: no files given.")
    if "name" in kw:
        raise DataError("load_runs: 'name' cannot be shared by several files; names are file stems.")
    stems = [Path(p).stem for p in paths]
    seen: dict[str, int] = {}
    runs, units = [], []
    for p, stem in zip(paths, stems):
        name = stem
        if stems.count(stem) > 1:
            seen[stem] = seen.get(stem, 0) + 1
            name = f"{stem}_{seen[stem]}"
        if is_log(p):
            runs.extend(log_runs(p, name, channel_map, kw, Run))
            continue
        try:
            runs.append(Run.from_csv(p, name, **kw))
        except UnitsError as exc:  # every file's unit problems in one message
            units.append(exc)
    if len(units) == 1:
        raise units[0]
    if units:
        degs = list(dict.fromkeys(c for e in units for c in e.columns))
        tu = next((e.time_unit for e in units if e.time_unit), None)
        drops = list(dict.fromkeys(c for e in units for c in e.drop_degrees))
        fixes = ([f"--degrees {' '.join(degs)}"] if degs else []) + ([f"--time-unit {tu}"] if tu else [])
        tail = ([f"pass {' and '.join(fixes)} (Python: degrees=..., time_unit=...)"] if fixes else []) + (
            [f"drop {' '.join(drops)} from --degrees (Python: from degrees=...)"] if drops else [])
        detail = f"{len(units)} files have unit problems: " + " | ".join(e.detail for e in units)
        raise UnitsError(f"{detail}; {' and '.join(tail)}", degs, tu, drops, detail)
    return runs


def resample_runs(runs: Sequence[Run], dt: float, option: str = "--resample", held: Sequence[str] = ()) -> list[Run]:
    """Every run resampled to the step ``dt`` [s] (``held``: inputs held over each sample, :meth:`Run.resample`); a
    run left with fewer than ``MIN_SAMPLES`` stops with ``option``, the run's length and the longest step that keeps
    every run."""
    for r in runs:
        if (k := int(np.floor(r.duration / dt + 1e-9)) + 1) < MIN_SAMPLES:
            most = 0.995 * min(q.duration for q in runs) / (MIN_SAMPLES - 1)
            raise DataError(f"{option} {dt:g}: run '{r.name}' lasts {r.duration:.4g} s, so a step of {dt:g} s leaves "
                            f"{k} sample(s) (at least {MIN_SAMPLES} needed); give a step of at most {most:.3g} s")
    return [r.resample(dt, held) for r in runs]


def example_path(name: str) -> Path:
    """Path of a bundled example file (``name`` without ``.csv``)."""
    path = _EXAMPLES_DIR / f"{name}.csv"
    if name not in _EXAMPLES or not path.is_file():
        raise DataError(f"unknown example '{name}'; available: {sorted(_EXAMPLES)}.")
    return path


def example_runs(name: str = "sspa_zigzag") -> list[Run]:
    """Load a bundled example (rudder sign converted to starboard-positive)."""
    path = example_path(name)
    return [Run.from_csv(path, name, rudder_sign="port", metadata={"example": name, **_EXAMPLES[name]})]


def shared_data_dir() -> Path | None:
    """The shared real-data folder (``DIFFSHIP_SHARED_DATA`` or ``<repo>/../shared/data``), if any."""
    candidates = []
    if os.environ.get("DIFFSHIP_SHARED_DATA"):
        candidates.append(Path(os.environ["DIFFSHIP_SHARED_DATA"]))
    candidates += [Path(__file__).resolve().parents[2].parent / "shared" / "data",
                   Path.cwd().parent / "shared" / "data"]
    return next((c for c in candidates if c.is_dir()), None)


def kvlcc2_runs(root: str | os.PathLike | None = None) -> list[Run]:
    """Load the 13 KVLCC2 (HSVA, SIMMAN 2008) zigzag tests from the tidy CSVs.

    The files have no data licence and are read from outside the repository
    (``root``, ``$DIFFSHIP_SHARED_DATA/kvlcc2_hsva`` or ``../shared/data/kvlcc2_hsva``).
    Rudder sign in the files is port-positive; it is flipped to starboard-positive.
    """
    if root is None:
        candidates = []
        if os.environ.get("DIFFSHIP_SHARED_DATA"):
            env = Path(os.environ["DIFFSHIP_SHARED_DATA"])
            candidates += [env / "kvlcc2_hsva", env]
        candidates.append(Path.cwd().parent / "shared" / "data" / "kvlcc2_hsva")
        shared = shared_data_dir()
        if shared is not None:
            candidates.append(shared / "kvlcc2_hsva")
        folder = next((c for c in candidates if list(c.glob("HSVA_CPMC_KVLCC2_*.csv"))), None)
        if folder is None:
            raise DataError("KVLCC2 data not found: looked in "
                            f"{[str(c) for c in candidates]}; set DIFFSHIP_SHARED_DATA to the "
                            "shared data folder or pass root=.")
    else:
        folder = Path(root)
    files = sorted(folder.glob("HSVA_CPMC_KVLCC2_*.csv"))
    if not files:
        raise DataError(f"{folder}: no HSVA_CPMC_KVLCC2_*.csv files found.")
    runs = []
    for f in files:
        m = re.search(r"Z_(\d+)_(\d+)(?:_([SP]))?$", f.stem)
        test = f.stem.split("KVLCC2_", 1)[-1]
        meta: dict[str, Any] = {"ship": "KVLCC2", "facility": "HSVA (SIMMAN 2008)", "test": test,
                                "model_scale": 45.714, "licence": "none stated: do not redistribute"}
        if m:
            meta.update(manoeuvre="zigzag", rudder_angle_deg=float(m.group(1)),
                        switch_heading_deg=float(m.group(2)))
        run = Run.from_csv(f, f"KVLCC2_{test}", rudder_sign="port", metadata=meta)
        side = {"S": "starboard", "P": "port"}.get(m.group(3)) if m and m.group(3) else None
        if side is None:  # not in the file name: first clear rudder order in the data
            d = run["delta"]
            side = "starboard" if d[int(np.argmax(np.abs(d) > 0.5 * np.abs(d).max()))] > 0 else "port"
        runs.append(Run(run.name, run.time, run.channels, {**run.metadata, "first_rudder": side},
                        check_units=False))
    return runs
