#!/usr/bin/env bash
# Runs every test of the project on a fresh machine (Rust toolchain, gcc, Python 3.11 + pip):
# Rust unit and integration tests (physics, scenes, paper cases, FMI C ABI via libloading, the
# cbindgen header check, the C signature check), then the FMU tests (packing, modelDescription
# staleness, the C host example, fmpy validation and simulation), which install their own
# Python virtual environment, and last bounded fuzzing of the scene parser, FMU-state decoding
# and FMI call sequences (scripts/fuzz.sh, nightly toolchain).
#
# Three independent preparations run in the background while the Rust tests build and run
# (their logs: target/prep-*.log): the Python environment (mostly downloads), then the
# portable FMU binary (scripts/build-fmu-lib.sh) and the fuzz targets' build. They share the
# cores with the Rust build; the idle gaps of the build's serial tail and of the tests' long
# last tests are what they fill.
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TERM_COLOR=never
mkdir -p target
t0=$SECONDS
stamp() { echo "   ($(( (SECONDS - t0) / 60 )) min $(( (SECONDS - t0) % 60 )) s since the start)"; }
echo "== cargo fmt --check"
if cargo fmt --version >/dev/null 2>&1; then cargo fmt --all -- --check; else echo "rustfmt not installed: skipped"; fi

echo "== background: Python environment, portable FMU binary, fuzz build (target/prep-*.log)"
(
    scripts/setup_python.sh >target/prep-python.log 2>&1 &&
        nice -n 5 scripts/build-fmu-lib.sh >target/prep-fmu-lib.log 2>&1
) &
prep_fmu=$!
( nice -n 5 env FUZZ_BUILD_ONLY=1 scripts/fuzz.sh >target/prep-fuzz.log 2>&1 ) &
prep_fuzz=$!
# Neither outlives this script (an early failure kills them).
trap 'kill $prep_fmu $prep_fuzz 2>/dev/null || true' EXIT

echo "== cargo build --release"
cargo build --release
stamp
# Every stage runs whatever the ones before it gave (a failed test does not hide the others);
# each stage's exit status counts besides the summed test counts, so a build that fails before
# any test runs is a failure too.
echo "== cargo test --release"
set +e
cargo test --release --no-fail-fast -- --include-ignored 2>&1 | tee target/cargo-test.log
rust_rc=${PIPESTATUS[0]}
set -e
stamp
echo "== FMU tests"
if ! wait $prep_fmu; then
    echo "the Python environment or the portable FMU binary failed:"
    tail -n 30 target/prep-python.log target/prep-fmu-lib.log
    echo "FMU tests: 0 passed, 1 failed" | tee target/fmu-test.log
    fmu_rc=1
else
    set +e
    scripts/fmu_tests.sh 2>&1 | tee target/fmu-test.log
    fmu_rc=${PIPESTATUS[0]}
    set -e
fi
stamp
echo "== fuzz"
# cargo-fuzz targets (nightly), about 20 s each; fails on any crash. See scripts/fuzz.sh.
wait $prep_fuzz || true
cat target/prep-fuzz.log
set +e
scripts/fuzz.sh 2>&1 | tee target/fuzz-test.log
fuzz_rc=${PIPESTATUS[0]}
set -e
stamp
passed=$(grep -hEo '[0-9]+ passed' target/cargo-test.log target/fmu-test.log target/fuzz-test.log | awk '{s+=$1} END {print s+0}')
failed=$(grep -hEo '[0-9]+ failed' target/cargo-test.log target/fmu-test.log target/fuzz-test.log | awk '{s+=$1} END {print s+0}')
echo "all: $passed passed, $failed failed"
for stage in "Rust tests:$rust_rc" "FMU tests:$fmu_rc" "fuzz:$fuzz_rc"; do
    if [ "${stage##*:}" != 0 ]; then
        echo "${stage%:*} exited with status ${stage##*:}"
        failed=$((failed > 0 ? failed : 1))
    fi
done
[ "$failed" = 0 ]
