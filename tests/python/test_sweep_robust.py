"""Bad input and lost processes in the sweep runner (tools/sweep.py), the reliability issue's
item 10: refused options (--workers 0, --threads 0, --timeout <= 0 or non-finite, --retries < 0),
malformed tables (extra or missing cells, duplicated or unnamed columns, not UTF-8), bad base
scenes (missing, invalid JSON or TOML; a TOML base runs), the output folder and an incompatible
results file, a default timeout, a timeout that ends the run's whole process group, and a run
whose Dask worker is killed (SIGKILL) taking its `mps` child with it.

Every user error is one line ``sweep.py: error: ...`` naming the option, file, row or column,
with exit status 2 and no traceback. The tests with a real run need a built target/release/mps
(MPS_BIN overrides it); the others use a stand-in script."""
import csv
import inspect
import json
import re
import os
import signal
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))
import sweep  # noqa: E402

SWEEP = ROOT / "tools" / "sweep.py"
MPS = Path(os.environ.get("MPS_BIN", ROOT / "target" / "release" / "mps"))
needs_mps = pytest.mark.skipif(not MPS.is_file(), reason=f"{MPS} not built (cargo build --release)")
linux = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc (Linux)")


@pytest.fixture(scope="module")
def client():
    from distributed import Client, LocalCluster

    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                           dashboard_address=":0")
    c = Client(cluster)
    yield c
    c.close()
    cluster.close()


def small2d(end_time=0.02):
    scene = json.loads((ROOT / "tests" / "data" / "small2d.json").read_text())
    scene["end_time"] = end_time
    return scene


@pytest.fixture()
def base(tmp_path):
    p = tmp_path / "base.json"
    p.write_text(json.dumps(small2d()))
    return p


@pytest.fixture()
def table(tmp_path):
    return write_table(tmp_path / "t.csv", ["bodies[0].material.young"], [[1e6]])


@pytest.fixture()
def fake_mps(tmp_path):
    """A stand-in for mps that fails at once (so a sweep that should have been refused ends)."""
    p = tmp_path / "fake-mps"
    p.write_text("#!/bin/sh\necho 'error: fake mps' >&2\nexit 1\n")
    p.chmod(0o755)
    return p


def write_table(path, header, rows):
    path.write_text("\n".join([",".join(header)] + [",".join(map(str, r)) for r in rows]) + "\n")
    return path


def cli(*args, timeout=60):
    return subprocess.run([sys.executable, str(SWEEP), *map(str, args)], capture_output=True,
                          text=True, timeout=timeout)


def assert_user_error(p, *needles):
    """Exit status 2, one error line holding every needle, no traceback."""
    assert p.returncode == 2, (p.returncode, p.stderr)
    assert "Traceback" not in p.stderr, p.stderr
    errors = [l for l in p.stderr.splitlines() if "error:" in l]
    assert len(errors) == 1, p.stderr
    for n in needles:
        assert n in errors[0], (n, errors[0])


