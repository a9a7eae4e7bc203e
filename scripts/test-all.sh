#!/usr/bin/env bash
# Runs every test of the project on a fresh machine (Rust toolchain, gcc, Python 3.11 + pip):
# Rust unit and integration tests (physics, scenes, paper cases, FMI C ABI via libloading, the
# cbindgen header check, the C signature check), then the FMU tests (packing, modelDescription
# staleness, the C host example, fmpy validation and simulation), which install their own
# Python virtual environment, and last bounded fuzzing of the scene parser, FMU-state decoding
# and FMI call sequences (scripts/fuzz.sh, nightly toolchain).
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TERM_COLOR=never
echo "== cargo fmt --check"
if cargo fmt --version >/dev/null 2>&1; then cargo fmt --all -- --check; else echo "rustfmt not installed: skipped"; fi
echo "== cargo build --release"
cargo build --release
echo "== cargo test --release"
cargo test --release --no-fail-fast -- --include-ignored 2>&1 | tee target/cargo-test.log
echo "== FMU tests"
scripts/fmu_tests.sh 2>&1 | tee target/fmu-test.log
echo "== fuzz"
# cargo-fuzz targets (nightly), about 20 s each; fails on any crash. See scripts/fuzz.sh.
scripts/fuzz.sh 2>&1 | tee target/fuzz-test.log
passed=$(grep -hEo '[0-9]+ passed' target/cargo-test.log target/fmu-test.log target/fuzz-test.log | awk '{s+=$1} END {print s+0}')
failed=$(grep -hEo '[0-9]+ failed' target/cargo-test.log target/fmu-test.log target/fuzz-test.log | awk '{s+=$1} END {print s+0}')
echo "all: $passed passed, $failed failed"
