"""Fleet mode on Dask distributed: manifest checks, grouping, per-vessel failure isolation,
rerun skips what is done, one results table, every fit's verdict in its row, fit file and the summary,
a killed worker loses only its own fits (slow)."""

from __future__ import annotations

import json
import os
import signal
from pathlib import Path

import pytest

pytest.importorskip("distributed", reason="fleet mode needs the 'fleet' extra: pip install 'diffship[fleet]'")
pytest.importorskip("pyarrow", reason="the fleet's results table is parquet: pip install 'diffship[fleet]'")

import pandas as pd

from diffship.errors import DataError
from diffship.fleet import read_manifest
from diffship.fleet.__main__ import main
from diffship.fleet.engine import group_jobs, run_fleet
from diffship.fleet.worker import fit_group


def _fleet(tmp_path, n, bad=(), duration=30.0):
    from diffship.synthetic import usv_runs

    lines = ["vessel,run,runs,model,vessel_file"]
    for i in range(n):
        (r,) = usv_runs(1, duration=duration, dt=0.1, seed=200 + i)
        r.to_dataframe().to_csv(tmp_path / f"v{i}.csv", index=False)
        model = "nomoto1" if i in bad else "fossen3"  # nomoto1 needs a rudder these runs lack: its own failure
        lines.append(f"boat{i},d1,v{i}.csv,{model},{'' if i in bad else 'usv'}")
    (tmp_path / "fleet.csv").write_text("\n".join(lines) + "\n")
    return tmp_path / "fleet.csv"


def test_manifest_errors_name_the_row(tmp_path):
    m = tmp_path / "m.csv"
    m.write_text("vessel,runs\nb,x.csv\n")
    with pytest.raises(DataError, match="lacks column.*model"):
        read_manifest(m)
    m.write_text("vessel,runs,model\nb,missing.csv,fossen3\n")
    with pytest.raises(DataError, match="row 2: run file .*missing.csv not found"):
        read_manifest(m)
    (tmp_path / "a.csv").write_text("time\n0\n")
    m.write_text("vessel,runs,model\nb,a.csv,fossen3\nb,a.csv,fossen3\n")
    with pytest.raises(DataError, match="row 3: vessel-run b__a appears twice"):
        read_manifest(m)


def test_grouping_by_model_and_batch(tmp_path):
    (tmp_path / "a.csv").write_text("time\n" + "\n".join(map(str, range(50))))
    rows = "\n".join(f"b{i},r,a.csv,{'fossen3' if i < 5 else 'nomoto1'}" for i in range(8))
    m = tmp_path / "m.csv"
    m.write_text("vessel,run,runs,model\n" + rows + "\n")
    groups = group_jobs(read_manifest(m), batch=2)
    assert sorted(len(g) for g in groups) == [1, 1, 2, 2, 2]
    assert all(len({j.model for j in g}) == 1 for g in groups)


def test_failures_are_isolated_and_a_rerun_skips_what_is_done(tmp_path, capsys):
    """Vessel-runs that fail (a model their data cannot drive) are rows with their error; the others are
    not touched; a rerun retries only what is not done. (Failing fits stop before any compilation.)"""
    manifest = _fleet(tmp_path, 3, bad=(0, 1, 2), duration=3.0)
    out = tmp_path / "out"
    done_row = {"key": "boat9__d1", "status": "ok", "fit_file": str(manifest)}  # a vessel-run done earlier
    (out / "rows").mkdir(parents=True)
    (out / "rows" / "boat9__d1.json").write_text(json.dumps(done_row))
    assert main([str(manifest), "--out", str(out), "--workers", "1", "--batch", "2"]) == 1
    said = capsys.readouterr().out
    assert "0 fitted, 3 failed, 0 skipped" in said
    assert "3 FAILED (3 without a fit)" in said and "NOT USABLE: boat0__d1 (no fit: DataError" in said
    df = pd.read_parquet(out / "results.parquet").set_index("key")
    assert set(df.index) == {"boat0__d1", "boat1__d1", "boat2__d1", "boat9__d1"}
    assert (df.loc[["boat0__d1", "boat1__d1", "boat2__d1"], "status"] == "failed").all()
    assert df.loc["boat0__d1", "error"].startswith("DataError") and "delta" in df.loc["boat0__d1", "error"]
    assert (df.loc["boat0__d1", "verdict"], bool(df.loc["boat0__d1", "usable"])) == ("FAILED", False)
    assert json.loads(Path(df.loc["boat0__d1", "fit_file"]).read_text())["error"].startswith("DataError")
    assert df.loc["boat9__d1", "status"] == "ok"  # untouched


