"""Readers of robot logs: per-topic tables of fields on the topic's own clock.

=========================  ===================  ======================  ===========================
format                     suffix               library (extra)          clocks available
=========================  ===================  ======================  ===========================
ROS 2 bag, sqlite3 / MCAP  folder, .db3, .mcap  ``rosbags`` (``logs``)  ``header`` stamp, ``log``
ArduPilot DataFlash        .bin                 ``pymavlink`` (logs)    ``TimeUS`` (boot), ``log``
MAVLink telemetry          .tlog                ``pymavlink`` (logs)    ``time_boot_ms``, ``log``
PX4 ULog                   .ulg                 ``pyulog`` (logs)       ``timestamp`` (boot)
parquet table              .parquet             ``pyarrow`` (logs)      a time column
=========================  ===================  ======================  ===========================

``log`` is the recording clock (bag receive time, MAVLink log time); ``header`` the sender's stamp
(``header.stamp`` of ROS messages; ROS times are counted from the bag's start in integer nanoseconds,
``Table.epoch`` keeps the start). ``auto`` picks ``header`` where messages have one, else the
vehicle's boot clock, else ``log``. Every reader returns, for each requested topic, a
:class:`Table`: time [s] on the chosen clock and each requested field as an ``(N,)`` array or, for
a vector / quaternion / array field, an ``(N, k)`` array with its component names.
"""

from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..errors import DataError

__all__ = ["LOG_SUFFIXES", "Table", "is_log", "read_tables", "require_extra"]

LOG_SUFFIXES = (".db3", ".mcap", ".bin", ".tlog", ".ulg", ".parquet")
#: Time fields -> factor to seconds.
_TIME_FIELDS = {"TimeUS": 1e-6, "TimeMS": 1e-3, "timestamp": 1e-6, "time_boot_ms": 1e-3, "time_usec": 1e-6}


@dataclasses.dataclass(frozen=True)
class Table:
    """One topic's samples: ``time`` [s] on ``clock``, ``values[field]`` ``(N,)`` or ``(N, k)``,
    ``components[field]`` the names of the k components of a composite field."""

    topic: str
    clock: str
    time: np.ndarray
    values: Mapping[str, np.ndarray]
    components: Mapping[str, tuple[str, ...]]
    epoch: float = 0.0  # [s] clock value of time 0 (ROS bags: the bag start, so that times keep ns resolution)


