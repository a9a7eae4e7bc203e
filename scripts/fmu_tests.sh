#!/usr/bin/env bash
# FMU tests end to end: builds the FMU binary (scripts/build-fmu-lib.sh: stripped, glibc 2.17),
# packs scenes/*.json and tests/data/small*.json into target/fmu/*.fmu, checks
# modelDescription/<scene>.xml against the generated XML, compiles and runs the example C host on
# a packed FMU, and runs the fmpy tests (tests/python, including the binary's portability) in .venv.
# Exits non-zero on any failure; the last line is pytest's summary. PYTEST_ARGS is passed to pytest
# (e.g. PYTEST_ARGS=--durations=20 for the slowest tests).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
out="$root/target/fmu"

echo "== python environment"
scripts/setup_python.sh

echo "== building the FMU binary (glibc 2.17, stripped)"
# FMU_LIB: a binary scripts/build-fmu-lib.sh has built already (scripts/test-all.sh).
if [ -n "${FMU_LIB:-}" ]; then
    lib="$FMU_LIB"
else
    lib="$(scripts/build-fmu-lib.sh | tail -n 1)"
fi
echo "$lib: $(stat -c %s "$lib") bytes"

echo "== packing FMUs into $out"
# The release `mps` binary: MPS_BIN (scripts/test-all.sh passes the one it built, so that no
# cargo call waits for the build directory that its running Rust tests hold), else built here.
mps="${MPS_BIN:-}"
if [ -z "$mps" ]; then
    cargo build --release --quiet --bin mps
    mps="$root/target/release/mps"
fi
rm -rf "$out" && mkdir -p "$out"
shopt -s nullglob
scenes=(scenes/*.json)
if (( ${#scenes[@]} == 0 )); then
    echo "no scenes/*.json" >&2
    exit 1
fi
# The paper's scenes: packed, and modelDescription/<name>.xml must be up to date.
"$mps" pack --lib "$lib" --out-dir "$out" \
    --check-xml modelDescription "${scenes[@]}"
# The small test scenes of the FMI layer (tests/data/clamped_cube.json is the Rust tests' slow
# set-up, 8 s of closure, which pack would build once more for nothing).
"$mps" pack --lib "$lib" --out-dir "$out" tests/data/small*.json

echo "== example C host"
fmu="$out/$(basename "${scenes[-1]}" .json).fmu"
log="$root/target/c_host/run.log"
mkdir -p "$root/target/c_host"
make -s -C examples/c_host run FMU="$fmu" STOP=0.02 STEP=0.001 | tee "$log"
grep -q "^last successful time 0.02" "$log" || { echo "C host did not reach t = 0.02" >&2; exit 1; }

echo "== fmpy tests"
# Two pytest-xdist workers, each test file on one of them (its module fixtures built once): the
# files are single-threaded Python with FMUs on one or two threads, and test_fmu.py's two full
# case 3 runs alone take about 47 s, so one process is a long single-threaded chain at the end of
# scripts/test-all.sh. FMU_TEST_WORKERS=0 runs them in this process.
MPS_FMU_DIR="$out" .venv/bin/python -m pytest tests/python -q -p no:cacheprovider \
    -n "${FMU_TEST_WORKERS:-2}" --dist loadfile ${PYTEST_ARGS:-}