def alive(pid: int) -> bool:
    """The process exists and is not a zombie (a dead child that nobody reaped yet)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except (FileNotFoundError, ProcessLookupError):
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def wait_gone(pid: int, seconds: float) -> bool:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if not alive(pid):
            return True
        time.sleep(0.1)
    return not alive(pid)


# ---------------------------------------------------------------------------------------------
# Options


@pytest.mark.parametrize("opt,value", [
    ("--workers", "0"), ("--workers", "-1"), ("--threads", "0"), ("--threads", "-2"),
    ("--timeout", "0"), ("--timeout", "-1"), ("--timeout", "nan"), ("--timeout", "inf"),
    ("--retries", "-1"),
])
def test_bad_option_values_are_refused(opt, value, base, table, fake_mps, tmp_path):
    """Before: --workers 0 waited forever for a worker, printing nothing; --threads 0 and
    --timeout -1 were accepted (the timeout failed every run at once)."""
    out = tmp_path / "res.csv"
    p = cli("--base", base, "--table", table, "--out", out, "--mps", fake_mps, opt, value)
    assert p.returncode == 2, (p.returncode, p.stderr)
    assert "Traceback" not in p.stderr and opt in p.stderr, p.stderr
    assert not out.exists()


def test_sweep_api_refuses_bad_numbers(base, fake_mps, tmp_path):
    table = [{"end_time": 0.01}]
    out = tmp_path / "res.csv"

    def hung(*_):
        raise TimeoutError("sweep() did not return")

    old = signal.signal(signal.SIGALRM, hung)
    signal.alarm(120)  # before the fix, workers=0 waited forever
    try:
        for kw in ({"threads": 0}, {"timeout": -1.0}, {"timeout": float("nan")}, {"retries": -1},
                   {"workers": 0}):
            with pytest.raises(ValueError, match=next(iter(kw))):
                sweep.sweep(table, out, base=base, mps=fake_mps, progress=False, **kw)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    assert not out.exists()


def test_default_timeout():
    """Before: no default, so a stuck run held its worker forever. Now one hour per run
    (DEFAULT_TIMEOUT_S), raised with --timeout."""
    assert sweep.DEFAULT_TIMEOUT_S == 3600.0
    a = sweep.make_parser().parse_args(["--base", "b.json", "--table", "t.csv", "--out", "o.csv"])
    assert a.timeout == sweep.DEFAULT_TIMEOUT_S
    assert inspect.signature(sweep.sweep).parameters["timeout"].default == sweep.DEFAULT_TIMEOUT_S
    assert "3600" in sweep.make_parser().format_help()
    docs = (ROOT / "docs" / "sweeps.md").read_text()
    assert "3600" in docs


# ---------------------------------------------------------------------------------------------
# The variations table


def table_error(tmp_path, text: str | bytes, *needles):
    p = tmp_path / "bad.csv"
    p.write_bytes(text if isinstance(text, bytes) else text.encode())
    with pytest.raises(sweep.SweepError) as e:
        sweep.read_table(p)
    msg = str(e.value)
    assert "bad.csv" in msg and "\n" not in msg, msg
    for n in needles:
        assert n in msg, (n, msg)
    return msg


def test_table_row_with_extra_cells(tmp_path):
    """Before: the third cell was dropped silently."""
    table_error(tmp_path, "a,b\n1,2\n3,4,5\n", "row 2", "line 3", "3 cells", "2 columns")


def test_table_short_row(tmp_path):
    """Before: the missing cell ran with the base scene's value."""
    table_error(tmp_path, "a,b\n1,2\n3\n5,6\n", "row 2", "line 3", "1 cell", "2 columns")


def test_table_duplicated_and_unnamed_columns(tmp_path):
    """Before: a duplicated column took the last value; a column with no name was dropped."""
    table_error(tmp_path, "solver.dt,end_time, solver.dt\n1e-5,0.1,2e-5\n", "'solver.dt'",
                "columns 1 and 3")
    table_error(tmp_path, "a,,b\n1,2,3\n", "column 2", "no name")


def test_table_not_utf8(tmp_path):
    """Before: UnicodeDecodeError traceback (UTF-16, as spreadsheets save "Unicode text"; Latin-1)."""
    msg = table_error(tmp_path, "end_time\n0.1\n".encode("utf-16"), "UTF-8")
    assert "UTF-16" in msg
    table_error(tmp_path, "end_time,name\n0.1,caf\xe9\n".encode("latin-1"), "UTF-8", "line 2")
    table_error(tmp_path, b"end_time\n0.1\x00\n", "line 2")


