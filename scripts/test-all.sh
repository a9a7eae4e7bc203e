#!/usr/bin/env bash
# Runs every test of the project on a fresh machine (Rust toolchain, gcc, Python 3.11 + pip):
# Rust unit and integration tests (physics, scenes, paper cases, FMI C ABI via libloading, the
# cbindgen header check, the C signature check), the FMU tests (packing, modelDescription
# staleness, the C host example, fmpy validation and simulation), which install their own
# Python virtual environment, and bounded fuzzing of the scene parser, FMU-state decoding, the shipped closure and
# FMI call sequences (scripts/fuzz.sh, nightly toolchain).
#
# Two independent preparations run in the background while the Rust tests build (their logs:
# target/prep-*.log): the Python environment (mostly downloads), then the portable FMU binary
# (scripts/build-fmu-lib.sh); and the fuzz targets' build. They share the cores with the Rust
# build and fill the idle gaps of its serial tail. Then the three test stages run side by side.
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TERM_COLOR=never
mkdir -p target
t0=$SECONDS
stamp() { echo "   ($(( (SECONDS - t0) / 60 )) min $(( (SECONDS - t0) % 60 )) s since the start)"; }
echo "== cargo fmt --check"
if cargo fmt --version >/dev/null 2>&1; then cargo fmt --all -- --check; else echo "rustfmt not installed: skipped"; fi

echo "== background: Python environment, portable FMU binary, fuzz build (target/prep-*.log)"
# Each job leaves its exit status in target/<job>.rc when it ends (stale ones removed first).
rm -f target/prep-fmu.rc target/prep-fuzz.rc target/cargo-test.rc target/fmu-test.rc \
    target/fuzz-test.rc
(
    scripts/setup_python.sh >target/prep-python.log 2>&1 &&
        nice -n 5 scripts/build-fmu-lib.sh >target/prep-fmu-lib.log 2>&1
    echo $? >target/prep-fmu.rc
) &
prep_fmu=$!
# The fuzz build at the release build's priority: its chain ends in 70 s of single-threaded
# fuzzing, which must start early enough to run beside the other tests (niced, it ended last,
# 38 s after everything else, at 12 min 52 s on c9cd58c).
(
    env FUZZ_BUILD_ONLY=1 scripts/fuzz.sh >target/prep-fuzz.log 2>&1
    echo $? >target/prep-fuzz.rc
) &
prep_fuzz=$!
# Waits until the job that writes target/$1.rc has ended.
await() { while [ ! -f "target/$1.rc" ]; do sleep 1; done; }
# No job outlives this script (an early failure or an interrupt kills them).
trap 'kill $(jobs -p) 2>/dev/null || true' EXIT

echo "== cargo test --release --no-run (the library, the mps binary and every test in one build)"
# One cargo invocation builds the release library (rlib and cdylib), the `mps` binary
# (target/release/mps) and the test targets in one graph, so the test crates compile beside
# the library's serial tail. No `cargo build --release` besides: the tests' dev-dependencies
# unify some features differently, so each of the two would compile the library again for
# the other (2 min 8 s on a fresh 2-core clone).
cargo test --release --no-run
stamp
# The three test stages run side by side: the Rust tests use both cores most of the time, the
# FMU tests (one Python process) and bounded fuzzing (one libFuzzer process) fill what they
# leave. Each writes its own log, printed whole when it ends. Every stage runs whatever the
# others give (a failed test does not hide the others); each stage's exit status counts
# besides the summed test counts, so a build that fails before any test runs is a failure too.
echo "== Rust tests, FMU tests and fuzzing, side by side (target/cargo-test.log, fmu-test.log, fuzz-test.log)"
# The Rust tests run two at a time (libtest's threads, one per core), each on one rayon thread:
# with two tests on two cores, a test's loops on two threads would only wait for each other
# (the suite alone: 129 s wall and 32 s of system time on two threads per test, 102 s and 0.7 s
# on one). The tests of thread-count independence and the memory measurements build their own
# pools of 1-8 threads; the FMU instances keep their worker threads (MPS_FMI_THREADS unset).
(
    RAYON_NUM_THREADS=1 cargo test --release --no-fail-fast -- --include-ignored \
        >target/cargo-test.log 2>&1
    echo $? >target/cargo-test.rc
) &
rust_job=$!
(
    # The FMU tests need the Python environment and the portable binary (background above).
    await prep-fmu
    if [ "$(cat target/prep-fmu.rc)" != 0 ]; then
        {
            echo "the Python environment or the portable FMU binary failed:"
            tail -n 30 target/prep-python.log target/prep-fmu-lib.log
            echo "FMU tests: 0 passed, 1 failed"
        } >target/fmu-test.log 2>&1
        echo 1 >target/fmu-test.rc
    else
        # The binaries built already: no cargo call here (cargo would wait for the build
        # directory that the running Rust tests hold).
        # One worker thread per FMU instance, for the same reason as the Rust tests' one rayon
        # thread (fmpy's tests alone: 164 CPU-s on two threads, 137 on one); the unload test
        # and the Rust tests (fmi_host, unload) keep the instances' worker threads.
        MPS_FMI_THREADS=1 MPS_BIN="$PWD/target/release/mps" \
            FMU_LIB="$(tail -n 1 target/prep-fmu-lib.log)" \
            nice -n 5 scripts/fmu_tests.sh >target/fmu-test.log 2>&1
        echo $? >target/fmu-test.rc
    fi
) &
fmu_job=$!
(
    # cargo-fuzz targets (nightly), about 20 s each; fails on any crash. See scripts/fuzz.sh.
    await prep-fuzz
    {
        cat target/prep-fuzz.log
        nice -n 5 scripts/fuzz.sh
    } >target/fuzz-test.log 2>&1
    echo $? >target/fuzz-test.rc
) &
fuzz_job=$!
wait $rust_job || true
echo "== cargo test --release -- --include-ignored"
cat target/cargo-test.log
stamp
wait $fmu_job || true
echo "== FMU tests"
cat target/fmu-test.log
stamp
wait $fuzz_job || true
echo "== fuzz"
cat target/fuzz-test.log
stamp
rust_rc=$(cat target/cargo-test.rc 2>/dev/null || echo 1)
fmu_rc=$(cat target/fmu-test.rc 2>/dev/null || echo 1)
fuzz_rc=$(cat target/fuzz-test.rc 2>/dev/null || echo 1)
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
