#!/usr/bin/env python3
"""Parameter sweeps of the MPS solver on dask.distributed.

One row of a variations table (CSV: one column per scene field path such as
``bodies[0].material.young``, ``bodies[block].material.poisson`` (a list element by its
``name``), ``solver.fracture_strain``, ``end_time``; or, with ``--fmu``, one column per FMU
parameter name) is one run. Each run writes the varied scene to a temporary directory and runs
the ``mps`` program on it as a subprocess (``mps run SCENE --json``, or with ``--mode case3``
``mps case3 --scene SCENE --json`` for contact/fracture event times), or simulates the FMU with
fmpy, and returns one result row: the parameters, the sha256 of the varied scene (``scene_hash``),
``status`` (ok / failed), ``message`` and the figures of the run's JSON summary.

By default the runs go to a LocalCluster on this machine (``--workers`` processes, one thread
each); with ``--scheduler ADDRESS`` the same sweep runs on an existing Dask cluster (its workers
need the ``mps`` program at the path given by ``--mps``, or the FMU is sent to them). A run's
failure (scene error, blow-up, overlap, timeout: ``--timeout``, one hour by default) is a row
with status ``failed`` and its message and does not stop the sweep; a task whose worker dies is
re-run elsewhere (Dask's retries), and on Linux its ``mps`` run dies with it. Results are written
after each finished run; re-running a sweep skips the rows whose scene hash is already in the
output (``--retry-failed`` re-runs the failed ones).

The base scene is JSON, or TOML when its name ends in ``.toml``. Bad input (an option, a table
row with more or fewer cells than the header, a duplicated column, a file that is not UTF-8, a
base scene that does not parse, an output that is not results of this tool) is refused before
anything runs: one line naming it, exit status 2.

Example::

    python tools/sweep.py --base tests/data/small2d.json --table variations.csv --out results.csv
    python tools/sweep.py --base scenes/case3_collision.json --mode case3 \\
        --table study.csv --out study.parquet --scheduler tcp://10.0.0.5:8786 --plot study.png \\
        --x solver.fracture_strain --y first_fracture
"""
from __future__ import annotations

import argparse
import codecs
import copy
import csv
import hashlib
import io
import json
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_MPS = ROOT / "target" / "release" / "mps"
# Seconds one run of mps may take before it is killed and its row failed. One hour is far above
# the project's sweep runs (a full case 3 run, 1.7 s simulated, 5300 particles: 17 s on 2 idle
# cores, 30-70 s on one thread of a loaded machine; BENCHMARKS.md) and still ends a stuck run
# the same day; raise it with --timeout for larger scenes.
DEFAULT_TIMEOUT_S = 3600.0


class SweepError(ValueError):
    """Bad input (an option, the table, the base scene, the output): the message names it."""


def check_numbers(workers: int = 1, threads: int | None = None, timeout: float | None = None,
                  retries: int = 0) -> None:
    """Refuses a worker count or solver thread count below 1, a timeout that is not a finite
    positive number of seconds (None: no timeout) and negative retries."""
    def is_int(v):
        return isinstance(v, int) and not isinstance(v, bool)

    if not is_int(workers) or workers < 1:
        raise SweepError(f"workers must be an integer of at least 1, got {workers!r}")
    if threads is not None and (not is_int(threads) or threads < 1):
        raise SweepError(f"threads must be an integer of at least 1, got {threads!r}")
    if timeout is not None and (isinstance(timeout, bool) or not isinstance(timeout, (int, float))
                                or not math.isfinite(timeout) or timeout <= 0):
        raise SweepError(f"timeout must be a finite number of seconds above 0, got {timeout!r}")
    if not is_int(retries) or retries < 0:
        raise SweepError(f"retries must be an integer of at least 0, got {retries!r}")

# ---------------------------------------------------------------------------------------------
# Scene field paths


class PathError(ValueError):
    """A field path that does not name a place in the scene."""


_TOKEN = re.compile(r"\.?([^.\[\]]+)|\[([^\]]*)\]")


def parse_path(path: str) -> list[Any]:
    """``bodies[0].material.young`` -> ``["bodies", 0, "material", "young"]``; ``[block]`` selects
    the list element whose ``name`` is ``block`` (kept as ``("name", "block")``)."""
    keys: list[Any] = []
    pos = 0
    path = path.strip()
    while pos < len(path):
        m = _TOKEN.match(path, pos)
        if not m or m.end() == pos:
            raise PathError(f"cannot parse the field path {path!r} at character {pos}")
        if m.group(1) is not None:
            keys.append(m.group(1))
        else:
            idx = m.group(2).strip()
            if re.fullmatch(r"-?\d+", idx):
                keys.append(int(idx))
            elif idx:
                keys.append(("name", idx))
            else:
                raise PathError(f"empty index [] in the field path {path!r}")
        pos = m.end()
    if not keys:
        raise PathError("empty field path")
    return keys