def test_table_empty_cells_blank_lines_and_bom(tmp_path):
    """An empty cell keeps the base scene's value; blank lines and rows of empty cells only
    (spreadsheets append them) are skipped; a UTF-8 byte-order mark is not part of the first
    column's name."""
    p = tmp_path / "t.csv"
    p.write_bytes("\ufeffa, b \n1,\n\n,\n,2\n \t, \n3,4\n".encode())
    assert sweep.read_table(p) == [{"a": 1}, {"b": 2}, {"a": 3, "b": 4}]
    p.write_text("a,b\n,\n")
    with pytest.raises(sweep.SweepError, match="no rows"):
        sweep.read_table(p)


def test_table_errors_on_the_command_line(base, fake_mps, tmp_path):
    out = tmp_path / "res.csv"
    t = tmp_path / "t.csv"
    t.write_text("bodies[0].material.young,end_time\n1e6,0.01\n2e6\n")
    assert_user_error(cli("--base", base, "--table", t, "--out", out, "--mps", fake_mps),
                      "t.csv", "row 2")
    t.write_bytes("end_time\n0.01\n".encode("utf-16"))
    assert_user_error(cli("--base", base, "--table", t, "--out", out, "--mps", fake_mps),
                      "t.csv", "UTF-8")
    assert_user_error(cli("--base", base, "--table", tmp_path, "--out", out, "--mps", fake_mps),
                      "--table")
    assert not out.exists()


# ---------------------------------------------------------------------------------------------
# The base scene


def to_toml(d: dict, prefix: str = "") -> list[str]:
    """Enough of a TOML writer for a scene: scalars and arrays as JSON (valid TOML), objects as
    tables, lists of objects as arrays of tables."""
    lines, tables = [], []
    for k, v in d.items():
        if isinstance(v, dict) or (isinstance(v, list) and v and all(isinstance(e, dict) for e in v)):
            tables.append((k, v))
        else:
            # A key that is not bare ("$schema") is a quoted string.
            key = k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else json.dumps(k)
            lines.append(f"{key} = {json.dumps(v)}")
    for k, v in tables:
        for e in (v if isinstance(v, list) else [v]):
            lines.append(f"[[{prefix}{k}]]" if isinstance(v, list) else f"[{prefix}{k}]")
            lines += to_toml(e, f"{prefix}{k}.")
    return lines


def test_bad_base_scene(table, fake_mps, tmp_path):
    """Before: a traceback (JSONDecodeError, UnicodeDecodeError, AttributeError)."""
    out = tmp_path / "res.csv"
    run = lambda b: cli("--base", b, "--table", table, "--out", out, "--mps", fake_mps)  # noqa: E731
    assert_user_error(run(tmp_path / "missing.json"), "--base", "missing.json", "no such file")
    bad = tmp_path / "bad.json"
    bad.write_text('{"name": "x",\n "end_time": 0.1,,}')
    assert_user_error(run(bad), "--base", "bad.json", "not valid JSON", "line 2")
    bad.write_text("[1, 2]")
    assert_user_error(run(bad), "bad.json", "object")
    bad.write_bytes('{"name": "caf\xe9"}'.encode("latin-1"))
    assert_user_error(run(bad), "bad.json", "UTF-8")
    bad_toml = tmp_path / "bad.toml"
    bad_toml.write_text("name = 'x'\nend_time = \n")
    assert_user_error(run(bad_toml), "--base", "bad.toml", "not valid TOML", "line 2")
    bad_toml.write_text("name = 'x'\nwhen = 1979-05-27T07:32:00Z\n")
    assert_user_error(run(bad_toml), "bad.toml", "when")
    with pytest.raises(sweep.SweepError, match="missing.json"):
        sweep.sweep([{"end_time": 0.1}], out, base=tmp_path / "missing.json", mps=MPS,
                    progress=False)
    assert not out.exists()


