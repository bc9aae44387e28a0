"""Tests of diffship.data: loading, validation and resampling of measured runs."""

from __future__ import annotations

import pickle

import numpy as np
import pandas as pd
import pytest

from diffship.data import Run, example_path, example_runs, kvlcc2_runs, load_runs, resample_runs, shared_data_dir
from diffship.errors import DataError


def make_df(n: int = 50, dt: float = 0.1) -> pd.DataFrame:
    t = np.arange(n) * dt
    r = 0.02 * np.sin(0.5 * t)
    psi = np.cumsum(r) * dt
    return pd.DataFrame({"time": t, "x0": 1.2 * t, "y0": 0.01 * t, "psi": psi, "u": 1.2 + 0 * t,
                         "v": 0.01 * np.cos(t), "r": r, "delta": 0.3 * np.sign(np.sin(0.3 * t))})


def write(tmp_path, df: pd.DataFrame, name: str = "run.csv", sep: str = ",") -> str:
    path = tmp_path / name
    df.to_csv(path, sep=sep, index=False)
    return path


def raises(match: str, fn, *args, **kw) -> str:
    with pytest.raises(DataError) as info:
        fn(*args, **kw)
    msg = str(info.value)
    for part in match.split("|"):
        assert part in msg, f"{part!r} not in {msg!r}"
    return msg


# --- round trips and immutability -------------------------------------------------------
def test_round_trip_dataframe():
    df = make_df()
    run = Run.from_dataframe(df, "a")
    assert run.n == 50 and run.t0 == 0.0
    assert run.duration == pytest.approx(4.9) and run.dt == pytest.approx(0.1)
    back = run.to_dataframe()
    pd.testing.assert_frame_equal(back, df)
    assert run.has("psi", "r", "time") and not run.has("tau_x")
    assert run.metadata["source"] == "DataFrame" and run.metadata["rudder_sign_in_source"] == "starboard"
    assert "a" in repr(run)
    assert pickle.loads(pickle.dumps(run)).n == run.n


def test_caller_data_untouched_and_arrays_private():
    df = make_df()
    before = df.copy()
    run = Run.from_dataframe(df, rudder_sign="port", degrees=["psi"], check_units=False)
    pd.testing.assert_frame_equal(df, before)
    for c in df.columns:
        assert not np.shares_memory(run[c], df[c].to_numpy())
    t, delta = np.arange(20.0), np.full(20, 0.1)
    t0, d0 = t.copy(), delta.copy()
    run = Run("b", t, {"delta": delta})
    assert not np.shares_memory(run.time, t) and not np.shares_memory(run["delta"], delta)
    assert not run["delta"].flags.writeable and not run.time.flags.writeable
    with pytest.raises(ValueError):
        run["delta"][0] = 1.0
    with pytest.raises(TypeError):
        run.channels["x"] = t  # type: ignore[index]
    np.testing.assert_array_equal(t, t0)
    np.testing.assert_array_equal(delta, d0)
    assert t.flags.writeable and delta.flags.writeable


def test_rudder_flip_for_port():
    df = make_df()
    port = Run.from_dataframe(df, rudder_sign="port")
    np.testing.assert_array_equal(port["delta"], -df["delta"].to_numpy())
    np.testing.assert_array_equal(port["r"], df["r"].to_numpy())
    assert port.metadata["rudder_sign_in_source"] == "port"
    raises("rudder_sign", Run.from_dataframe, df, rudder_sign="left")


