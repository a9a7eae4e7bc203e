"""The parameter sweep runner (tools/sweep.py) on a LocalCluster of 2 workers with the small 2D
scene (tests/data/small2d.json, shortened to 0.02 s): results per row, a run that fails cleanly
(Poisson ratio 0.7), a bad field path, the skip of rows already done, the CLI, Parquet and plots.
Needs a built target/release/mps (MPS_BIN overrides it)."""
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))
import sweep  # noqa: E402

MPS = Path(os.environ.get("MPS_BIN", ROOT / "target" / "release" / "mps"))
pytestmark = pytest.mark.skipif(not MPS.is_file(), reason=f"{MPS} not built (cargo build --release)")


@pytest.fixture(scope="module")
def client():
    from distributed import Client, LocalCluster

    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                           dashboard_address=":0")
    c = Client(cluster)
    yield c
    c.close()
    cluster.close()


@pytest.fixture()
def base(tmp_path):
    scene = json.loads((ROOT / "tests" / "data" / "small2d.json").read_text())
    scene["end_time"] = 0.02
    p = tmp_path / "base.json"
    p.write_text(json.dumps(scene))
    return p


def write_table(path, header, rows):
    path.write_text("\n".join([",".join(header)] + [",".join(map(str, r)) for r in rows]) + "\n")
    return path


def test_field_paths():
    s = {"bodies": [{"name": "a", "material": {"young": 1.0}}, {"name": "b", "material": {}}]}
    sweep.set_path(s, "bodies[0].material.young", 2.0)
    sweep.set_path(s, "bodies[b].material.poisson", 0.25)
    sweep.set_path(s, "solver.fracture_strain", 0.1)
    assert s["bodies"][0]["material"]["young"] == 2.0
    assert s["bodies"][1]["material"]["poisson"] == 0.25
    assert s["solver"] == {"fracture_strain": 0.1}
    with pytest.raises(sweep.PathError, match="out of range"):
        sweep.set_path(s, "bodies[5].material.young", 1.0)
    with pytest.raises(sweep.PathError, match="no element named 'c'"):
        sweep.set_path(s, "bodies[c].material.young", 1.0)
    assert sweep.parse_value("paper") == "paper"
    assert sweep.parse_value("0.7") == 0.7
    assert sweep.parse_value("true") is True
    # The hash ignores key order but not values.
    assert sweep.scene_hash({"a": 1, "b": 2}) == sweep.scene_hash({"b": 2, "a": 1})
    assert sweep.scene_hash({"a": 1}) != sweep.scene_hash({"a": 1.5})


def test_sweep_rows_failure_and_skip(client, base, tmp_path):
    table = write_table(tmp_path / "t.csv", ["bodies[0].material.young", "bodies[strip].material.poisson"],
                        [[1e6, 0.3], [2e6, 0.3], [1e6, 0.7], [4e6, 0.3]])
    out = tmp_path / "res.csv"
    series = tmp_path / "series"
    df = sweep.sweep(sweep.read_table(table), out, base=base, client=client, mps=MPS,
                     series=series, progress=False)
    assert len(df) == 4
    ok = df[df.status == "ok"].sort_values("bodies[0].material.young")
    bad = df[df.status == "failed"]
    # The invalid Poisson ratio fails cleanly, naming the field; the other rows run.
    assert len(ok) == 3 and len(bad) == 1, df[["status", "message"]]
    assert bad["bodies[strip].material.poisson"].iloc[0] == 0.7
    assert "poisson" in bad["message"].iloc[0].lower()
    assert (ok["end_time"] - 0.02).abs().max() < 1e-9
    assert (ok["steps"] > 0).all()
    # The varied field reaches the solver: the stable step scales as 1/wave speed ~ E^-1/2, so
    # 4x Young's modulus takes 2x the steps to the same end time (within the step rounding).
    steps = ok["steps"].to_numpy()
    assert steps[0] < steps[1] < steps[2]
    assert steps[2] / steps[0] == pytest.approx(2.0, rel=0.1)
    assert (ok["tip.umax"] > 0).all()
    assert len(set(df["scene_hash"])) == 4
    assert len(list(series.glob("*.csv"))) == 3
    # A re-run skips every row already in the output (their hashes), and runs only a new one.
    mtime = out.stat().st_mtime_ns
    df2 = sweep.sweep(sweep.read_table(table), out, base=base, client=client, mps=MPS, progress=False)
    assert len(df2) == 4
    assert out.stat().st_mtime_ns == mtime  # nothing ran, nothing rewritten
    table2 = write_table(tmp_path / "t2.csv", ["bodies[0].material.young"], [[1e6], [3e6]])
    df3 = sweep.sweep(sweep.read_table(table2), out, base=base, client=client, mps=MPS, progress=False)
    # [1e6] with the base's poisson 0.3 is the same scene as row 1: skipped; 3e6 is new.
    assert len(df3) == 5
    assert (df3["bodies[0].material.young"] == 3e6).sum() == 1
    # The rows change no geometry: one closure for them all, kept beside the results.
    cache = out.with_name(out.name + ".closure-cache")
    assert len(list(cache.glob("closure-2d-*.bin"))) == 1, list(cache.iterdir())


