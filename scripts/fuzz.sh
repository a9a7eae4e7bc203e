#!/usr/bin/env bash
# Bounded fuzzing of mps-solid (fuzz/): installs cargo-fuzz if missing, builds the targets with
# the nightly toolchain, replays the committed corpora and regressions, then fuzzes each target
# for FUZZ_SECONDS (default 20). Exits non-zero on any crash, hang or failed build; the last line
# is "fuzz: N passed, M failed" (N = targets that ran clean).
#
#   FUZZ_SECONDS=60 scripts/fuzz.sh          # longer runs
#   FUZZ_TARGETS="scene" scripts/fuzz.sh     # some targets only
#   FUZZ_UPDATE_CORPUS=1 scripts/fuzz.sh     # merge what the run found into fuzz/corpus
#   MPS_FUZZ_ALL=1 scripts/fuzz.sh           # also inputs of known open defects (fuzz/README.md)
#   FUZZ_BUILD_ONLY=1 scripts/fuzz.sh        # build the targets and stop (test-all.sh does this early)
#
# A crash leaves its input in fuzz/artifacts/<target>/; reproduce it with
#   fuzz/target/<host>/release/<target> fuzz/artifacts/<target>/crash-...
# and, once fixed, keep the input in fuzz/regressions/<target>/ (replayed on every run).
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
seconds=${FUZZ_SECONDS:-20}
targets=${FUZZ_TARGETS:-scene fmu_state closure fmi_calls}
export CARGO_TERM_COLOR=never

if ! cargo +nightly --version >/dev/null 2>&1; then
    echo "fuzz: no nightly toolchain (cargo-fuzz needs one: rustup toolchain install nightly)"
    echo "fuzz: 0 passed, 1 failed"
    exit 1
fi
t0=$SECONDS
if ! cargo fuzz --version >/dev/null 2>&1; then
    echo "== installing cargo-fuzz"
    # --debug: cargo-fuzz only drives cargo and the targets; unoptimised it installs in about a
    # third of the time (273 s on a fresh 2-core machine, optimised).
    # No debug info either (CARGO_PROFILE_DEV_DEBUG=0): a 6.6 MB binary instead of 30 MB.
    if ! CARGO_PROFILE_DEV_DEBUG=0 cargo install cargo-fuzz --locked --debug; then
        echo "fuzz: cannot install cargo-fuzz"
        echo "fuzz: 0 passed, 1 failed"
        exit 1
    fi
fi
t1=$SECONDS
echo "cargo-fuzz: $(cargo fuzz --version) (install: $((t1 - t0)) s)"

# Release build with libFuzzer's coverage instrumentation and debug assertions (overflow checks);
# no sanitizer: the crate's unsafe code is only the C ABI, which the targets do not call.
# codegen-units 4 as the main crate's release profile: cargo-fuzz's default of 1 makes the
# cold build of mps-solid one long single-threaded compile.
if ! cargo +nightly fuzz build -s none --codegen-units 4; then
    echo "fuzz: the targets do not build"
    echo "fuzz: 0 passed, 1 failed"
    exit 1
fi
if [ "${FUZZ_BUILD_ONLY:-0}" = 1 ]; then
    echo "fuzz: targets built ($((SECONDS - t1)) s)"
    exit 0
fi
host=$(rustc +nightly -vV | sed -n 's/^host: //p')
bin="$root/fuzz/target/$host/release"
t2=$SECONDS
echo "build: $((t2 - t1)) s"

# Fresh seeds (real FMU states in the current format, the scenes of the repository).
seeds="$root/target/fuzz-seeds"
rm -rf "$seeds"
MPS_FUZZ_SEEDS="$seeds" "$bin/fmu_state" >/dev/null 2>&1 || {
    echo "fuzz: writing the seeds failed"
    MPS_FUZZ_SEEDS="$seeds" "$bin/fmu_state" || true
    echo "fuzz: 0 passed, 1 failed"
    exit 1
}

passed=0
failed=0
for t in $targets; do
    corpus="$root/fuzz/corpus/$t"
    regressions="$root/fuzz/regressions/$t"
    work="$root/target/fuzz-work/$t"
    artifacts="$root/fuzz/artifacts/$t"
    log="$root/target/fuzz-$t.log"
    mkdir -p "$corpus" "$regressions" "$artifacts" "$seeds/$t"
    rm -rf "$work"
    mkdir -p "$work"
    extra=()
    if [ -f "$root/fuzz/dict/$t.dict" ]; then extra+=("-dict=$root/fuzz/dict/$t.dict"); fi
    # Call sequences: long inputs from the start (libFuzzer's slow length ramp would keep
    # them at a few calls for the whole bounded run).
    if [ "$t" = fmi_calls ]; then extra+=(-len_control=0 -max_len=512); fi
    # Each input of the regressions once, then fuzzing from the committed corpus and the fresh
    # seeds, whose every input libFuzzer runs first, whatever the time budget (new inputs go to
    # the work directory, never into the repository). The corpus is not replayed separately
    # besides: for fmi_calls that replay alone took the whole budget.
    ok=1
    nreplay=$(find "$corpus" "$regressions" -type f | wc -l)
    if ! "$bin/$t" -runs=0 -timeout=30 -artifact_prefix="$artifacts/" "$regressions" \
        >"$log" 2>&1; then
        ok=0
        echo "$t: replay of the regressions FAILED (log: $log)"
    fi
    if [ $ok = 1 ] && ! "$bin/$t" "$work" "$corpus" "$seeds/$t" "${extra[@]}" \
        -max_total_time="$seconds" -timeout=30 -rss_limit_mb=2048 \
        -artifact_prefix="$artifacts/" -print_final_stats=1 >>"$log" 2>&1; then
        ok=0
        echo "$t: fuzzing FAILED (log: $log)"
    fi
    runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
    found=$(find "$work" -type f | wc -l)
    if [ $ok = 1 ]; then
        passed=$((passed + 1))
        echo "$t: ok, $nreplay corpus and regression inputs replayed, ${runs:-0} runs in ${seconds} s, $found new inputs"
    else
        failed=$((failed + 1))
        grep -E "panicked at|^thread|ERROR: libFuzzer|SUMMARY|Test unit written|timeout" "$log" | head -8 || true
    fi
    if [ "${FUZZ_UPDATE_CORPUS:-0}" = 1 ] && [ $ok = 1 ]; then
        "$bin/$t" -merge=1 "$corpus" "$work" >>"$log" 2>&1
        echo "$t: corpus now $(find "$corpus" -type f | wc -l) inputs, $(du -sk "$corpus" | cut -f1) KB"
    fi
done
echo "fuzz time: $((SECONDS - t0)) s (install $((t1 - t0)) s, build $((t2 - t1)) s, runs $((SECONDS - t2)) s)"
echo "fuzz: $passed passed, $failed failed"
[ "$failed" = 0 ]
