"""ROS 2 bags (sqlite3 and MCAP, written by rosbags' own writer) as runs: round trips, REP-103 frames,
clocks, zero-order hold of inputs, gaps split and reported, and the fit through ``--map``."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

pytest.importorskip("rosbags", reason="ROS 2 bag tests need the 'logs' extra: pip install 'diffship[logs]'")

import logwriters as lw

from diffship.data import load_runs
from diffship.errors import DataError
from diffship.synthetic import usv_runs


@pytest.fixture(scope="module")
def usv_run():
    return usv_runs(1, duration=30.0, dt=0.1, seed=2)[0]  # the seed-002 USV, realistic noise


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_bag_round_trip_is_the_csv_run(tmp_path, usv_run, storage):
    bag = lw.ros_odom_wrench_bag(tmp_path / "bag", usv_run, storage=storage)
    (run,) = load_runs([bag], channel_map="ros2_usv")
    assert run.n == usv_run.n and np.allclose(run.time, usv_run.time - usv_run.t0, atol=1e-9)
    for c in ("x0", "y0", "psi", "u", "v", "r"):  # ENU/FLU -> NED/FRD undone exactly
        assert np.allclose(run[c], usv_run[c], atol=1e-9), c
    for c in ("tau_x", "tau_y", "tau_z"):  # 50 Hz wrench held onto the 10 Hz odometry grid
        assert np.allclose(run[c], usv_run[c], rtol=1e-9, atol=1e-6), c
    src = run.metadata["sources"]
    assert src["odom"]["rate_hz"] == pytest.approx(10.0) and src["wrench"]["rate_hz"] == pytest.approx(50.0)
    assert src["odom"]["clock"].startswith("header") and run.metadata["holds"]["tau_x"] == "zoh"
    assert run.metadata["holds"]["u"] == "linear" and run.metadata["gaps"] == []


def test_ros_frame_signs_by_hand(tmp_path, usv_run):
    """A vessel heading east (ROS yaw 0) has psi = +90 deg; ROS +y (left) velocity is -v; ROS +z rate is -r."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    M = ts.types
    V3 = M["geometry_msgs/msg/Vector3"]
    odom_t, wr_t = M["nav_msgs/msg/Odometry"], M["geometry_msgs/msg/WrenchStamped"]
    yaw = np.deg2rad(30.0)  # 30 deg counter-clockwise from east = 60 deg clockwise from north
    with Writer(tmp_path / "b", version=9) as w:
        co = w.add_connection("/odom", odom_t.__msgtype__, typestore=ts)
        cw = w.add_connection("/wrench", wr_t.__msgtype__, typestore=ts)
        for k in range(20):
            stamp = M["builtin_interfaces/msg/Time"](sec=100 + k // 10, nanosec=(k % 10) * 100_000_000)
            h = M["std_msgs/msg/Header"](stamp=stamp, frame_id="odom")
            pose = M["geometry_msgs/msg/Pose"](position=M["geometry_msgs/msg/Point"](x=1.0 * k, y=2.0, z=0.0),
                                               orientation=M["geometry_msgs/msg/Quaternion"](
                                                   x=0.0, y=0.0, z=np.sin(yaw / 2), w=np.cos(yaw / 2)))
            tw = M["geometry_msgs/msg/Twist"](linear=V3(x=1.5, y=0.2, z=0.0), angular=V3(x=0.0, y=0.0, z=0.05))
            m = odom_t(header=h, child_frame_id="base_link",
                       pose=M["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
                       twist=M["geometry_msgs/msg/TwistWithCovariance"](twist=tw, covariance=np.zeros(36)))
            ns = (100 + k / 10) * 1e9
            w.write(co, int(ns), ts.serialize_cdr(m, odom_t.__msgtype__))
            wm = wr_t(header=h, wrench=M["geometry_msgs/msg/Wrench"](force=V3(x=100.0, y=10.0, z=0.0),
                                                                    torque=V3(x=0.0, y=0.0, z=-40.0)))
            w.write(cw, int(ns), ts.serialize_cdr(wm, wr_t.__msgtype__))
    (run,) = load_runs([tmp_path / "b"], channel_map="ros2_usv", check_units=False)
    assert np.allclose(run["psi"], np.deg2rad(60.0))
    assert np.allclose(run["x0"], 2.0) and np.allclose(run["y0"], np.arange(20.0))  # north = ENU y, east = ENU x
    assert np.allclose(run["u"], 1.5) and np.allclose(run["v"], -0.2) and np.allclose(run["r"], -0.05)
    assert np.allclose(run["tau_x"], 100.0) and np.allclose(run["tau_y"], -10.0) and np.allclose(run["tau_z"], 40.0)


def test_clocks_header_and_receive_time_are_stated(tmp_path, usv_run):
    """The receive clock lags the header stamps by the transport latency; the map chooses, the metadata says."""
    bag = lw.ros_odom_wrench_bag(tmp_path / "bag", usv_run, latency=0.05)
    cmap = tmp_path / "log_clock.toml"
    from diffship.logs.channelmap import MAPS_DIR

    cmap.write_text((MAPS_DIR / "ros2_usv.toml").read_text().replace('clock = "header"', 'clock = "log"'))
    (a,) = load_runs([bag], channel_map="ros2_usv")
    (b,) = load_runs([bag], channel_map=cmap)
    assert a.metadata["sources"]["odom"]["clock"].startswith("header")
    assert b.metadata["sources"]["odom"]["clock"] == "log (bag receive time)"
    assert b.metadata["time_origin"] - a.metadata["time_origin"] == pytest.approx(0.05, abs=1e-6)
    assert np.allclose(a["u"], b["u"], atol=1e-9)  # both topics lag alike: same samples


def test_gap_splits_the_run_and_is_reported(tmp_path, usv_run):
    bag = lw.ros_odom_wrench_bag(tmp_path / "bag", usv_run, gaps=[(12.05, 14.5)])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        runs = load_runs([bag], channel_map="ros2_usv")
    assert [r.name for r in runs] == ["bag_1", "bag_2"]
    assert runs[0].time[-1] == pytest.approx(12.0) and runs[1].t0 == pytest.approx(14.5)
    assert not np.any((runs[1].time > 12.0) & (runs[1].time < 14.5))  # nothing filled in the gap
    msg = " ".join(str(w.message) for w in caught)
    assert "gap" in msg and "bag_1, bag_2" in msg and "not filled" in msg
    gaps = runs[0].metadata["gaps"]
    assert {g["topic"] for g in gaps} == {"/odom", "/wrench"} and runs[1].metadata["segment"]["index"] == 2
    assert gaps[0]["length"] == pytest.approx(2.5, abs=0.05)


def test_map_errors_are_one_line(tmp_path, usv_run):
    bag = lw.ros_odom_wrench_bag(tmp_path / "bag", usv_run)
    with pytest.raises(DataError, match="needs a channel map"):
        load_runs([bag])
    bad = tmp_path / "bad.toml"
    bad.write_text('frame = "ros"\n[sources.o]\ntopic = "/odom"\n[channels]\nu = { source = "o", '
                   'field = "twist.twist.linear", unit = "knots" }\n')
    with pytest.raises(DataError, match="unknown unit 'knots'"):
        load_runs([bag], channel_map=bad)
    bad.write_text('frame = "ros"\n[sources.o]\ntopic = "/odometry"\n[channels]\nu = { source = "o", '
                   'field = "twist.twist.linear" }\n')
    with pytest.raises(DataError, match="no topic '/odometry'.*'/odom'"):
        load_runs([bag], channel_map=bad)
    bad.write_text('frame = "ros"\n[sources.o]\ntopic = "/odom"\n[channels]\nv = { source = "o", '
                   'field = "twist.twist.linear.y" }\n')  # a scalar in ROS axes: the sign slip this refuses
    with pytest.raises(DataError, match="name the vector"):
        load_runs([bag], channel_map=bad)
    with pytest.raises(DataError, match="no such file and no bundled map"):
        load_runs([bag], channel_map="nope")


def test_missing_extra_names_it(tmp_path, usv_run, monkeypatch):
    import sys

    bag = lw.ros_odom_wrench_bag(tmp_path / "bag", usv_run)
    monkeypatch.setitem(sys.modules, "rosbags.highlevel", None)  # as if the extra were not installed
    with pytest.raises(DataError, match=r"pip install 'diffship\[logs\]'"):
        load_runs([bag], channel_map="ros2_usv")


def _fit_json(argv, tmp_path, tag):
    from diffship.fit.cli import main

    out = tmp_path / f"{tag}.json"
    assert main([*argv, "--model", "fossen3", "--vessel", "usv", "--method", "output-error", "--quiet",
                 "--json", str(out)]) == 0
    return json.loads(out.read_text())["methods"]["output_error"]


@pytest.mark.slow
def test_fit_through_map_matches_the_csv(tmp_path):
    """python -m diffship.fit BAG --map ros2_usv --model fossen3: the CSV's estimates within their standard errors."""
    runs = usv_runs(2, duration=90.0, dt=0.1, seed=2)
    csvs, bags = [], []
    for r, storage in zip(runs, ("sqlite3", "mcap")):
        r.to_dataframe().to_csv(tmp_path / f"{r.name}.csv", index=False)
        csvs.append(str(tmp_path / f"{r.name}.csv"))
        bags.append(str(lw.ros_odom_wrench_bag(tmp_path / f"{r.name}_bag", r, storage=storage)))
    a = _fit_json(csvs, tmp_path, "csv")
    b = _fit_json([*bags, "--map", "ros2_usv", "--html", str(tmp_path / "fit.html"), "--save",
                   str(tmp_path / "fit.json")], tmp_path, "bag")
    data = json.loads((tmp_path / "fit.json").read_text())["data"]  # the fit file says where each run came from
    assert data[1]["log"]["sources"]["wrench"]["rate_hz"] == pytest.approx(50.0) and data[1]["log"]["gaps"] == []
    assert a["converged"] and b["converged"] and a["free"] == b["free"]
    for n in a["free"]:
        assert abs(a["params"][n] - b["params"][n]) < 0.1 * a["stderr"][n], n
    import base64
    import re

    imgs = re.findall(r'<img alt="[^"]*" src="data:image/png;base64,([^"]+)"', (tmp_path / "fit.html").read_text())
    assert len(imgs) == 1 and base64.b64decode(imgs[0])[:4] == b"\x89PNG"  # the fit figure, embedded