def test_degrees_conversion_and_column_mapping():
    df = make_df().rename(columns={"psi": "heading_deg", "delta": "rudder_deg "})
    df["heading_deg"] = np.degrees(df["heading_deg"])
    df["rudder_deg "] = np.degrees(df["rudder_deg "])
    run = Run.from_dataframe(df, columns={"psi": "heading_deg"}, degrees=["psi", "rudder_deg"])
    ref = make_df()
    np.testing.assert_allclose(run["psi"], ref["psi"], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(run["rudder_deg"], ref["delta"], rtol=1e-12)
    assert set(run.metadata["degrees_converted"]) == {"psi", "rudder_deg"}
    raises("'nope'", Run.from_dataframe, df, degrees=["nope"])
    raises("'heading'|available columns", Run.from_dataframe, df, columns={"psi": "heading"})


def test_resample_uniform_grid_and_values():
    t = np.sort(np.concatenate([np.linspace(0, 10, 37), [3.33, 7.77]]))
    psi = 0.5 * t  # goes past pi: stays unwrapped
    psi_wrapped = np.angle(np.exp(1j * psi))
    run = Run("w", t, {"x0": 2.0 * t + 1.0, "psi": psi_wrapped})
    res = run.resample(0.25)
    np.testing.assert_allclose(res.time, np.arange(41) * 0.25)
    np.testing.assert_allclose(res["x0"], 2.0 * res.time + 1.0)
    np.testing.assert_allclose(res["psi"], 0.5 * res.time, atol=1e-12)
    assert res.metadata["resampled_dt"] == 0.25
    assert run.resample(0.3).time[-1] == pytest.approx(9.9)
    raises("dt", run.resample, 0.0)


def test_resample_step_longer_than_a_run_names_the_option_and_the_length():
    runs = [Run("long", np.arange(100) * 0.5, {"psi": np.zeros(100)}), Run("short", np.arange(50) * 0.2,
                                                                            {"psi": np.zeros(50)})]
    msg = raises("--resample 2: run 'short' lasts 9.8 s|leaves 5 sample(s)|at least 10|at most 1.08 s",
                 resample_runs, runs, 2.0)
    assert "'long'" not in msg
    assert [r.n for r in resample_runs(runs, 1.08)] == [46, 10]


def test_time_unit_that_makes_the_log_faster_than_a_ship_log_is_named():
    """Seconds stated as ms (a 10 Hz log read as 10 kHz) and ms stated as µs: one UnitsError with the rate and
    the unit that gives a ship's rate; milliseconds stated as ms load."""
    from diffship.data import UnitsError

    with pytest.raises(UnitsError) as e:
        Run.from_dataframe(make_df(), time_unit="ms")
    assert e.value.time_unit == "s" and "10000 Hz" in str(e.value) and "--time-unit s" in str(e.value), e.value
    ms = make_df().assign(time=lambda d: d["time"] * 1000.0)
    with pytest.raises(UnitsError) as e:
        Run.from_dataframe(ms, time_unit="us")
    assert e.value.time_unit == "ms" and "--time-unit ms" in str(e.value), e.value
    assert Run.from_dataframe(ms, time_unit="ms").dt == pytest.approx(0.1)
    assert Run.from_dataframe(make_df(), time_unit="ms", check_units=False).dt == pytest.approx(1e-4)



def slow_turns(dt: float = 1.0, n: int = 120) -> tuple[pd.DataFrame, pd.DataFrame]:
    """A log sampled every ``dt`` seconds, in seconds: heading with its yaw rate, and track with its surge speed."""
    t = np.arange(n) * dt
    yaw = pd.DataFrame({"time": t, "psi": 0.25 * (1 - np.cos(0.2 * t)), "r": 0.05 * np.sin(0.2 * t)})
    track = pd.DataFrame({"time": t, "x0": 1.5 * t, "y0": 0.3 * t, "u": np.full(n, 1.53)})
    return yaw, track


def test_seconds_stated_as_ms_at_a_ship_log_rate_are_named_by_the_rates():
    """A 1 Hz log in seconds read as ms is a 1000 Hz log, which the rate limit lets pass: the heading's rate
    against r (or the track against u) is then 1000 times too high, named with time_unit='s'; µs stated for ms
    likewise; the same data in the right unit, and a genuine ms log, load."""
    from diffship.data import UnitsError

    for df in slow_turns():
        with pytest.raises(UnitsError) as e:
            Run.from_dataframe(df, time_unit="ms")
        msg = str(e.value)
        assert e.value.time_unit == "s" and "time column looks like seconds" in msg and "--time-unit s" in msg, msg
        assert "1000 times too close" in msg and "time_unit='s'" in msg, msg
        assert Run.from_dataframe(df).dt == pytest.approx(1.0)
        ms = df.assign(time=df["time"] * 1000.0)
        assert Run.from_dataframe(ms, time_unit="ms").dt == pytest.approx(1.0)
        with pytest.raises(UnitsError) as e:
            Run.from_dataframe(ms, time_unit="us")
        assert e.value.time_unit == "ms" and "--time-unit ms" in str(e.value), e.value
        fast = slow_turns(0.1, 400)[0].assign(time=lambda d: d["time"] * 1000.0)
        assert Run.from_dataframe(fast, time_unit="ms").dt == pytest.approx(0.1)


def zigzag(heading_deg: float = 20.0, rudder: float = 0.17) -> pd.DataFrame:
    """A zigzag at 10 Hz: heading swinging ±``heading_deg`` [deg], rudder ±``rudder`` in the file's numbers."""
    t = np.arange(300) * 0.1
    psi = np.radians(heading_deg) * np.sin(2 * np.pi * t / 15)
    return pd.DataFrame({"time": t, "psi": psi, "r": np.gradient(psi, t),
                         "delta": rudder * np.sign(np.sin(2 * np.pi * t / 15))})


def test_rudder_in_radians_declared_degrees_is_named(tmp_path):
    """A rudder in radians declared in degrees is a rudder under 1° while the ship turns through 40°: named, with
    the fix to drop it from --degrees (never to add it, also when several files are joined); a straight run with
    a small rudder and true degrees load."""
    from diffship.data import UnitsError

    with pytest.raises(UnitsError) as e:
        Run.from_dataframe(zigzag(), "zig", degrees=["delta"])
    msg = str(e.value)
    assert e.value.drop_degrees == ("delta",) and not e.value.columns and e.value.time_unit is None, msg
    assert "'zig'" in msg and "'delta'" in msg and "drop delta from --degrees" in msg and "40°" in msg, msg
    assert "0.17°" in msg and "looks like radians" in msg and "\n" not in msg, msg
    with pytest.raises(UnitsError) as e:
        Run.from_dataframe(zigzag().rename(columns={"delta": "delta_n"}), degrees=["delta_n"])
    assert e.value.drop_degrees == ("delta_n",) and "drop delta_n from --degrees" in str(e.value), e.value
    assert Run.from_dataframe(zigzag()).n == 300
    assert Run.from_dataframe(zigzag(3.0, 0.5), degrees=["delta"]).n == 300
    assert np.max(np.abs(Run.from_dataframe(zigzag(20.0, 10.0), degrees=["delta"])["delta"])) == pytest.approx(
        np.radians(10.0))
    a = write(tmp_path, zigzag(), "a.csv")
    b = write(tmp_path, zigzag().assign(time=lambda d: d["time"] * 1000.0), "b.csv")
    with pytest.raises(UnitsError) as e:
        load_runs([a, b], degrees=["delta"])
    msg = str(e.value)
    assert "2 files" in msg and "a.csv" in msg and "b.csv" in msg and "drop delta from --degrees" in msg, msg
    assert "--time-unit ms" in msg and "--degrees delta" not in msg and e.value.drop_degrees == ("delta",), msg

def test_slice_and_with_channels():
    run = Run.from_dataframe(make_df())
    part = run.slice(1.0, 2.0)
    assert part.t0 == pytest.approx(1.0) and part.time[-1] == pytest.approx(2.0) and part.n == 11
    more = run.with_channels(tau_x=np.ones(run.n), delta=np.zeros(run.n))
    assert more.has("tau_x") and np.all(more["delta"] == 0) and np.any(run["delta"] != 0)
    raises("too few samples: 3", run.slice, 1.0, 1.25)
    raises("['tau_z', 'w']|the test|'psi'|--columns tau_z=", run.require, ["psi", "tau_z", "w"], "the test")
    run.require("psi", "nothing")
    raises("no channel 'zz'|'psi'", run.__getitem__, "zz")


# --- bad input -----------------------------------------------------------------------
@pytest.mark.parametrize("change, match", [
    (lambda d: d.iloc[[0, 1, 2, 4, 3, *range(5, 50)]], "time goes backwards at row 4"),
    (lambda d: d.assign(time=np.r_[d.time[:6], d.time[5], d.time[7:]]), "repeated time stamp at row 6"),
    (lambda d: d.assign(psi=np.r_[d.psi[:7], np.nan, d.psi[8:]]), "'psi' has 1 NaN/inf value(s), first at row 7"),
    (lambda d: d.assign(u=np.r_[d.u[:3], np.inf, np.inf, d.u[5:]]), "'u' has 2 NaN/inf value(s), first at row 3"),
    (lambda d: d.assign(v=["0.1"] * 9 + ["abc"] + ["0.2"] * 40), "'v' is not numeric (first bad value 'abc' at row 9)"),
    (lambda d: d.iloc[:9], "too few samples: 9 (need at least 10)"),
    (lambda d: d.assign(delta=np.degrees(d.delta)), "'delta' looks like degrees|--degrees delta"),
    (lambda d: d.assign(psi=np.degrees(d.psi)), "'psi' looks like degrees while 'r'"),
    (lambda d: d.assign(r=np.degrees(d.r)), "'r' looks like deg/s"),
    (lambda d: d.assign(psi=np.degrees(d.psi) + 90.0).drop(columns="r"), "'psi' looks like degrees"),
    (lambda d: d.drop(columns="time"), "no time column 'time'|columns={'time'"),
])
def test_bad_csv_files(tmp_path, change, match):
    path = write(tmp_path, change(make_df()), "bad_run.csv")
    msg = raises(match, Run.from_csv, path)
    assert "bad_run.csv" in msg and "'bad_run'" in msg


def test_bad_files(tmp_path):
    raises("missing.csv|not found", Run.from_csv, tmp_path / "missing.csv")
    (tmp_path / "empty.csv").write_text("")
    raises("empty.csv|empty file", Run.from_csv, tmp_path / "empty.csv")
    (tmp_path / "header.csv").write_text("time,psi\n")
    raises("header.csv|no rows", Run.from_csv, tmp_path / "header.csv")
    (tmp_path / "garbage.csv").write_bytes(bytes(range(256)) * 20)
    raises("garbage.csv|binary", Run.from_csv, tmp_path / "garbage.csv")
    raises("'w'", Run, "w", np.arange(20.0), {"delta": np.zeros(19)})


def test_separators_and_degree_psi_wrapping(tmp_path):
    df = make_df()
    for sep in (";", "\t", " "):
        run = Run.from_csv(write(tmp_path, df, "s.csv", sep=sep))
        np.testing.assert_allclose(run["psi"], df["psi"])
    text = (tmp_path / "s.csv").read_text().replace(" ", ";").replace(".", ",")
    (tmp_path / "comma.csv").write_text(text)
    np.testing.assert_allclose(Run.from_csv(tmp_path / "comma.csv")["x0"], df["x0"])
    # heading in degrees, wrapped to [0, 360), no r: caught by the 360 jump
    t = np.arange(100) * 0.1
    wrapped = pd.DataFrame({"time": t, "psi": np.mod(-10 + 2 * t, 360.0)})
    raises("'psi' looks like degrees", Run.from_dataframe, wrapped)
    # a multi-turn unwrapped turning circle in radians is not a false alarm
    tc = np.arange(400) * 0.1
    circle = pd.DataFrame({"time": tc, "psi": 0.25 * tc, "r": np.full(400, 0.25)})
    assert Run.from_dataframe(circle)["psi"].max() > 2 * np.pi


def test_load_runs_unique_names(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    df = make_df()
    paths = [write(tmp_path / "a", df, "z.csv"), write(tmp_path / "b", df, "z.csv"),
             write(tmp_path, df, "other.csv")]
    assert [r.name for r in load_runs(paths, rudder_sign="port")] == ["z_1", "z_2", "other"]
    raises("no files", load_runs, [])


# --- real data --------------------------------------------------------------------------
def test_bundled_sspa_example():
    assert example_path("sspa_zigzag").is_file()
    (run,) = example_runs("sspa_zigzag")
    assert run.n == 2073 and run.dt == pytest.approx(0.02, rel=1e-6)
    assert run.metadata["rudder_sign_in_source"] == "port" and run.metadata["licence"] == "Apache-2.0"
    delta, r = run["delta"], run["r"]
    lags = [int(s / run.dt) for s in (0.0, 1.0, 2.0, 3.0)]
    corr = [np.corrcoef(delta[: run.n - k], r[k:])[0, 1] for k in lags]
    assert max(corr) > 0.5, corr  # starboard rudder (delta > 0) gives r > 0
    raises("unknown example", example_path, "nope")


def test_kvlcc2_loads_without_false_alarms():
    shared = shared_data_dir()
    if shared is None or not (shared / "kvlcc2_hsva").is_dir():
        pytest.skip("../shared/data/kvlcc2_hsva not found: set DIFFSHIP_SHARED_DATA to run this test")
    runs = kvlcc2_runs(shared / "kvlcc2_hsva")
    assert len(runs) == 13
    for run in runs:
        assert run.has("x0", "y0", "psi", "u", "v", "r", "delta")
        assert run.dt == pytest.approx(0.05, rel=1e-6)
        assert run.metadata["rudder_sign_in_source"] == "port"
    by = {r.metadata["test"]: r for r in runs}
    assert by["Z_10_10_S"].metadata["first_rudder"] == "starboard"
    assert by["Z_20_10_P"].metadata["first_rudder"] == "port"
    assert by["Z_20_10_S"].metadata["rudder_angle_deg"] == 20.0
    s = by["Z_10_10_S"]
    i = int(np.argmax(np.abs(s["delta"]) > 0.1))
    assert s["delta"][i] > 0 and s["r"][i + 100] > 0  # starboard rudder first, starboard turn
    raises("KVLCC2|no HSVA", kvlcc2_runs, shared / "sspa_zigzag")


# --- column names and time gaps ---------------------------------------------------------
def test_repeated_header_name_stops_at_the_raw_header(tmp_path):
    df = make_df()[["time", "delta", "psi", "r", "psi"]]  # pandas would read the copy as 'psi.1'
    msg = raises("dup.csv|run 'dup'|column 'psi' appears 2 times|columns 3 and 5", Run.from_csv,
                 write(tmp_path, df, "dup.csv", sep=";"))
    assert msg.count("\n") == 0
    (tmp_path / "spaced.csv").write_text(write(tmp_path, df, "x.csv").read_text().replace(",psi\n", ", psi \n", 1))
    raises("spaced.csv|column 'psi' appears 2 times", Run.from_csv, tmp_path / "spaced.csv")


@pytest.mark.parametrize("col", ["Psi", "Psi ", "PSI"])
def test_channel_name_in_other_case_is_named_not_skipped(tmp_path, col):
    df = make_df().rename(columns={"psi": col})
    raises("near.csv|run 'near'|column 'Psi'|did you mean 'psi'|--columns psi=Psi".replace("Psi", col.strip()),
           Run.from_csv, write(tmp_path, df, "near.csv"))
    run = Run.from_csv(tmp_path / "near.csv", columns={"psi": col.strip()})  # mapped: read as psi
    np.testing.assert_array_equal(run["psi"], make_df()["psi"])
    raises("DataFrame|did you mean 'psi'", Run.from_dataframe, df)  # the library the same
    raises("column 'Time'|did you mean 'time'", Run.from_dataframe, make_df().rename(columns={"time": "Time"}))


def test_other_names_in_other_case_load_as_before():
    both = Run.from_dataframe(make_df().assign(Psi=0.0))  # 'psi' is there: 'Psi' is a column of its own
    assert both.has("psi", "Psi")
    ship = Run.from_dataframe(make_df().rename(columns={"u": "U"}).assign(N=1.0))  # ship notation: U, N
    assert ship.has("U", "N") and not ship.has("u")


def test_gap_in_time_names_run_time_and_split(tmp_path):
    df = make_df(200).drop(index=range(50, 100))  # 5 s missing at 10 Hz
    msg = raises("gap.csv|run 'gap'|no samples for 5.1 s between t=4.9 s and t=10 s|split the run there",
                 Run.from_csv, write(tmp_path, df, "gap.csv"))
    assert "rows 49 and 50" in msg and msg.count("\n") == 0


def test_jitter_and_short_dropouts_are_not_gaps():
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.7, 1.3, 300))  # a 1 Hz log with jitter and one missed 4 s
    t[150:] += 3.0
    assert Run("sea", t, {"psi": np.zeros(t.size)}).n == 300
    t = np.delete(np.arange(500) * 0.02, range(100, 140))  # 50 Hz, 0.82 s without samples: under 1 s
    assert Run("tank", t, {"psi": np.zeros(t.size)}).n == 460
    raises("run 'sea'|no samples for 6", Run, "sea", np.r_[np.arange(20.0), 25.0 + np.arange(20.0)], {})


