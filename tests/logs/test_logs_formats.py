"""ArduPilot DataFlash .BIN, PX4 ULog .ulg and parquet as runs with the bundled maps.

The .BIN and .ulg files are written from the formats' documented binary records (tests/logs/logwriters.py)
and read back by pymavlink and pyulog through diffship's readers."""

from __future__ import annotations

import logwriters as lw
import numpy as np
import pytest

from diffship.data import load_runs
from diffship.errors import DataError

T = np.arange(0.0, 20.0 + 1e-9, 0.1)  # [s]
PSI = np.deg2rad(350.0) + 0.05 * T  # crosses north (360 deg) at t = 3.5 s
U, V = 2.0 + 0.02 * T, 0.3 * np.sin(0.5 * T)  # body velocities [m/s]
VN, VE = U * np.cos(PSI) - V * np.sin(PSI), U * np.sin(PSI) + V * np.cos(PSI)  # earth (NED) velocity


def _bin(path, drop=()):
    keep = [i for i, t in enumerate(T) if not any(a < t < b for a, b in drop)]
    us = [int(round(T[i] * 1e6)) + 5_000_000 for i in keep]  # boot time, the log starts 5 s after boot
    return lw.dataflash(path, {
        "XKF1": (150, "Qffffff", "TimeUS,PN,PE,PD,VN,VE,VD",
                 [(us[j], 10 * T[i], -3 * T[i], 1.0, VN[i], VE[i], 0.0) for j, i in enumerate(keep)]),
        "ATT": (151, "Qfff", "TimeUS,Roll,Pitch,Yaw",
                [(us[j], 1.0, -2.0, float(np.rad2deg(PSI[i]) % 360.0)) for j, i in enumerate(keep)]),
        "IMU": (152, "Qfff", "TimeUS,GyrX,GyrY,GyrZ", [(us[j], 0.0, 0.0, 0.05) for j, i in enumerate(keep)]),
        "RCOU": (153, "QHHHHHH", "TimeUS,C1,C2,C3,C4,C5,C6",
                 [(us[j], 1500 + j % 7, 1500, 1500, 1500, 1600, 1400) for j, i in enumerate(keep)]),
    })


def test_ardupilot_bin_with_the_ardusub_map(tmp_path):
    pytest.importorskip("pymavlink", reason="ArduPilot logs need the 'logs' extra: pip install 'diffship[logs]'")
    (run,) = load_runs([_bin(tmp_path / "dive.BIN")], channel_map="ardusub")
    assert run.n == T.size and np.allclose(run.time, T, atol=1e-9)
    assert np.allclose(run["psi"], PSI - 2 * np.pi, atol=1e-6)  # 350 deg -> -10 deg, continuous through north
    assert np.allclose(run["phi"], np.deg2rad(1.0), atol=1e-7) and np.allclose(run["theta"], np.deg2rad(-2.0), atol=1e-7)
    assert np.allclose(run["u"], U, atol=1e-5) and np.allclose(run["v"], V, atol=1e-5)  # NED velocity into the body
    assert np.allclose(run["x0"], 10 * T, atol=1e-4) and np.allclose(run["r"], 0.05)
    assert run["pwm_5"][0] == 1600 and run.metadata["holds"]["pwm_1"] == "zoh"
    assert run.metadata["sources"]["att"]["clock"] == "TimeUS (vehicle boot time)"
    assert run.metadata["time_origin"] == pytest.approx(5.0)


def test_ardupilot_bin_gap_splits(tmp_path):
    pytest.importorskip("pymavlink", reason="ArduPilot logs need the 'logs' extra: pip install 'diffship[logs]'")
    with pytest.warns(UserWarning, match="split into run"):
        runs = load_runs([_bin(tmp_path / "dive.BIN", drop=[(8.05, 11.0)])], channel_map="ardusub")
    assert [r.name for r in runs] == ["dive_1", "dive_2"]
    assert runs[0].time[-1] == pytest.approx(8.0) and runs[1].t0 == pytest.approx(11.0)