def set_path(scene: dict, path: str, value: Any) -> None:
    """Sets ``value`` at ``path`` in ``scene``; missing object keys are created (the scene's
    validation names an unknown field), a list index out of range or a missing name is an
    error naming the path."""
    keys = parse_path(path)
    node: Any = scene
    for i, key in enumerate(keys):
        last = i == len(keys) - 1
        where = path if last else f"{path} (at {keys[i]!r})"
        if isinstance(key, str):
            if not isinstance(node, dict):
                raise PathError(f"{where}: not an object")
            if last:
                node[key] = value
                return
            if not isinstance(node.get(key), (dict, list)):
                node[key] = {}
            node = node[key]
        else:
            if not isinstance(node, list):
                raise PathError(f"{where}: not a list")
            if isinstance(key, tuple):
                hits = [k for k, e in enumerate(node) if isinstance(e, dict) and e.get("name") == key[1]]
                if not hits:
                    raise PathError(f"{path}: no element named {key[1]!r}")
                key = hits[0]
            if not -len(node) <= key < len(node):
                raise PathError(f"{path}: index {key} out of range (the list has {len(node)} elements)")
            if last:
                node[key] = value
                return
            node = node[key]


def parse_value(text: str) -> Any:
    """A table cell: JSON (numbers, true/false, null, lists, quoted strings), else the text."""
    t = text.strip()
    if t == "":
        return None
    try:
        return json.loads(t)
    except ValueError:
        return t