# --- what a run is built from ------------------------------------------------------------
def test_run_arguments_of_the_wrong_kind_stop_with_what_to_pass():
    t, r = np.arange(50) * 0.1, np.zeros(50)
    raises("run 'a'|column 'r' holds complex numbers|np.real", Run, "a", t, {"r": r + 1j})
    raises("channels must be a mapping|got list", Run, "a", t, [r, r])
    raises("channels must be a mapping|got NoneType", Run, "a", t, None)
    raises("metadata must be a mapping|got list", Run, "a", t, {"r": r}, metadata=[1, 2])
    raises("needs a pandas DataFrame|got dict|pd.DataFrame(data)", Run.from_dataframe, {"time": t, "r": r})
    raises("needs a pandas DataFrame|got ndarray", Run.from_dataframe, np.c_[t, r])
    assert Run("a", t, pd.DataFrame({"r": r})).channel_names == ("r",)


def test_timedelta_time_column_is_read_as_its_seconds():
    df = pd.DataFrame({"time": pd.to_timedelta(5.0 + np.arange(100) * 0.1, unit="s"), "r": np.zeros(100)})
    before = df.copy()
    run = Run.from_dataframe(df)
    np.testing.assert_allclose(run.time, 5.0 + np.arange(100) * 0.1)
    pd.testing.assert_frame_equal(df, before)
    raises("holds timedeltas|time_unit='ms' does not apply", Run.from_dataframe, df, time_unit="ms")