def test_closure_cache_changes_no_result(client, base, tmp_path):
    # The closure taken from the cache gives the run a build from scratch gives.
    table = write_table(tmp_path / "t.csv", ["bodies[0].material.young"], [[1e6], [2e6]])
    rows = sweep.read_table(table)
    cached = sweep.sweep(rows, tmp_path / "a.csv", base=base, client=client, mps=MPS,
                         progress=False).sort_values("bodies[0].material.young")
    plain = sweep.sweep(rows, tmp_path / "b.csv", base=base, client=client, mps=MPS,
                        progress=False, closure_cache=False).sort_values("bodies[0].material.young")
    assert not (tmp_path / "b.csv.closure-cache").exists()
    for col in ["steps", "tip.umax", "tip.uy_end"]:
        if col in cached:
            assert cached[col].tolist() == plain[col].tolist(), col


def test_bad_path_and_blow_up(client, base, tmp_path):
    """A path that names nothing and a run that blows up (a time step far above the stable one)
    are failed rows with their message; the sweep goes on."""
    table = write_table(tmp_path / "t.csv", ["bodies[3].material.young", "solver.dt", "end_time"],
                        [[1e6, "", ""], ["", 1e-3, 0.05], ["", "", 0.01]])
    out = tmp_path / "res.parquet"
    df = sweep.sweep(sweep.read_table(table), out, base=base, client=client, mps=MPS, progress=False)
    assert out.exists() and len(df) == 3
    msg = dict(zip(df["status"] + ":" + df["message"].fillna(""), df["status"]))
    failed = df[df.status == "failed"]["message"].tolist()
    assert any("out of range" in m for m in failed), msg
    assert len(failed) == 2, msg
    assert (df.status == "ok").sum() == 1