def scene_hash(scene: dict) -> str:
    """sha256 of the canonical JSON of a scene (sorted keys, no spaces)."""
    text = json.dumps(scene, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def decode_utf8(data: bytes, what: str) -> str:
    """``data`` as UTF-8 text (a byte-order mark is dropped); UTF-16/32, other encodings and NUL
    characters are a SweepError naming ``what`` and the line."""
    for bom, name in ((codecs.BOM_UTF32_LE, "UTF-32"), (codecs.BOM_UTF32_BE, "UTF-32"),
                      (codecs.BOM_UTF16_LE, "UTF-16"), (codecs.BOM_UTF16_BE, "UTF-16")):
        if data.startswith(bom):
            raise SweepError(f"{what}: {name} text (byte-order mark {bom.hex()}), not UTF-8; "
                             "save it as UTF-8")
    if data.startswith(codecs.BOM_UTF8):
        data = data[len(codecs.BOM_UTF8):]
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        line = data[:e.start].count(b"\n") + 1
        raise SweepError(f"{what}: not UTF-8 text (byte 0x{data[e.start]:02x} on line {line}); "
                         "save it as UTF-8") from None
    if "\0" in text:
        line = text[:text.index("\0")].count("\n") + 1
        raise SweepError(f"{what}: a NUL character on line {line} (UTF-16 without a byte-order "
                         "mark, or not a text file?); save it as UTF-8 text")
    return text


def _not_json(node: Any, where: str = "") -> str | None:
    """The path of the first value in ``node`` that JSON cannot hold (a TOML date or time)."""
    if isinstance(node, dict):
        for k, v in node.items():
            hit = _not_json(v, f"{where}.{k}" if where else str(k))
            if hit:
                return hit
    elif isinstance(node, list):
        for i, v in enumerate(node):
            hit = _not_json(v, f"{where}[{i}]")
            if hit:
                return hit
    elif not (node is None or isinstance(node, (str, int, float, bool))):
        return where or "the scene"
    return None


def load_base(path: Path) -> dict:
    """The base scene as a dict: TOML when the file name ends in ``.toml``, else JSON, as
    ``mps run`` reads them (the runs get it as JSON). A missing file, text that is not UTF-8,
    invalid JSON or TOML, a TOML date/time or a top level that is not an object is a SweepError
    naming the file (and the line). Whether the scene itself is valid is for mps to say, run by
    run."""
    path = Path(path)
    what = f"--base {path}"
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise SweepError(f"{what}: no such file") from None
    except OSError as e:
        raise SweepError(f"{what}: cannot read it ({e.strerror or e})") from None
    text = decode_utf8(data, what)
    if path.suffix == ".toml":
        try:
            scene = tomllib.loads(text)
        except tomllib.TOMLDecodeError as e:
            raise SweepError(f"{what}: not valid TOML: {e}") from None
        bad = _not_json(scene)
        if bad:
            raise SweepError(f"{what}: {bad} is a TOML date/time, which no scene field takes")
    else:
        try:
            scene = json.loads(text)
        except json.JSONDecodeError as e:
            hint = "" if text.lstrip()[:1] in ("{", "[") else " (a TOML scene needs the .toml extension)"
            raise SweepError(f"{what}: not valid JSON: {e.msg} at line {e.lineno} column "
                             f"{e.colno}{hint}") from None
    if not isinstance(scene, dict):
        raise SweepError(f"{what}: a scene is an object ({{...}}), this is a "
                         f"{type(scene).__name__}")
    return scene


def _cells(n: int) -> str:
    return f"{n} cell" if n == 1 else f"{n} cells"


def read_table(path: Path) -> list[dict[str, Any]]:
    """The variations table, CSV in UTF-8: one dict (column -> value) per row. The header names
    the columns (each once, none empty); every row has as many cells as the header. An empty
    cell keeps the base scene's value (the column is left out of that row's dict); blank lines
    and rows whose cells are all empty are skipped. Anything else is a SweepError naming the
    file, the line and the data row (data row 1 is the record after the header)."""
    path = Path(path)
    what = f"--table {path}"
    try:
        data = path.read_bytes()
    except OSError as e:
        raise SweepError(f"{what}: cannot read it ({e.strerror or e})") from None
    reader = csv.reader(io.StringIO(decode_utf8(data, what), newline=""), strict=True)
    header: list[str] | None = None
    record = 0  # data row: records after the header, blank ones included
    rows: list[dict[str, Any]] = []
    line = 1
    try:
        for cells in reader:
            first, line = line, reader.line_num + 1  # first line of this record; of the next
            if header is None:
                if not any(c.strip() for c in cells):
                    continue
                header = [c.strip() for c in cells]
                seen: dict[str, int] = {}
                for i, name in enumerate(header, 1):
                    if not name:
                        raise SweepError(f"{what}: column {i} of the header (line {first}) has no "
                                         "name")
                    if name in seen:
                        raise SweepError(f"{what}: the column {name!r} appears twice in the "
                                         f"header (columns {seen[name]} and {i})")
                    seen[name] = i
                continue
            record += 1
            if not any(c.strip() for c in cells):
                continue
            if len(cells) != len(header):
                n = len(header)
                raise SweepError(f"{what}: line {first} (data row {record}) has "
                                 f"{_cells(len(cells))}, the header has {n} column"
                                 f"{'' if n == 1 else 's'}")
            rows.append({k: parse_value(v) for k, v in zip(header, cells) if v.strip() != ""})
    except csv.Error as e:
        raise SweepError(f"{what}: line {line}: {e}") from None
    if header is None:
        raise SweepError(f"{what}: empty (no header)")
    if not rows:
        raise SweepError(f"{what}: no rows under the header")
    return rows


# ---------------------------------------------------------------------------------------------
# One run (executed on a worker)


def _num(x: Any) -> Any:
    return x if not isinstance(x, float) or math.isfinite(x) else None


def _figures_run(res: dict) -> dict:
    """Figures of ``mps run --json``."""
    out = {}
    for k in ("particles", "bonds", "steps", "dt", "critical_dt", "end_time", "wall_time_s",
              "pair_updates_per_s", "kinetic_energy", "strain_energy", "frequency_hz", "peak_m"):
        if k in res:
            out[k] = _num(res[k])
    for name, u in res.get("final_displacement", []):
        for ax, v in zip("xyz", u):
            out[f"{name}.u{ax}"] = _num(v)
    series = res.get("series") or {}
    for name, disp in zip(series.get("probes", []), series.get("displacement", [])):
        if disp:
            out[f"{name}.umax"] = max(math.sqrt(sum(c * c for c in u)) for u in disp)
    for name, f in res.get("final_reaction", []):
        for ax, v in zip("xyz", f):
            out[f"{name}.reaction_{ax}"] = _num(v)
    return out


def _figures_case3(rep: dict) -> dict:
    """Figures of ``mps case3 --scene --json`` (contact/fracture events)."""
    out = {}
    for k in ("particles", "steps", "dt", "critical_dt", "end_time", "wall_time_s", "first_contact",
              "first_fracture", "first_fractured_surface_contact", "separation", "failure_time",
              "final_broken_bonds", "final_fragments", "final_large_fragments", "contact_searches"):
        if k in rep:
            out[k] = _num(rep[k])
    hist = rep.get("history") or []
    if hist:
        out["max_bond_strain"] = max(h.get("max_bond_strain", 0.0) for h in hist)
        for t in (0.4, 0.6, 1.0):
            before = [h for h in hist if h["time"] <= t + 1e-9]
            if before and before[-1]["time"] >= t - 1e-6:
                out[f"broken_bonds_{t:g}s"] = before[-1]["broken_bonds"]
    return out


def _series_case3(rep: dict) -> str:
    hist = rep.get("history") or []
    if not hist:
        return ""
    cols = list(hist[0].keys())
    lines = [",".join(cols)] + [",".join(str(h[c]) for c in cols) for h in hist]
    return "\n".join(lines) + "\n"


def _die_with_parent():
    """On Linux, a ``preexec_fn`` that puts the child in a process group of its own and has the
    kernel send it SIGKILL when the thread that started it ends (``prctl(PR_SET_PDEATHSIG)``), so
    a run dies with its Dask worker even when the worker is killed with SIGKILL. None elsewhere
    (or without prctl): the caller starts a new session instead, which still gives a group to
    kill on timeout. The setting survives ``exec`` (a wrapper script that execs mps keeps it)
    but not ``fork``: a wrapper should exec mps rather than start it as a child."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        import ctypes

        prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None
    parent = os.getpid()

    def preexec():
        os.setpgid(0, 0)
        prctl(1, ctypes.c_ulong(signal.SIGKILL))  # PR_SET_PDEATHSIG
        if os.getppid() != parent:  # the parent died before the prctl
            os._exit(137)

    return preexec


def _kill_group(p: subprocess.Popen) -> None:
    """SIGKILL to the run's process group (the program and whatever it started)."""
    try:
        os.killpg(p.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    except OSError:
        p.kill()


def run_scene(scene: dict, params: dict, mps: str, mode: str = "run", want_series: bool = False,
              timeout: float | None = None, threads: int | None = None,
              closure_cache: str | None = None) -> dict:
    """Writes ``scene`` to a temporary directory and runs ``mps`` on it; returns the result row
    (never raises for a failed run: status ``failed`` and the message). ``timeout``: seconds,
    then the run's process group is killed and the row failed (None: no limit). The run dies
    with the process that called this (Linux; see ``_die_with_parent``). ``closure_cache``: a
    directory where ``mps run`` keeps the default operator's closure of each geometry and finds
    it again (rows that change materials, step or damping pay it once per worker)."""
    row: dict[str, Any] = dict(params)
    row["scene_hash"] = scene_hash(scene)
    row["status"] = "failed"
    row["message"] = ""
    row["worker_host"] = os.uname().nodename
    t0 = time.perf_counter()
    tmp = tempfile.mkdtemp(prefix="mps-sweep-")
    try:
        path = Path(tmp) / "scene.json"
        path.write_text(json.dumps(scene, indent=1))
        if mode == "case3":
            cmd = [mps, "case3", "--scene", str(path), "--json"]
        else:
            cmd = [mps, "run", str(path), "--out", str(Path(tmp) / "out"), "--json"]
        env = dict(os.environ)
        if threads is not None:
            env["RAYON_NUM_THREADS"] = str(threads)
        if closure_cache is not None and mode == "run":
            env["MPS_CLOSURE_CACHE"] = closure_cache
        preexec = _die_with_parent()
        group = {"preexec_fn": preexec} if preexec is not None else {"start_new_session": True}
        try:
            p = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE, text=True, encoding="utf-8",
                                 errors="replace", env=env, **group)
        except OSError as e:
            row["message"] = f"cannot run {mps}: {e}"
            return row
        with p:
            try:
                stdout, stderr = p.communicate(timeout=timeout)
            except subprocess.TimeoutExpired:
                _kill_group(p)
                try:
                    p.communicate(timeout=10)
                except subprocess.TimeoutExpired:  # a process outside the group holds the pipes
                    pass
                row["message"] = f"timeout after {timeout:g} s"
                return row
            except BaseException:
                _kill_group(p)
                raise
        err = "\n".join(l for l in stderr.splitlines() if l.startswith("error"))
        res = None
        if stdout.strip():
            try:
                res = json.loads(stdout)
            except ValueError:
                res = None
        if res is None:
            row["message"] = err or stderr.strip()[-500:] or f"exit code {p.returncode}, no output"
            return row
        if mode == "case3":
            rep = res[0] if isinstance(res, list) else res
            row.update(_figures_case3(rep))
            if want_series:
                row["_series"] = _series_case3(rep)
            if rep.get("failure"):
                row["message"] = rep["failure"]
                return row
        else:
            row.update(_figures_run(res))
            if want_series:
                csv_path = Path(tmp) / "out" / "probes.csv"
                row["_series"] = csv_path.read_text() if csv_path.exists() else ""
            if res.get("error"):
                row["message"] = res["error"]
                return row
        if p.returncode != 0:
            row["message"] = err or f"exit code {p.returncode}"
            return row
        row["status"] = "ok"
        return row
    finally:
        row["elapsed_s"] = time.perf_counter() - t0
        shutil.rmtree(tmp, ignore_errors=True)


def run_fmu(fmu_bytes: bytes, fmu_hash: str, params: dict, stop_time: float | None,
            step_size: float | None, want_series: bool = False) -> dict:
    """Simulates the FMU (fmpy) with ``params`` as start values; the row holds each output's
    final value and largest magnitude."""
    row: dict[str, Any] = dict(params)
    key = json.dumps({"fmu": fmu_hash, "params": params, "stop": stop_time, "step": step_size},
                     sort_keys=True)
    row["scene_hash"] = hashlib.sha256(key.encode()).hexdigest()
    row["status"] = "failed"
    row["message"] = ""
    row["worker_host"] = os.uname().nodename
    t0 = time.perf_counter()
    tmp = tempfile.mkdtemp(prefix="mps-sweep-fmu-")
    try:
        import numpy as np
        from fmpy import simulate_fmu

        path = Path(tmp) / "model.fmu"
        path.write_bytes(fmu_bytes)
        messages: list[str] = []

        def logger(_component, _instance, status, _category, message):
            if status > 1:  # warning and above
                messages.append(message.decode() if isinstance(message, bytes) else str(message))

        try:
            res = simulate_fmu(str(path), start_values=dict(params), stop_time=stop_time,
                               output_interval=step_size, step_size=step_size, logger=logger,
                               fmi_call_logger=None)
        except Exception as e:  # noqa: BLE001 - any FMU failure is a failed row
            row["message"] = (" | ".join(messages[-3:]) + " | " if messages else "") + str(e)
            return row
        names = [n for n in res.dtype.names if n != "time"]
        row["end_time"] = float(res["time"][-1])
        for n in names:
            col = np.asarray(res[n], dtype=float)
            row[n] = _num(float(col[-1]))
            row[f"{n}.absmax"] = _num(float(np.max(np.abs(col))))
        if want_series:
            lines = [",".join(res.dtype.names)]
            lines += [",".join(repr(float(v)) for v in r) for r in res]
            row["_series"] = "\n".join(lines) + "\n"
        row["status"] = "ok"
        return row
    finally:
        row["elapsed_s"] = time.perf_counter() - t0
        shutil.rmtree(tmp, ignore_errors=True)


# ---------------------------------------------------------------------------------------------
# Results file


RESULT_KEYS = ("scene_hash", "status")


def read_results(path: Path):
    """The results already in ``path`` (none when there is no file or it is empty). A file that
    cannot be read, or lacks the columns scene_hash and status (another tool's table, or not a
    table), is a SweepError, and the file is left as it is. Results with other parameter or
    figure columns (another table, another base scene) are kept: new rows are added to them."""
    import pandas as pd

    path = Path(path)
    what = f"--out {path}"
    if path.is_dir():
        raise SweepError(f"{what}: a folder; give the results file (.csv or .parquet) to write")
    if not path.exists() or path.stat().st_size == 0:
        return pd.DataFrame()
    keep = "; it is left as it is: move it away or give another --out"
    try:
        if path.suffix == ".parquet":
            df = pd.read_parquet(path)
        else:
            df = pd.read_csv(path, encoding="utf-8")
    except Exception as e:  # noqa: BLE001 - pandas and pyarrow raise many kinds
        reason = (str(e).strip().splitlines() or [type(e).__name__])[0][:200]
        raise SweepError(f"{what}: an existing file that cannot be read as results ({reason})"
                         f"{keep}") from None
    missing = [c for c in RESULT_KEYS if c not in df.columns]
    if missing:
        raise SweepError(f"{what}: an existing file without the column"
                         f"{'s' if len(missing) > 1 else ''} {', '.join(missing)} (not results "
                         f"of this tool){keep}")
    return df


def _make_folder(folder: Path, what: str) -> None:
    """Creates ``folder`` (and its parents); SweepError naming ``what`` when it cannot."""
    if folder.exists() and not folder.is_dir():
        raise SweepError(f"{what}: {folder} is not a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise SweepError(f"{what}: cannot create the folder {folder} ({e.strerror or e})") from None
    if not os.access(folder, os.W_OK | os.X_OK):
        raise SweepError(f"{what}: cannot write in the folder {folder}")


def write_results(path: Path, rows: list[dict], columns_first: list[str]) -> None:
    import pandas as pd

    df = pd.DataFrame(rows)
    first = [c for c in columns_first if c in df.columns]
    df = df[first + [c for c in df.columns if c not in first]]
    tmp = path.with_name(path.name + ".tmp")
    if path.suffix == ".parquet":
        # Mixed-type parameter columns (numbers and text) are stored as text.
        for c in df.columns:
            if df[c].dtype == object:
                df[c] = df[c].map(lambda v: None if v is None or (isinstance(v, float) and math.isnan(v)) else str(v))
        df.to_parquet(tmp, index=False)
    else:
        df.to_csv(tmp, index=False)
    os.replace(tmp, path)


# ---------------------------------------------------------------------------------------------
# The sweep


def make_client(scheduler: str | None, workers: int, processes: bool = True):
    """A client of the cluster at ``scheduler``, or of a new LocalCluster of ``workers`` workers
    with one thread each (each run is a subprocess, so threads would only share the cores)."""
    from distributed import Client, LocalCluster

    if scheduler:
        return Client(scheduler)
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=processes,
                           dashboard_address=":0")
    return Client(cluster)


def sweep(table: list[dict], out: Path, *, base: Path | None = None, fmu: Path | None = None,
          client=None, scheduler: str | None = None, workers: int = 2, mode: str = "run",
          mps: Path = DEFAULT_MPS, series: Path | None = None, retries: int = 2,
          timeout: float | None = DEFAULT_TIMEOUT_S, retry_failed: bool = False, stop_time: float | None = None,
          step_size: float | None = None, processes: bool = True, progress: bool = True,
          threads: int | None = None, closure_cache: bool = True):
    """Runs every row of ``table`` not already in ``out``; returns the results DataFrame.
    ``timeout``: seconds per run of mps (None: none). ``closure_cache``: the runs keep the
    default operator's closure of each geometry in ``<out>.closure-cache`` beside the results and
    take it from there
    (a worker that cannot write there warns and computes it). Bad input raises SweepError."""
    from distributed import as_completed

    if (base is None) == (fmu is None):
        raise ValueError("give exactly one of base (a scene) or fmu")
    check_numbers(workers, threads, timeout, retries)
    out = Path(out)
    series = Path(series) if series is not None else None
    params_cols = sorted({k for r in table for k in r})
    first = params_cols + ["scene_hash", "status", "message"]

    # The jobs: (hash, params, scene) with the scene built and hashed on the client.
    jobs = []
    prebuilt: list[dict] = []
    if base is not None:
        base_scene = load_base(base)
        for params in table:
            scene = copy.deepcopy(base_scene)
            try:
                for k, v in params.items():
                    set_path(scene, k, v)
            except PathError as e:
                row = dict(params, scene_hash=scene_hash({"base": base_scene, "params": params}),
                           status="failed", message=f"bad field path: {e}")
                prebuilt.append(row)
                continue
            jobs.append((scene_hash(scene), params, scene))
    else:
        fmu_bytes = Path(fmu).read_bytes()
        fmu_hash = hashlib.sha256(fmu_bytes).hexdigest()
        for params in table:
            key = json.dumps({"fmu": fmu_hash, "params": params, "stop": stop_time, "step": step_size},
                             sort_keys=True)
            jobs.append((hashlib.sha256(key.encode()).hexdigest(), params, None))

    done = read_results(out)
    _make_folder(out.parent, f"--out {out}")
    if series is not None:
        _make_folder(series, f"--series {series}")
    rows: list[dict] = done.to_dict("records") if len(done) else []
    if retry_failed and rows:
        rows = [r for r in rows if r.get("status") == "ok"]
    changed = len(rows) != len(done)
    have = {r["scene_hash"] for r in rows}
    for r in prebuilt:
        if r["scene_hash"] not in have:
            rows.append(r)
            have.add(r["scene_hash"])
            changed = True
    todo, seen = [], set()
    for h, params, scene in jobs:
        if h in have or h in seen:
            continue
        seen.add(h)
        todo.append((h, params, scene))
    skipped = len(jobs) - len(todo)
    print(f"sweep: {len(table)} rows, {skipped} already in {out} (or repeated), {len(todo)} to run",
          file=sys.stderr)
    if not todo:
        if changed or not out.exists():
            write_results(out, rows, first)
        return read_results(out)

    own = client is None
    if own:
        client = make_client(scheduler, workers, processes)
    try:
        if __name__ != "__main__":
            # Workers need this module's code but not this file: send it by value.
            import cloudpickle

            cloudpickle.register_pickle_by_value(sys.modules[__name__])
        if client.dashboard_link and progress:
            print(f"sweep: dashboard {client.dashboard_link}", file=sys.stderr)
        want_series = series is not None
        cache = str(out.with_name(out.name + ".closure-cache").resolve()) if closure_cache else None
        futures = []
        if base is not None:
            for h, params, scene in todo:
                futures.append(client.submit(run_scene, scene, params, str(mps), mode, want_series,
                                             timeout, threads, cache, key=f"mps-run-{h}",
                                             retries=retries, pure=False))
        else:
            blob = client.scatter(fmu_bytes, broadcast=True)
            for h, params, _ in todo:
                futures.append(client.submit(run_fmu, blob, fmu_hash, params, stop_time, step_size,
                                             want_series, key=f"mps-fmu-{h}", retries=retries,
                                             pure=False))
        bar = None
        if progress:
            bar = _start_progress(futures)
        n = 0
        last_write = 0.0
        for fut in as_completed(futures):
            n += 1
            try:
                row = fut.result()
            except Exception as e:  # noqa: BLE001 - e.g. KilledWorker after the retries
                h = fut.key.split("-", 2)[2]
                params = next(p for hh, p, _ in todo if hh == h)
                row = dict(params, scene_hash=h, status="failed",
                           message=f"task failed on the cluster: {type(e).__name__}: {e}")
            text = row.pop("_series", None)
            if text and series is not None:
                (series / f"{row['scene_hash'][:16]}.csv").write_text(text)
            rows.append(row)
            if not progress:
                pass
            elif bar is None:
                print(f"[{n}/{len(futures)}] {row['status']:6} {row['scene_hash'][:12]} "
                      f"{row.get('message', '')[:100]}", file=sys.stderr)
            now = time.monotonic()
            if now - last_write > 2.0 or n == len(futures):
                write_results(out, rows, first)
                last_write = now
        if bar is not None:
            bar.join(timeout=5)
    finally:
        if own:
            cluster = getattr(client, "cluster", None)
            client.close()
            if cluster is not None:
                cluster.close()
    return read_results(out)


def _start_progress(futures):
    """Dask's text progress bar, in a thread so that results are written as they arrive."""
    import threading

    try:
        from distributed.diagnostics.progressbar import progress as dask_progress
    except ImportError:
        return None
    if not sys.stderr.isatty():
        return None
    t = threading.Thread(target=lambda: dask_progress(futures, notebook=False), daemon=True)
    t.start()
    return t


# ---------------------------------------------------------------------------------------------
# Plots


def plot(df, x: str, ys: list[str], path: Path, hue: str | None = None) -> None:
    """Each y column against x (ok runs), one line per value of ``hue``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = df[df["status"] == "ok"] if "status" in df else df
    fig, axes = plt.subplots(len(ys), 1, figsize=(6, 3 * len(ys)), squeeze=False)
    for ax, y in zip(axes[:, 0], ys):
        if y not in ok:
            ax.set_title(f"{y}: no such column")
            continue
        groups = ok.groupby(hue) if hue and hue in ok else [(None, ok)]
        for name, g in groups:
            g = g.sort_values(x)
            ax.plot(g[x], g[y], "o-", label=f"{hue}={name}" if name is not None else None)
        ax.set_xlabel(x)
        ax.set_ylabel(y)
        if hue:
            ax.legend(fontsize=8)
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


# ---------------------------------------------------------------------------------------------


def _int_at_least(low: int):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"must be at least {low}, got {value}")
        return value

    parse.__name__ = "integer"
    return parse


def _seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"must be a finite number of seconds above 0, got {text}")
    return value


def make_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    src = ap.add_mutually_exclusive_group(required=True)
    src.add_argument("--base", type=Path, help="base scene (JSON; TOML if it ends in .toml)")
    src.add_argument("--fmu", type=Path, help="FMU to simulate with fmpy (columns: parameter names)")
    ap.add_argument("--table", type=Path, required=True,
                    help="CSV of variations, one column per field path or FMU parameter")
    ap.add_argument("--out", type=Path, required=True, help="results .csv or .parquet")
    ap.add_argument("--scheduler", help="address of an existing Dask scheduler (tcp://host:8786)")
    ap.add_argument("--workers", type=_int_at_least(1), default=max(1, os.cpu_count() or 1),
                    help="LocalCluster workers (default: the number of cores)")
    ap.add_argument("--mode", choices=["run", "case3"], default="run",
                    help="run: `mps run` (probes, frequency, peak); case3: `mps case3 --scene` "
                         "(contact, fracture, separation times, broken bonds)")
    ap.add_argument("--mps", type=Path, default=Path(os.environ.get("MPS_BIN", DEFAULT_MPS)),
                    help="the mps program (on a cluster: its path on the workers)")
    ap.add_argument("--series", type=Path, help="write each run's series to DIR/<hash>.csv")
    ap.add_argument("--threads", type=_int_at_least(1),
                    help="solver threads per run (RAYON_NUM_THREADS; default: all cores; "
                         "cores / workers avoids oversubscription)")
    ap.add_argument("--retries", type=_int_at_least(0), default=2,
                    help="re-runs of a task that raised (default: 2)")
    ap.add_argument("--timeout", type=_seconds, default=DEFAULT_TIMEOUT_S,
                    help="seconds per run of mps; a run still going then is killed and its row "
                         f"failed (default: {DEFAULT_TIMEOUT_S:g}; raise it for long runs)")
    ap.add_argument("--retry-failed", action="store_true", help="re-run rows recorded as failed")
    ap.add_argument("--stop-time", type=float, help="FMU: stop time (s)")
    ap.add_argument("--step-size", type=float, help="FMU: communication step (s)")
    ap.add_argument("--plot", type=Path, help="write a PNG of --y against --x")
    ap.add_argument("--x", help="plot: x column")
    ap.add_argument("--y", action="append", default=[], help="plot: y column (repeatable)")
    ap.add_argument("--hue", help="plot: one line per value of this column")
    ap.add_argument("--quiet", action="store_true", help="no progress output")
    return ap


def main(argv: list[str] | None = None) -> int:
    ap = make_parser()
    a = ap.parse_args(argv)
    if a.out.suffix not in (".csv", ".parquet"):
        ap.error(f"--out must end in .csv or .parquet, got {a.out}")
    if a.base is not None and not a.base.is_file():
        ap.error(f"--base {a.base}: no such file")
    if a.fmu is not None and not a.fmu.is_file():
        ap.error(f"--fmu {a.fmu}: no such file")
    if not a.table.is_file():
        ap.error(f"--table {a.table}: no such file")
    if a.base is not None and not a.scheduler and not Path(a.mps).is_file():
        ap.error(f"--mps {a.mps}: no such program (cargo build --release)")
    if a.plot and (not a.x or not a.y):
        ap.error("--plot needs --x and at least one --y")
    try:
        table = read_table(a.table)
        if a.plot:
            _make_folder(a.plot.parent, f"--plot {a.plot}")
        df = sweep(table, a.out, base=a.base, fmu=a.fmu, scheduler=a.scheduler, workers=a.workers,
                   mode=a.mode, mps=Path(a.mps).resolve() if not a.scheduler else a.mps,
                   series=a.series, retries=a.retries, timeout=a.timeout,
                   retry_failed=a.retry_failed, stop_time=a.stop_time, step_size=a.step_size,
                   progress=not a.quiet, threads=a.threads)
    except SweepError as e:  # bad input: one line, argparse's status 2, no traceback
        ap.exit(2, f"{ap.prog}: error: {e}\n")
    n_ok = int((df["status"] == "ok").sum()) if len(df) else 0
    print(f"sweep: {n_ok} ok, {len(df) - n_ok} failed, results in {a.out}", file=sys.stderr)
    if a.plot:
        if a.x not in df.columns:
            ap.exit(2, f"{ap.prog}: error: --x {a.x}: not a column of the results in {a.out} "
                       "(the table's columns, and the figures of the runs that went well)\n")
        plot(df, a.x, a.y, a.plot, a.hue)
        print(f"sweep: plot {a.plot}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
