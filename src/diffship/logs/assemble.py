"""From per-source tables on their own clocks to runs on one grid: frames, clocks, holds, gaps.

1. **Channels on their source's clock.** Each channel is read from its source's field, converted to
   SI (``unit``), scaled, offset and, with ``frame = "ros"``, turned from ENU/FLU into NED/FRD
   (:mod:`diffship.logs.frames`). Earth-frame velocities (``north``, ``east``) become body
   velocities with the map's heading ψ (interpolated to the velocity's clock):
   ``u = v_N cos ψ + v_E sin ψ``, ``v = −v_N sin ψ + v_E cos ψ``.
2. **Gaps.** A source whose consecutive samples are more than ``max_gap`` apart (default: 5 × its
   median step) has a gap there. Gaps are never filled: the run is split at every gap of any source
   and each piece is a run of its own (pieces shorter than 10 grid samples are dropped and reported).
3. **One grid.** Times are shifted so that the latest source start is 0 (``metadata["time_origin"]``
   keeps the clock value). The grid steps by ``dt`` (default: the slowest measured output's median
   step) and is aligned on that source's samples. Outputs are interpolated linearly (angles
   unwrapped first); inputs are held (zero-order hold): the value of the last sample at or before
   each grid time, the hold a digital controller applies.
4. **Metadata.** ``sources`` (topic, clock, samples, rate), ``gaps`` (source, start, end [s]),
   ``segment`` (k of n, span), ``map``.

Plain NumPy; returns ``(name, time, channels, metadata)`` tuples that :mod:`diffship.data` turns into runs.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DataError
from .channelmap import ChannelMap, ChannelSpec
from .frames import ANGLE_FROM_ATTITUDE, ROS_VECTOR_RULES, euler_from_quaternion, ros_vector_component
from .readers import Table

__all__ = ["GAP_FACTOR", "MIN_SEGMENT", "assemble"]

GAP_FACTOR = 5.0
MIN_SEGMENT = 10
_ANGLES = {"psi", "phi", "theta"}
_TOL = 1e-6  # [s] clock tolerance when matching grid times to samples


def _clean_time(t: np.ndarray, where: str) -> tuple[np.ndarray, np.ndarray, int]:
    """Sorted unique times (order index, number of reordered/duplicate samples dropped or moved)."""
    if t.size < 2 or not np.all(np.isfinite(t)):
        raise DataError(f"{where}: fewer than 2 samples or non-finite time stamps.")
    order = np.argsort(t, kind="stable")
    ts = t[order]
    keep = np.concatenate([[True], np.diff(ts) > 0])
    changed = int((order != np.arange(t.size)).sum() + (~keep).sum())
    return ts[keep], order[keep], changed


def _quaternion(spec: ChannelSpec, table: Table, frame: str, where: str) -> np.ndarray:
    a = table.values[spec.field]
    comps = table.components[spec.field]
    if spec.quaternion:
        order = spec.quaternion
        if a.ndim != 2 or a.shape[1] != 4:
            raise DataError(f"{where}: field '{spec.field}' is not a 4-component array (quaternion = {order!r}).")
        wxyz = a[:, [order.index(c) for c in "wxyz"]]
    elif comps == ("x", "y", "z", "w"):
        wxyz = a[:, [3, 0, 1, 2]]
    else:
        raise DataError(f"{where}: '{spec.channel}' needs a quaternion; field '{spec.field}' has components "
                        f"{comps or 'none'}: name a quaternion field or set quaternion = \"wxyz\" for an array q[0..3].")
    return euler_from_quaternion(wxyz, frame, where)[:, ANGLE_FROM_ATTITUDE[spec.channel]]


def _channel(spec: ChannelSpec, table: Table, frame: str, where: str) -> np.ndarray:
    """A channel's values on its source's samples, SI and NED/FRD (earth velocities handled by the caller)."""
    a = table.values[spec.field]
    if spec.channel in ANGLE_FROM_ATTITUDE and (a.ndim == 2 or spec.quaternion):
        y = _quaternion(spec, table, frame, where)
    elif a.ndim == 2:
        comps = table.components[spec.field]
        if frame == "ros" and comps[:3] == ("x", "y", "z"):
            y = ros_vector_component(spec.channel, a[:, :3], where)
        else:
            raise DataError(f"{where}: field '{spec.field}' is a vector {comps}; with frame = \"{frame}\" name one "
                            "component (e.g. '.x'), or use frame = \"ros\" for REP-103 vectors.")
    else:
        y = a.astype(np.float64)
        if frame == "ros" and spec.channel in ROS_VECTOR_RULES:  # a scalar would skip the ENU/FLU conversion
            raise DataError(f"{where}: with frame = \"ros\" name the vector (e.g. 'twist.twist.linear'), not the "
                            f"scalar '{spec.field}': diffship picks and signs the component of '{spec.channel}' "
                            "(REP 103 -> NED/FRD); or use frame = \"ned\" with an explicit scale.")
        if frame == "ros" and spec.channel == "psi":
            y = np.pi / 2 - y * spec.factor  # a ROS yaw angle: counter-clockwise from east
            return y + spec.offset
    return y * spec.factor + spec.offset


def assemble(path: str | Path, cmap: ChannelMap, tables: Mapping[str, Table],
             name: str) -> list[tuple[str, np.ndarray, dict[str, np.ndarray], dict[str, Any]]]:
    """Split, resample and hold the channels of ``tables`` (see the module docstring)."""
    clean: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    src_meta: dict[str, dict[str, Any]] = {}
    for s, tab in tables.items():
        where = f"{path}, source '{s}' ({tab.topic})"
        t, idx, changed = _clean_time(np.asarray(tab.time, dtype=np.float64), where)
        clean[s] = (t, idx)
        step = float(np.median(np.diff(t)))
        src_meta[s] = {"topic": tab.topic, "clock": tab.clock, "samples": int(t.size),
                       "rate_hz": round(1.0 / step, 6), "reordered_or_duplicate": changed}
    origin = max(float(t[0]) for t, _ in clean.values())
    values: dict[str, tuple[np.ndarray, np.ndarray]] = {}  # channel -> (time rel. origin, values)
    for ch, spec in cmap.channels.items():
        if spec.north:
            continue
        tab, (t, idx) = tables[spec.source], clean[spec.source]
        where = f"{path}, channel '{ch}' from {tab.topic}"
        sub = Table(tab.topic, tab.clock, t, {k: np.asarray(v)[idx] for k, v in tab.values.items()}, tab.components,
                    tab.epoch)
        values[ch] = (t - origin, _channel(spec, sub, cmap.frame, where))
    for ch, spec in cmap.channels.items():
        if not spec.north:
            continue
        if "psi" not in values:
            raise DataError(f"{cmap.path}: channel '{ch}' from earth-frame velocity needs a 'psi' channel in the map.")
        tab, (t, idx) = tables[spec.source], clean[spec.source]
        vn = tab.values[spec.north][idx] * spec.factor
        ve = tab.values[spec.east][idx] * spec.factor
        psi = np.interp(t - origin, values["psi"][0], np.unwrap(values["psi"][1]))
        body = vn * np.cos(psi) + ve * np.sin(psi) if ch == "u" else -vn * np.sin(psi) + ve * np.cos(psi)
        values[ch] = (t - origin, body + spec.offset)
    # gaps of every source, on the shifted clock
    gaps = []
    for s, (t, _) in clean.items():
        step = np.diff(t)
        limit = cmap.max_gap if cmap.max_gap is not None else GAP_FACTOR * float(np.median(step))
        for i in np.flatnonzero(step > limit):
            gaps.append({"source": s, "topic": tables[s].topic, "start": float(t[i] - origin),
                         "end": float(t[i + 1] - origin), "length": float(step[i]), "threshold": float(limit)})
    gaps.sort(key=lambda g: g["start"])
    end = min(float(t[-1]) for t, _ in clean.values()) - origin
    if end <= 0:
        raise DataError(f"{path}: the sources do not overlap in time ({src_meta}); check the clocks.")
    # the grid: dt and alignment from the slowest output source
    outputs = {cmap.channels[c].source for c in cmap.channels if not cmap.channels[c].zoh} or set(clean)
    ref = max(outputs, key=lambda s: float(np.median(np.diff(clean[s][0]))))
    ref_t = clean[ref][0] - origin
    dt = cmap.dt or float(np.median(np.diff(ref_t)))
    pieces, a = [], 0.0
    for g in gaps:
        if g["end"] <= a or g["start"] >= end:
            a = max(a, g["end"])
            continue
        pieces.append((a, g["start"]))
        a = g["end"]
    pieces.append((a, end))
    segments, dropped = [], []
    for lo, hi in pieces:
        first = ref_t[ref_t >= lo - _TOL]
        start = float(first[0]) if first.size and cmap.dt is None else lo
        k = int(np.floor((hi - start) / dt + 1e-9))
        if k + 1 < MIN_SEGMENT:
            dropped.append({"start": lo, "end": hi, "samples": max(k + 1, 0)})
            continue
        segments.append(start + dt * np.arange(k + 1))
    if not segments:
        raise DataError(f"{path}: no piece of at least {MIN_SEGMENT} samples between the gaps "
                        f"({[(round(g['start'], 3), round(g['end'], 3)) for g in gaps]} s); raise max_gap in the map "
                        "only if the gaps are harmless.")
    out = []
    for k, grid in enumerate(segments):
        chans = {}
        for ch, (t, y) in values.items():
            if cmap.channels[ch].zoh:
                i = np.searchsorted(t, grid + _TOL, side="right") - 1
                chans[ch] = y[np.clip(i, 0, None)]
            else:
                yy = np.unwrap(y) if ch in _ANGLES else y
                chans[ch] = np.interp(grid, t, yy)
                if ch in _ANGLES:  # continuous within the piece, starting in (-pi, pi]
                    chans[ch] = chans[ch] - 2 * np.pi * np.round(chans[ch][0] / (2 * np.pi))
        seg_name = name if len(segments) == 1 else f"{name}_{k + 1}"
        meta = {"source": str(path), "map": cmap.path or cmap.name, "frame": cmap.frame, "sources": src_meta,
                "time_origin": origin + next(iter(tables.values())).epoch, "grid_dt": dt, "grid_reference": ref, "gaps": gaps,
                "dropped_pieces": dropped, "segment": {"index": k + 1, "of": len(segments),
                                                       "start": float(grid[0]), "end": float(grid[-1])},
                "holds": {c: ("zoh" if cmap.channels[c].zoh else "linear") for c in values},
                "rudder_sign_in_source": cmap.rudder_sign}
        out.append((seg_name, grid, chans, meta))
    return out