def test_cli_local_cluster_scheduler_and_plot(client, base, tmp_path):
    """The command line on its own LocalCluster (2 workers), with a plot; then the same sweep with
    one more row on an existing cluster (--scheduler): only the new row runs."""
    table = write_table(tmp_path / "t.csv", ["bodies[0].material.young"], [[1e6], [2e6]])
    out = tmp_path / "res.csv"
    png = tmp_path / "p.png"
    p = subprocess.run([sys.executable, str(ROOT / "tools" / "sweep.py"), "--base", str(base),
                        "--table", str(table), "--out", str(out), "--workers", "2", "--mps", str(MPS),
                        "--plot", str(png), "--x", "bodies[0].material.young", "--y", "tip.umax"],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert "2 ok, 0 failed" in p.stderr
    assert png.stat().st_size > 1000
    write_table(table, ["bodies[0].material.young"], [[1e6], [2e6], [5e6]])
    p = subprocess.run([sys.executable, str(ROOT / "tools" / "sweep.py"), "--base", str(base),
                        "--table", str(table), "--out", str(out), "--mps", str(MPS),
                        "--scheduler", client.scheduler.address],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert "2 already in" in p.stderr and "1 to run" in p.stderr
    assert "3 ok, 0 failed" in p.stderr
    # Bad input: a clear message and an error status, no traceback.
    p = subprocess.run([sys.executable, str(ROOT / "tools" / "sweep.py"), "--base", str(base),
                        "--table", str(tmp_path / "missing.csv"), "--out", str(out)],
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 2 and "missing.csv: no such file" in p.stderr


FMU_DIR = os.environ.get("MPS_FMU_DIR")


@pytest.mark.skipif(not FMU_DIR or not (Path(FMU_DIR) / "small2d.fmu").is_file(),
                    reason="MPS_FMU_DIR/small2d.fmu not packed (scripts/fmu_tests.sh packs it)")
def test_fmu_sweep(client, tmp_path):
    """An FMU sweep with fmpy: parameters as start values, one that the FMU refuses."""
    table = write_table(tmp_path / "t.csv", ["strip.young", "strip.poisson"],
                        [[1e6, 0.3], [2e6, 0.3], [1e6, 0.7]])
    out = tmp_path / "fmu.csv"
    df = sweep.sweep(sweep.read_table(table), out, fmu=Path(FMU_DIR) / "small2d.fmu",
                     client=client, stop_time=0.02, step_size=0.002, progress=False)
    assert len(df) == 3
    ok = df[df.status == "ok"]
    assert len(ok) == 2 and (ok["end_time"] - 0.02).abs().max() < 1e-9
    assert ok["tip.uy"].abs().min() > 0
    bad = df[df.status == "failed"]
    assert "poisson" in bad["message"].iloc[0].lower()


def test_killed_worker_task_is_rerun(client, base, tmp_path):
    """The first run kills its worker process (SIGKILL of the subprocess's parent); Dask's nanny
    restarts the worker, the scheduler re-runs the task, and the row is ok."""
    marker = tmp_path / "killed-once"
    fake = tmp_path / "mps-killer"
    fake.write_text(f"""#!/bin/sh
if [ ! -e {marker} ]; then touch {marker}; kill -9 $PPID; sleep 5; exit 9; fi
exec {MPS} "$@"
""")
    fake.chmod(0o755)
    table = write_table(tmp_path / "t.csv", ["bodies[0].material.young"], [[1.5e6]])
    out = tmp_path / "res.csv"
    df = sweep.sweep(sweep.read_table(table), out, base=base, client=client, mps=fake, progress=False)
    assert marker.exists()  # the worker was killed once
    assert len(df) == 1 and df["status"].iloc[0] == "ok", df[["status", "message"]]
    client.wait_for_workers(2, timeout=60)


def test_case3_mode_event_times(client, tmp_path):
    """--mode case3 (`mps case3 --scene`): the case 3 scene to 0.08 s gives the first contact at
    the paper's 0.07 s (0.35 m gap at 5 m/s, checks every 2.5 ms) and no fracture yet; an
    unknown field is a failed row naming it."""
    table = [{"end_time": 0.08}, {"end_time": 0.08, "solver.no_such_field": 1}]
    out = tmp_path / "c3.csv"
    df = sweep.sweep(table, out, base=ROOT / "scenes" / "case3_collision.json", client=client,
                     mode="case3", mps=MPS, threads=1, progress=False)
    ok = df[df.status == "ok"]
    assert len(ok) == 1, df[["status", "message"]]
    assert ok["first_contact"].iloc[0] == pytest.approx(0.07, abs=0.0025)
    assert ok["final_broken_bonds"].iloc[0] == 0 and ok["particles"].iloc[0] == 5300
    bad = df[df.status == "failed"]
    assert "no_such_field" in bad["message"].iloc[0]