def require_extra(module: str, what: str):
    """Import ``module`` or stop with one line naming the extra to install."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise DataError(f"{what} needs the optional package '{module.split('.')[0]}': "
                        "pip install 'diffship[logs]'") from None


def is_log(path: str | Path) -> bool:
    """True for the log formats of this module (a ROS 2 bag folder holds metadata.yaml)."""
    p = Path(path)
    return p.suffix.lower() in LOG_SUFFIXES or (p.is_dir() and (p / "metadata.yaml").is_file())


def read_tables(path: str | Path, wanted: Mapping[str, tuple[str, set[str]]]) -> dict[str, Table]:
    """Read ``wanted`` (source name -> (topic, clock), fields) from the log at ``path``."""
    p = Path(path)
    if not p.exists():
        raise DataError(f"{p}: file not found; check the path.")
    suffix = p.suffix.lower()
    if p.is_dir() or suffix in (".db3", ".mcap"):
        return _read_rosbag(p, wanted)
    if suffix in (".bin", ".tlog"):
        return _read_mavlink(p, wanted)
    if suffix == ".ulg":
        return _read_ulog(p, wanted)
    if suffix == ".parquet":
        return _read_parquet(p, wanted)
    raise DataError(f"{p}: unknown log format '{suffix}'; known: {', '.join(LOG_SUFFIXES)} or a ROS 2 bag folder.")


def _stack(rows: list, where: str, field: str) -> tuple[np.ndarray, tuple[str, ...]]:
    first = rows[0]
    if isinstance(first, (int, float, np.integer, np.floating, bool)):
        return np.asarray(rows, dtype=np.float64), ()
    names = tuple(c for c in ("x", "y", "z", "w") if hasattr(first, c))
    if names:
        return np.array([[float(getattr(r, c)) for c in names] for r in rows]), names
    raise DataError(f"{where}: field '{field}' is neither a number nor a vector/quaternion "
                    f"({type(first).__name__}); name a numeric field or a geometry_msgs vector.")


def _resolve(msg, path: str, where: str):
    obj = msg
    for part in path.split("."):
        if not hasattr(obj, part):
            have = [a for a in dir(obj) if not a.startswith("_")]
            raise DataError(f"{where}: no field '{path}' ('{part}' not found; there: {have}).")
        obj = getattr(obj, part)
    return obj


def _read_rosbag(p: Path, wanted) -> dict[str, Table]:
    highlevel = require_extra("rosbags.highlevel", f"{p} (a ROS 2 bag)")
    typesys = require_extra("rosbags.typesys", f"{p} (a ROS 2 bag)")
    folder = p if p.is_dir() else p.parent
    out = {}
    try:
        reader = highlevel.AnyReader([folder], default_typestore=typesys.get_typestore(typesys.Stores.ROS2_HUMBLE))
        reader.open()
    except Exception as exc:  # noqa: BLE001 (rosbags raises several error types for unreadable bags)
        raise DataError(f"{p}: cannot open as a ROS 2 bag ({exc}).") from None
    try:
        topics = {c.topic: c for c in reader.connections}
        zero = int(reader.start_time)  # [ns]
        for name, ((topic, clock), fields) in wanted.items():
            where = f"{p}, topic {topic}"
            conns = [c for c in reader.connections if c.topic == topic]
            if not conns:
                raise DataError(f"{p}: no topic '{topic}' (source '{name}'); topics: {sorted(topics)}.")
            msgs, logt = [], []
            for conn, stamp, raw in reader.messages(connections=conns):
                msgs.append(reader.deserialize(raw, conn.msgtype))
                logt.append(stamp)
            if not msgs:
                raise DataError(f"{where}: no messages.")
            has_header = hasattr(msgs[0], "header")
            use = ("header" if has_header else "log") if clock == "auto" else clock
            if use == "header":
                if not has_header:
                    raise DataError(f"{where}: clock = \"header\" but {conns[0].msgtype} has no header; use \"log\".")
                ns = np.array([m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in msgs], dtype=np.int64)
                t = (ns - zero) * 1e-9  # integer nanoseconds from the bag start: no float rounding of epochs
            elif use == "log":
                t = (np.asarray(logt, dtype=np.int64) - zero) * 1e-9
            else:
                raise DataError(f"{where}: clock {use!r}; a ROS 2 bag has \"header\" and \"log\".")
            values, comps = {}, {}
            for f in sorted(fields):
                values[f], comps[f] = _stack([_resolve(m, f, where) for m in msgs], where, f)
            out[name] = Table(topic, f"{use} ({'header.stamp' if use == 'header' else 'bag receive time'})", t,
                              values, comps, epoch=zero * 1e-9)
    finally:
        reader.close()
    return out


def _read_mavlink(p: Path, wanted) -> dict[str, Table]:
    mavutil = require_extra("pymavlink.mavutil", f"{p} (an ArduPilot/MAVLink log)")
    types = {topic for (topic, _), _ in wanted.values()}
    rows: dict[str, list] = {t: [] for t in types}
    conn = None
    try:
        conn = mavutil.mavlink_connection(str(p), dialect="ardupilotmega")
        while True:
            m = conn.recv_match(type=list(types), blocking=False)
            if m is None:
                break
            rows[m.get_type()].append((m._timestamp, m.to_dict()))
    except DataError:
        raise
    except Exception as exc:  # noqa: BLE001 (pymavlink raises plain exceptions on corrupt logs)
        raise DataError(f"{p}: cannot read as a DataFlash/MAVLink log ({exc}).") from None
    finally:
        if conn is not None:
            conn.close()
    out = {}
    for name, ((topic, clock), fields) in wanted.items():
        where = f"{p}, message {topic}"
        if not rows[topic]:
            raise DataError(f"{where}: no messages of type {topic} (source '{name}').")
        d0 = rows[topic][0][1]
        boot = next((f for f in ("TimeUS", "TimeMS", "time_boot_ms", "time_usec") if f in d0), None)
        use = (boot or "log") if clock == "auto" else clock
        if use == "log":
            t = np.array([ts for ts, _ in rows[topic]])
        elif use in _TIME_FIELDS and use in d0:
            t = np.array([d[use] for _, d in rows[topic]], dtype=np.float64) * _TIME_FIELDS[use]
        else:
            raise DataError(f"{where}: clock {use!r} is not a time field of {topic}; use \"log\" or one of "
                            f"{[f for f in _TIME_FIELDS if f in d0]}.")
        values = {}
        for f in sorted(fields):
            if f not in d0:
                raise DataError(f"{where}: no field '{f}'; fields: {[k for k in d0 if k != 'mavpackettype']}.")
            values[f] = np.array([d[f] for _, d in rows[topic]], dtype=np.float64)
        out[name] = Table(topic, f"{use} ({'log time' if use == 'log' else 'vehicle boot time'})", t, values, {})
    return out


def _read_ulog(p: Path, wanted) -> dict[str, Table]:
    pyulog = require_extra("pyulog", f"{p} (a PX4 ULog)")
    names = sorted({topic.split(":")[0] for (topic, _), _ in wanted.values()})
    try:
        ulog = pyulog.ULog(str(p), names)
    except Exception as exc:  # noqa: BLE001 (pyulog raises plain exceptions on corrupt files)
        raise DataError(f"{p}: cannot read as a ULog ({exc}).") from None
    out = {}
    for name, ((topic, clock), fields) in wanted.items():
        base, _, inst = topic.partition(":")
        data = [d for d in ulog.data_list if d.name == base and d.multi_id == int(inst or 0)]
        if not data:
            raise DataError(f"{p}: no ULog topic '{topic}' (source '{name}'); topics: "
                            f"{sorted({d.name for d in ulog.data_list})}.")
        d = data[0].data
        use = "timestamp" if clock == "auto" else clock
        if use not in d:
            raise DataError(f"{p}, topic {topic}: no clock field '{use}'.")
        t = np.asarray(d[use], dtype=np.float64) * _TIME_FIELDS.get(use, 1.0)
        values, comps = {}, {}
        for f in sorted(fields):
            if f in d:
                values[f], comps[f] = np.asarray(d[f], dtype=np.float64), ()
            elif f"{f}[0]" in d:
                k = sum(1 for key in d if key.startswith(f"{f}["))
                values[f] = np.stack([np.asarray(d[f"{f}[{i}]"], dtype=np.float64) for i in range(k)], axis=1)
                comps[f] = tuple(str(i) for i in range(k))
            else:
                raise DataError(f"{p}, topic {topic}: no field '{f}'; fields: {sorted(d)}.")
        out[name] = Table(topic, f"{use} (vehicle boot time)", t, values, comps)
    return out


def _read_parquet(p: Path, wanted) -> dict[str, Table]:
    pq = require_extra("pyarrow.parquet", f"{p} (a parquet table)")
    try:
        df = pq.read_table(p).to_pandas()
    except Exception as exc:  # noqa: BLE001 (pyarrow raises ArrowInvalid and others)
        raise DataError(f"{p}: cannot read as parquet ({exc}).") from None
    out = {}
    for name, ((topic, clock), fields) in wanted.items():
        col = "time" if clock in ("auto", "log") else clock
        if col not in df.columns:
            raise DataError(f"{p}: no time column '{col}'; columns: {list(df.columns)}; set clock = \"<column>\".")
        missing = [f for f in fields if f not in df.columns]
        if missing:
            raise DataError(f"{p}: no column(s) {missing}; columns: {list(df.columns)}.")
        t = df[col]
        t = (t - t.iloc[0]).dt.total_seconds().to_numpy() if np.issubdtype(t.dtype, np.datetime64) else \
            t.to_numpy(dtype=np.float64)
        out[name] = Table(topic, f"{col} (column)", t, {f: df[f].to_numpy(dtype=np.float64) for f in fields}, {})
    return out
