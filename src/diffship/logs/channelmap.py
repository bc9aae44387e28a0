"""The channel map: which log field becomes which diffship channel (a TOML file).

A map names its sources (a topic of a ROS 2 bag, a message type of an ArduPilot / MAVLink log, a
ULog topic, or a parquet file's table) with the clock each keeps, and for every diffship channel
the source, the field, its unit, a scale (sign) and how it is held between samples::

    name = "ros2_usv"
    frame = "ros"          # "ros": REP-103 ENU/FLU converted to NED/FRD; "ned": already NED/FRD
    max_gap = 1.0          # [s] a longer gap in any source splits the run (default: 5 × its median step)
    dt = 0.1               # [s] grid step (default: the slowest measured output's median step)

    [sources.odom]
    topic = "/odom"
    clock = "header"       # header (message header stamp) | log (recording time) | a time field

    [channels]
    psi = { source = "odom", field = "pose.pose.orientation" }        # quaternion -> clockwise psi
    u = { source = "odom", field = "twist.twist.linear" }             # FLU vector -> FRD component
    tau_x = { source = "wrench", field = "wrench.force", hold = "zoh" }

Channel keys: ``source``, ``field`` (dotted path; a vector or quaternion with ``frame = "ros"``),
``unit`` (:data:`UNITS`; SI by default), ``scale`` (a factor after the unit, e.g. −1 for a sign),
``offset`` (added last, SI), ``quaternion`` (``"wxyz"`` or ``"xyzw"``: ``field`` is an array field
``q[0..3]``), ``north``/``east`` (earth-frame velocity fields: ``u``/``v`` are rotated into the body by
``psi``), ``hold`` (``"zoh"`` zero-order hold, the default for inputs; ``"linear"``, the default for
outputs). Plain Python (``tomllib``); maps bundled with diffship are in ``diffship/maps/``.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..errors import DataError
from .frames import FRAMES

__all__ = ["INPUT_CHANNELS", "UNITS", "ChannelMap", "ChannelSpec", "SourceSpec", "bundled_maps", "load_map"]

MAPS_DIR = Path(__file__).resolve().parents[1] / "maps"
_DEG = math.pi / 180.0
#: Units a map may declare -> factor to diffship's internal unit (SI, radians).
UNITS: dict[str, float] = {
    "si": 1.0, "m": 1.0, "m/s": 1.0, "rad": 1.0, "rad/s": 1.0, "N": 1.0, "N m": 1.0, "Nm": 1.0, "1/s": 1.0,
    "rev/s": 1.0, "rev/min": 1.0, "deg": _DEG, "deg/s": _DEG, "cdeg": _DEG / 100, "cdeg/s": _DEG / 100,
    "mm": 1e-3, "cm": 1e-2, "mm/s": 1e-3, "cm/s": 1e-2, "kN": 1e3, "kN m": 1e3, "us": 1.0, "1": 1.0,
}
#: Channels held between samples by default (zero-order hold): the inputs of diffship's models.
INPUT_CHANNELS = frozenset({"delta", "n", "rpm", "thrust", "nozzle", "delta_n", "tau_x", "tau_y", "tau_z",
                            "tau_k", "tau_m", "tau_n"})
_CHANNEL_KEYS = {"source", "field", "unit", "scale", "offset", "quaternion", "north", "east", "hold"}
_SOURCE_KEYS = {"topic", "clock"}
_TOP_KEYS = {"name", "description", "frame", "max_gap", "dt", "rudder_sign", "sources", "channels"}


@dataclasses.dataclass(frozen=True)
class SourceSpec:
    """One source: ``topic`` (ROS topic, MAVLink/DataFlash message type, ULog topic, ``"table"`` for
    parquet) and its clock (``"header"``, ``"log"`` or a time field such as ``TimeUS``)."""

    name: str
    topic: str
    clock: str = "auto"


@dataclasses.dataclass(frozen=True)
class ChannelSpec:
    """One diffship channel from one source field (see the module docstring for the keys)."""

    channel: str
    source: str
    field: str = ""
    unit: str = "si"
    scale: float = 1.0
    offset: float = 0.0
    quaternion: str = ""
    north: str = ""
    east: str = ""
    hold: str = ""

    @property
    def factor(self) -> float:
        return UNITS[self.unit] * self.scale

    @property
    def zoh(self) -> bool:
        """Zero-order hold between samples (inputs) rather than linear interpolation (outputs)."""
        return self.hold == "zoh" if self.hold else self.channel in INPUT_CHANNELS


@dataclasses.dataclass(frozen=True)
class ChannelMap:
    """A parsed channel map (:func:`load_map`)."""

    name: str
    frame: str
    sources: Mapping[str, SourceSpec]
    channels: Mapping[str, ChannelSpec]
    max_gap: float | None = None
    dt: float | None = None
    rudder_sign: str = "starboard"
    path: str = ""
    description: str = ""

    def fields(self) -> dict[str, set[str]]:
        """Source name -> the field paths the map reads from it."""
        out: dict[str, set[str]] = {s: set() for s in self.sources}
        for c in self.channels.values():
            out[c.source] |= {f for f in (c.field, c.north, c.east) if f}
        return out


def bundled_maps() -> list[str]:
    """Names of the maps shipped with diffship (``--map NAME``)."""
    return sorted(p.stem for p in MAPS_DIR.glob("*.toml"))


def _number(where: str, key: str, value: Any, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise DataError(f"{where}: '{key}' must be a finite number, got {value!r}.")
    if positive and value <= 0:
        raise DataError(f"{where}: '{key}' must be positive, got {value!r}.")
    return float(value)


def load_map(spec: str | Path | ChannelMap) -> ChannelMap:
    """Read a channel map: a TOML file path or the name of a bundled map (:func:`bundled_maps`)."""
    if isinstance(spec, ChannelMap):
        return spec
    path = Path(spec)
    if not path.is_file() and (MAPS_DIR / f"{spec}.toml").is_file():
        path = MAPS_DIR / f"{spec}.toml"
    if not path.is_file():
        raise DataError(f"--map {spec}: no such file and no bundled map of that name; bundled: {bundled_maps()}.")
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise DataError(f"{path}: not a valid TOML channel map ({exc}).") from None
    where = str(path)
    unknown = sorted(set(doc) - _TOP_KEYS)
    if unknown:
        raise DataError(f"{where}: unknown key(s) {unknown}; a channel map has {sorted(_TOP_KEYS)}.")
    frame = doc.get("frame", "ned")
    if frame not in FRAMES:
        raise DataError(f"{where}: frame = {frame!r}; use \"ros\" (REP-103 ENU/FLU) or \"ned\" (NED/FRD).")
    rudder = doc.get("rudder_sign", "starboard")
    if rudder not in ("starboard", "port"):
        raise DataError(f"{where}: rudder_sign = {rudder!r}; use \"starboard\" or \"port\".")
    sources = {}
    for name, s in (doc.get("sources") or {}).items():
        if not isinstance(s, dict) or "topic" not in s or set(s) - _SOURCE_KEYS:
            raise DataError(f"{where}: [sources.{name}] needs 'topic' (and optionally 'clock'), nothing else.")
        sources[name] = SourceSpec(name, str(s["topic"]), str(s.get("clock", "auto")))
    channels = {}
    for ch, c in (doc.get("channels") or {}).items():
        w = f"{where}: channel '{ch}'"
        if not isinstance(c, dict):
            raise DataError(f"{w}: expected a table {{ source = ..., field = ... }}.")
        if set(c) - _CHANNEL_KEYS:
            raise DataError(f"{w}: unknown key(s) {sorted(set(c) - _CHANNEL_KEYS)}; keys: {sorted(_CHANNEL_KEYS)}.")
        if c.get("source") not in sources:
            raise DataError(f"{w}: source {c.get('source')!r} is not one of the map's [sources] {sorted(sources)}.")
        unit = str(c.get("unit", "si"))
        if unit not in UNITS:
            raise DataError(f"{w}: unknown unit {unit!r}; known: {sorted(UNITS)}.")
        spec_ = ChannelSpec(ch, c["source"], str(c.get("field", "")), unit,
                            _number(w, "scale", c.get("scale", 1.0)), _number(w, "offset", c.get("offset", 0.0)),
                            str(c.get("quaternion", "")), str(c.get("north", "")), str(c.get("east", "")),
                            str(c.get("hold", "")))
        if spec_.hold not in ("", "zoh", "linear"):
            raise DataError(f"{w}: hold = {spec_.hold!r}; use \"zoh\" or \"linear\".")
        if spec_.quaternion not in ("", "wxyz", "xyzw"):
            raise DataError(f"{w}: quaternion = {spec_.quaternion!r}; use \"wxyz\" or \"xyzw\".")
        if bool(spec_.north) != bool(spec_.east) or (spec_.north and ch not in ("u", "v")):
            raise DataError(f"{w}: 'north' and 'east' (earth-frame velocity fields) go together, for u and v only.")
        if not spec_.field and not spec_.north:
            raise DataError(f"{w}: give 'field' (or 'north' and 'east' for an earth-frame velocity).")
        channels[ch] = spec_
    if not channels:
        raise DataError(f"{where}: no [channels]; map at least the channels your model needs.")
    max_gap = doc.get("max_gap")
    dt = doc.get("dt")
    return ChannelMap(str(doc.get("name", path.stem)), frame, sources, channels,
                      None if max_gap is None else _number(where, "max_gap", max_gap, True),
                      None if dt is None else _number(where, "dt", dt, True), rudder, str(path),
                      str(doc.get("description", "")))