@needs_mps
def test_toml_base_runs_like_the_json_one(client, tmp_path):
    """Before: json.loads of the TOML text, a traceback. `mps run` reads TOML scenes, so the sweep
    does too: the same scene as TOML and as JSON gives the same scene hash and the same run."""
    scene = small2d()
    toml_base = tmp_path / "base.toml"
    toml_base.write_text("\n".join(to_toml(scene)) + "\n")
    assert tomllib.loads(toml_base.read_text()) == scene
    json_base = tmp_path / "base.json"
    json_base.write_text(json.dumps(scene))
    table = [{"bodies[strip].material.young": 2e6}]
    a = sweep.sweep(table, tmp_path / "toml.csv", base=toml_base, client=client, mps=MPS,
                    progress=False)
    b = sweep.sweep(table, tmp_path / "json.csv", base=json_base, client=client, mps=MPS,
                    progress=False)
    assert list(a["status"]) == ["ok"], a[["status", "message"]]
    assert list(a["scene_hash"]) == list(b["scene_hash"])
    assert list(a["steps"]) == list(b["steps"])


# ---------------------------------------------------------------------------------------------
# The output


def test_missing_output_folder_is_created(client, base, fake_mps, tmp_path):
    """Before: the runs ran, then writing the results failed with a traceback (results lost)."""
    out = tmp_path / "new" / "sub" / "res.csv"
    df = sweep.sweep([{"end_time": 0.01}], out, base=base, client=client, mps=fake_mps,
                     progress=False)
    assert out.is_file() and len(df) == 1 and df["status"].iloc[0] == "failed"
    assert "fake mps" in df["message"].iloc[0]


