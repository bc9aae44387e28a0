"""Small log writers for the tests: ROS 2 bags with rosbags' own writer (sqlite3 and MCAP storage), and
ArduPilot DataFlash (.BIN) and PX4 ULog (.ulg) files from their documented binary records.

DataFlash: every record is ``0xA3 0x95 <type id>`` + payload; FMT records (type 128: type, length,
name[4], format[16], columns[64]) define the others (ArduPilot "LogStructure.h", format chars Q uint64,
f float32). ULog (docs.px4.io "ULog File Format"): a 16-byte header (magic ``ULog\\x01\\x12\\x35``, version,
uint64 start time), then messages ``uint16 size, uint8 type, payload``: ``B`` flag bits, ``F`` formats
``name:type field;...``, ``A`` add-logged (multi id, msg id, name), ``D`` data (msg id, packed fields).
"""

from __future__ import annotations

import struct

import numpy as np

EPOCH = 1_700_000_000.0  # [s] a plausible ROS time for header stamps


def ros_odom_wrench_bag(path, run, storage="sqlite3", wrench_factor=5, gaps=(), latency=0.003):
    """A ROS 2 bag from a diffship run (NED/FRD): /odom Odometry (ENU/FLU) at the run's rate, /wrench
    WrenchStamped (FLU) at ``wrench_factor`` times the rate (inputs linearly interpolated). Samples with
    time in a ``gaps`` interval are left out of both topics. Receive times = stamps + ``latency`` [s]."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    M = ts.types
    Header, Time = M["std_msgs/msg/Header"], M["builtin_interfaces/msg/Time"]
    V3, Q, P = M["geometry_msgs/msg/Vector3"], M["geometry_msgs/msg/Quaternion"], M["geometry_msgs/msg/Point"]
    Pose, PwC = M["geometry_msgs/msg/Pose"], M["geometry_msgs/msg/PoseWithCovariance"]
    Tw, TwC = M["geometry_msgs/msg/Twist"], M["geometry_msgs/msg/TwistWithCovariance"]
    Odom, Wr, WrS = M["nav_msgs/msg/Odometry"], M["geometry_msgs/msg/Wrench"], M["geometry_msgs/msg/WrenchStamped"]

    def header(t, frame):
        ns = int(round((EPOCH + t) * 1e9))
        return Header(stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=frame), ns

    def in_gap(t):
        return any(a < t < b for a, b in gaps)

    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    t = run.time
    with Writer(path, version=9, storage_plugin=plugin) as w:
        co = w.add_connection("/odom", Odom.__msgtype__, typestore=ts)
        cw = w.add_connection("/wrench", WrS.__msgtype__, typestore=ts)
        cov = np.zeros(36)
        msgs = []
        for k, tk in enumerate(t):
            if in_gap(tk):
                continue
            yaw = np.pi / 2 - run["psi"][k]
            h, ns = header(tk, "odom")
            m = Odom(header=h, child_frame_id="base_link",
                     pose=PwC(pose=Pose(position=P(x=run["y0"][k], y=run["x0"][k], z=0.0),
                                        orientation=Q(x=0.0, y=0.0, z=np.sin(yaw / 2), w=np.cos(yaw / 2))),
                              covariance=cov),
                     twist=TwC(twist=Tw(linear=V3(x=run["u"][k], y=-run["v"][k], z=0.0),
                                        angular=V3(x=0.0, y=0.0, z=-run["r"][k])), covariance=cov))
            msgs.append((ns + int(latency * 1e9), co, ts.serialize_cdr(m, Odom.__msgtype__)))
        tw = np.arange(t[0], t[-1] + 1e-9, (t[1] - t[0]) / wrench_factor)
        for tk in tw:
            if in_gap(tk):
                continue
            f = {c: float(np.interp(tk, t, run[c])) for c in ("tau_x", "tau_y", "tau_z")}
            h, ns = header(tk, "base_link")
            m = WrS(header=h, wrench=Wr(force=V3(x=f["tau_x"], y=-f["tau_y"], z=0.0),
                                        torque=V3(x=0.0, y=0.0, z=-f["tau_z"])))
            msgs.append((ns + int(latency * 1e9), cw, ts.serialize_cdr(m, WrS.__msgtype__)))
        for ns, c, raw in sorted(msgs, key=lambda x: x[0]):
            w.write(c, ns, raw)
    return path


def _fmt_record(type_id, name, fmt, columns):
    length = 3 + struct.calcsize("<" + fmt.replace("n", "4s").replace("N", "16s").replace("Z", "64s"))
    return bytes([0xA3, 0x95, 128]) + struct.pack("<BB4s16s64s", type_id, length, name.encode(),
                                                  fmt.encode(), columns.encode())


def dataflash(path, messages):
    """A DataFlash .BIN: ``messages`` = {name: (type id, format, columns, rows)} with float/uint64 fields."""
    out = bytearray(_fmt_record(128, "FMT", "BBnNZ", "Type,Length,Name,Format,Columns"))
    recs = []
    for name, (tid, fmt, cols, rows) in messages.items():
        out += _fmt_record(tid, name, fmt, cols)
        for row in rows:
            recs.append((row[0], bytes([0xA3, 0x95, tid]) + struct.pack("<" + fmt, *row)))
    for _, r in sorted(recs, key=lambda x: x[0]):
        out += r
    path.write_bytes(bytes(out))
    return path


def ulog(path, topics):
    """A ULog: ``topics`` = {name: (fields [(type, name)], rows)}; the first field is uint64_t timestamp."""
    def msg(kind, payload):
        return struct.pack("<HB", len(payload), ord(kind)) + payload

    codes = {"uint64_t": "Q", "float": "f", "double": "d", "int32_t": "i", "uint8_t": "B"}
    out = bytearray(b"ULog\x01\x12\x35" + bytes([1]) + struct.pack("<Q", 0))
    out += msg("B", bytes(16) + struct.pack("<3Q", 0, 0, 0))
    for name, (fields, _) in topics.items():
        out += msg("F", f"{name}:{''.join(f'{t} {n};' for t, n in fields)}".encode())
    recs = []
    for i, (name, (fields, rows)) in enumerate(topics.items()):
        out += msg("A", struct.pack("<BH", 0, i) + name.encode())
        fmt = "<" + "".join(codes[t.split("[")[0]] * (int(t.split("[")[1][:-1]) if "[" in t else 1) for t, _ in fields)
        for row in rows:
            recs.append((row[0], msg("D", struct.pack("<H", i) + struct.pack(fmt, *row))))
    for _, r in sorted(recs, key=lambda x: x[0]):
        out += r
    path.write_bytes(bytes(out))
    return path