def test_px4_ulog_with_the_px4_map(tmp_path):
    pytest.importorskip("pyulog", reason="PX4 logs need the 'logs' extra: pip install 'diffship[logs]'")
    us = (T * 1e6).astype(np.int64) + 1_000_000
    us_rates = (np.arange(0.0, 20.0 + 1e-9, 0.02) * 1e6).astype(np.int64) + 1_000_000  # 50 Hz gyro
    q = np.stack([np.cos(PSI / 2), 0 * T, 0 * T, np.sin(PSI / 2)], axis=1)  # yaw about NED z: w, x, y, z
    path = lw.ulog(tmp_path / "boat.ulg", {
        "vehicle_local_position": ([("uint64_t", "timestamp"), ("float", "x"), ("float", "y"), ("float", "vx"),
                                    ("float", "vy")],
                                   [(int(us[i]), 10 * T[i], -3 * T[i], VN[i], VE[i]) for i in range(T.size)]),
        "vehicle_attitude": ([("uint64_t", "timestamp"), ("float[4]", "q")],
                             [(int(us[i]), *q[i]) for i in range(T.size)]),
        "vehicle_angular_velocity": ([("uint64_t", "timestamp"), ("float[3]", "xyz")],
                                     [(int(t), 0.0, 0.0, 0.05) for t in us_rates]),
    })
    (run,) = load_runs([path], channel_map="px4")
    assert run.n == T.size and run.metadata["grid_dt"] == pytest.approx(0.1)  # the slowest output source
    assert np.allclose(run["psi"], PSI - 2 * np.pi, atol=1e-6)
    assert np.allclose(run["u"], U, atol=1e-5) and np.allclose(run["v"], V, atol=1e-5)
    assert np.allclose(run["phi"], 0.0, atol=1e-6) and np.allclose(run["r"], 0.05)
    assert run.metadata["sources"]["rates"]["rate_hz"] == pytest.approx(50.0)


def test_parquet_with_and_without_a_map(tmp_path):
    pa = pytest.importorskip("pyarrow", reason="parquet needs the 'logs' extra: pip install 'diffship[logs]'")
    import pyarrow.parquet as pq

    table = pa.table({"time": T, "psi": PSI - 2 * np.pi, "u": U, "v": V, "heading_deg": np.rad2deg(PSI)})
    pq.write_table(table, tmp_path / "a.parquet")
    (plain,) = load_runs([tmp_path / "a.parquet"], columns={"psi_deg": "heading_deg"}, degrees=["psi_deg"])
    assert np.allclose(plain["u"], U) and np.allclose(plain["psi_deg"], PSI)
    cmap = tmp_path / "m.toml"
    cmap.write_text('[sources.t]\ntopic = "table"\n[channels]\npsi = { source = "t", field = "heading_deg", '
                    'unit = "deg" }\nu = { source = "t", field = "u" }\n')
    (mapped,) = load_runs([tmp_path / "a.parquet"], channel_map=cmap)
    assert np.allclose(mapped["psi"], PSI - 2 * np.pi) and mapped.channel_names == ("psi", "u")
    with pytest.raises(DataError, match="do not apply to logs"):
        load_runs([tmp_path / "a.parquet"], channel_map=cmap, columns={"u": "v"})


def test_mavlink_tlog_with_the_tlog_map(tmp_path):
    """A .tlog (8-byte big-endian receive time [us] + a MAVLink packet, pymavlink's encoder): the vehicle's
    boot clock is used, not the ground station's receive time (which lags by a jittery radio latency)."""
    pytest.importorskip("pymavlink", reason="MAVLink logs need the 'logs' extra: pip install 'diffship[logs]'")
    import struct

    from pymavlink.dialects.v10 import ardupilotmega as mavlink

    mav = mavlink.MAVLink(None, srcSystem=1)
    rng = np.random.default_rng(0)
    out = bytearray()
    for i, t in enumerate(T):
        boot_ms = int(round(t * 1000)) + 60_000
        recv_us = int((1.7e9 + t + 0.2 + rng.uniform(0, 0.05)) * 1e6)  # radio latency 0.2-0.25 s
        wrapped = float(np.arctan2(np.sin(PSI[i]), np.cos(PSI[i])))  # MAVLink yaw is in (-pi, pi]
        for msg in (mavlink.MAVLink_attitude_message(boot_ms, 0.01, -0.02, wrapped, 0.0, 0.0, 0.05),
                    mavlink.MAVLink_local_position_ned_message(boot_ms, 10 * t, -3 * t, 0.0, VN[i], VE[i], 0.0)):
            out += struct.pack(">Q", recv_us) + msg.pack(mav)
    (tmp_path / "boat.tlog").write_bytes(bytes(out))
    (run,) = load_runs([tmp_path / "boat.tlog"], channel_map="mavlink_tlog")
    assert run.n == T.size and run.dt == pytest.approx(0.1)  # boot clock: exactly 10 Hz despite the jitter
    assert np.allclose(run["psi"], PSI - 2 * np.pi, atol=1e-6)  # unwrapped through north
    assert np.allclose(run["u"], U, atol=1e-5) and np.allclose(run["v"], V, atol=1e-5)
    assert run.metadata["sources"]["att"]["clock"] == "time_boot_ms (vehicle boot time)"
    assert run.metadata["time_origin"] == pytest.approx(60.0)