def test_output_that_cannot_be_written(base, table, fake_mps, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder\n")
    assert_user_error(cli("--base", base, "--table", table, "--out", blocker / "res.csv",
                          "--mps", fake_mps), "--out", "res.csv")
    folder = tmp_path / "res.csv"
    folder.mkdir()
    assert_user_error(cli("--base", base, "--table", table, "--out", folder, "--mps", fake_mps),
                      "--out", "res.csv")
    out = tmp_path / "ok.csv"
    assert_user_error(cli("--base", base, "--table", table, "--out", out, "--mps", fake_mps,
                          "--plot", blocker / "p.png", "--x", "end_time", "--y", "steps"),
                      "--plot", "p.png")
    assert not out.exists()  # refused before the runs, not after them


@pytest.mark.parametrize("name,content", [
    ("old.csv", b"young,tip_umax\n1e6,0.01\n2e6,0.02\n"),            # no scene_hash/status
    ("old.csv", b"\xff\xfey\x00o\x00u\x00n\x00g\x00\n\x00"),          # UTF-16
    ("old.parquet", b"PAR1 this is not a parquet file"),              # unreadable
])
def test_incompatible_results_file_is_kept(name, content, base, table, fake_mps, tmp_path):
    """Before: KeyError 'scene_hash' (or a decode error) as a traceback. Now refused, naming the
    file; the old file is left as it was."""
    out = tmp_path / name
    out.write_bytes(content)
    assert_user_error(cli("--base", base, "--table", table, "--out", out, "--mps", fake_mps),
                      "--out", name)
    assert out.read_bytes() == content
    assert not out.with_name(out.name + ".tmp").exists()


def test_empty_results_file_is_no_results(client, base, fake_mps, tmp_path):
    out = tmp_path / "res.csv"
    out.write_text("")
    df = sweep.sweep([{"end_time": 0.01}], out, base=base, client=client, mps=fake_mps,
                     progress=False)
    assert len(df) == 1


def test_plot_column_that_is_not_there(base, table, fake_mps, tmp_path):
    """Before: KeyError traceback after the sweep."""
    out = tmp_path / "res.csv"
    p = cli("--base", base, "--table", table, "--out", out, "--mps", fake_mps, "--workers", "1",
            "--quiet", "--plot", tmp_path / "p.png", "--x", "no_such_column", "--y", "steps", timeout=180)
    assert_user_error(p, "--x", "no_such_column")
    assert out.is_file()  # the results are written before the plot


# ---------------------------------------------------------------------------------------------
# Processes


@linux
def test_timeout_ends_the_runs_process_group(tmp_path):
    """A run over its timeout is killed with everything it started (its process group): before,
    only the program itself was killed and a child of a wrapper script ran on."""
    pidfile = tmp_path / "child.pid"
    fake = tmp_path / "mps-wrapper"
    fake.write_text(f"#!/bin/sh\nsleep 30 &\necho $! > {pidfile}\nwait\n")
    fake.chmod(0o755)
    t0 = time.monotonic()
    row = sweep.run_scene({"name": "x"}, {}, str(fake), timeout=2.0)
    elapsed = time.monotonic() - t0
    child = int(pidfile.read_text())
    try:
        assert row["status"] == "failed" and "timeout after 2" in row["message"], row
        assert elapsed < 15, elapsed
        assert wait_gone(child, 5.0), f"the wrapper's child {child} survived the timeout"
    finally:
        if alive(child):
            os.kill(child, signal.SIGKILL)


@linux
@needs_mps
def test_killed_worker_takes_its_mps_run_with_it(tmp_path):
    """SIGKILL of the Dask worker process that runs `mps` (a long run): the `mps` process ends
    with it (before: it ran on for the whole run, holding a core, while Dask re-ran the task on
    the restarted worker). The re-run here fails at once, so the sweep ends with a failed row."""
    scene = small2d(end_time=1000.0)  # minutes of work
    base = tmp_path / "long.json"
    base.write_text(json.dumps(scene))
    pidfile = tmp_path / "mps.pid"
    fake = tmp_path / "mps-once"
    fake.write_text(f"""#!/bin/sh
if [ -e {pidfile} ]; then echo 'error: re-run' >&2; exit 1; fi
echo $$ > {pidfile}
exec {MPS} "$@"
""")
    fake.chmod(0o755)
    table = write_table(tmp_path / "t.csv", ["bodies[0].material.young"], [[1e6]])
    out = tmp_path / "res.csv"
    sw = subprocess.Popen([sys.executable, str(SWEEP), "--base", str(base), "--table", str(table),
                           "--out", str(out), "--mps", str(fake), "--workers", "1",
                           "--threads", "1", "--timeout", "900", "--quiet"],
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                          start_new_session=True)
    pid = None
    try:
        end = time.monotonic() + 120
        while time.monotonic() < end and not (pidfile.exists() and pidfile.read_text().strip()):
            assert sw.poll() is None, sw.communicate()
            time.sleep(0.2)
        pid = int(pidfile.read_text())
        time.sleep(1.0)  # the shell has exec'd mps
        cmdline = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
        scene_path = next(a for a in cmdline if a.endswith(b"scene.json"))
        assert cmdline[0] == os.fsencode(MPS), cmdline
        worker = int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])
        assert b"python" in Path(f"/proc/{worker}/cmdline").read_bytes().lower()
        os.kill(worker, signal.SIGKILL)
        assert wait_gone(pid, 5.0), f"mps {pid} outlived its worker {worker}"
        for proc in Path("/proc").iterdir():
            if proc.name.isdigit():
                try:
                    args = (proc / "cmdline").read_bytes().split(b"\0")
                except OSError:
                    continue
                assert scene_path not in args or not alive(int(proc.name)), (proc.name, args)
        _, err = sw.communicate(timeout=180)
        assert sw.returncode == 0, err
        with open(out, newline="") as f:
            rows = list(csv.DictReader(f))
        assert len(rows) == 1 and rows[0]["status"] == "failed", rows
        assert "re-run" in rows[0]["message"]  # Dask ran the task again on the new worker
    finally:
        if pid is not None and alive(pid):
            os.kill(pid, signal.SIGKILL)
        if sw.poll() is None:
            os.killpg(sw.pid, signal.SIGKILL)
            sw.wait()