def test_every_fit_carries_its_verdict_in_the_table_the_fit_file_and_the_summary(tmp_path, capsys):
    """Two tiny Nomoto vessel-runs: a zigzag (usable) and a run whose rudder never moves (nothing excites K, T1
    or delta0: FAILED). The worker's group runs in this process (no cluster: seconds); the command then finds
    both fitted and reports from their rows: the verdict counts, the vessel-run that is not usable by name, and
    exit status 1 (one vessel-run without a usable fit)."""
    import numpy as np

    from diffship.fitfile import fit_warnings, load_fit
    from diffship.models import get_model
    from diffship.synthetic import nomoto_runs, simulate_run

    (zigzag,) = nomoto_runs(n_runs=1, duration=20.0, dt=0.2, seed=1)
    zigzag.to_dataframe().to_csv(tmp_path / "zigzag.csv", index=False)
    t = np.arange(0.0, 20.0 + 1e-9, 0.2)
    model = get_model("nomoto1")
    flat = simulate_run(model, t, {"delta": np.zeros_like(t)}, np.zeros(len(model.state_names)), name="flat",
                        noise="realistic", seed=3)
    flat.to_dataframe().to_csv(tmp_path / "flat.csv", index=False)
    manifest = tmp_path / "fleet.csv"
    manifest.write_text("vessel,run,runs,model\ngood,r,zigzag.csv,nomoto1\nquiet,r,flat.csv,nomoto1\n")
    out = tmp_path / "out"
    rows = {r["key"]: r for r in fit_group(read_manifest(manifest), str(out))}
    assert rows["good__r"]["status"] == "ok" and rows["quiet__r"]["status"] == "not usable"

    assert main([str(manifest), "--out", str(out), "--quiet"]) == 1  # both fitted before: skipped, no cluster
    said = capsys.readouterr().out
    assert "0 fitted, 0 failed, 2 skipped" in said
    assert "verdicts: 1 usable, 1 FAILED, 0 not converged, 0 unidentifiable; 1 of 2 vessel-runs NOT USABLE" in said
    assert "NOT USABLE: quiet__r (FAILED: " in said and "good__r" not in said
    df = pd.read_parquet(out / "results.parquet").set_index("key")
    good, quiet = df.loc["good__r"], df.loc["quiet__r"]
    assert (good["verdict"], bool(good["usable"]), good["unidentified"], good["on_bound"]) == ("usable", True, "", "")
    assert (quiet["verdict"], bool(quiet["usable"]), quiet["status"]) == ("FAILED", False, "not usable")
    assert set(quiet["unidentified"].split(",")) == {"K", "T1", "delta0"} and quiet["reason"]
    assert df[~df["usable"]].index.tolist() == ["quiet__r"]  # a program filters on the boolean column
    for key, usable in (("good__r", True), ("quiet__r", False)):
        doc = json.loads(Path(df.loc[key, "fit_file"]).read_text())
        assert doc["usable"] is usable and doc["verdict"]["usable"] is usable
        assert doc["metrics"]["train"]["fit_percent"]
    assert fit_warnings(load_fit(df.loc["quiet__r", "fit_file"]))[0].startswith("WARNING: this fit is labelled FAILED")
    assert fit_warnings(load_fit(df.loc["good__r", "fit_file"])) == []


@pytest.mark.slow
def test_killed_worker_loses_only_its_own_fits_and_the_rerun_completes(tmp_path):
    manifest = _fleet(tmp_path, 8, bad=(5,))
    out = tmp_path / "out"
    killed = []

    def kill_one(client, rows):
        if not killed:  # after the first finished task, kill a worker that is busy with another
            pids = client.run(os.getpid)
            victim = next(p for p in pids.values() if p not in {r.get("worker_pid") for r in rows})
            killed.append(victim)
            os.kill(victim, signal.SIGKILL)

    s = run_fleet(manifest, out, workers=2, batch=2, retries=0, progress=False, on_result=kill_one)
    df = pd.read_parquet(out / "results.parquet").set_index("key")
    lost = df[df["error"].fillna("").str.startswith("worker lost")]
    assert killed and 1 <= len(lost) <= 2  # at most one batch: the fits the killed worker had not finished
    assert df.loc["boat5__d1", "status"] == "failed" and "delta" in df.loc["boat5__d1", "error"]
    assert s["done"] == 8 - 1 - len(lost) and s["failed"] == 1 + len(lost)
    again = run_fleet(manifest, out, workers=2, batch=2, retries=0, progress=False)
    assert again["skipped"] == s["done"] and again["done"] == len(lost)
    df = pd.read_parquet(out / "results.parquet").set_index("key")
    ok = df[df["status"] == "ok"]
    assert len(ok) == 7 and all(os.path.isfile(f) for f in ok["fit_file"])
    assert ((ok["p_Xu"] - (-70.0)).abs() < 5 * ok["se_Xu"] + 10).all()  # truth Xu = -70 N s/m, within error
    assert (ok["cpu_seconds"] > 0).all()
    # one vessel-run, one answer: the fleet's fit is the command line's fit of the same run (same starts, same optimum)
    from diffship.fit.cli import main as fit_main

    assert fit_main([str(tmp_path / "v1.csv"), "--model", "fossen3", "--vessel", "usv", "--method", "output-error",
                     "--save", str(tmp_path / "cli.json"), "--quiet"]) in (0, 1)
    cli, fleet = (json.loads(Path(f).read_text()) for f in (tmp_path / "cli.json", df.loc["boat1__d1", "fit_file"]))
    assert cli["free"] == fleet["free"] and cli["cost"] == pytest.approx(fleet["cost"], rel=1e-9)
    for n in cli["free"]:
        assert abs(cli["params"][n] - fleet["params"][n]) <= 1e-6 * cli["stderr"][n], n
