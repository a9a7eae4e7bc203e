#!/usr/bin/env bash
# Builds the binary shipped in FMUs and prints its path (last line of stdout): the cdylib with
# the `fmu` profile (release code, no debug info, stripped), linked by cargo-zigbuild against
# glibc 2.17 so that it loads on any x86_64 Linux with glibc >= 2.17 (RHEL/CentOS 7 and later,
# Ubuntu 14.04 and later). Its tools (cargo-zigbuild and ziglang, in .venv) are installed by
# scripts/setup_python.sh, idempotently. Build output goes to stderr.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
target=x86_64-unknown-linux-gnu
glibc=2.17
scripts/setup_python.sh >&2
# cargo-zigbuild runs zig through `python -m ziglang` of the first python on PATH: the venv's.
# Without the `studies` feature: the FMU carries the product only (src/lib.rs).
PATH="$root/.venv/bin:$PATH" cargo zigbuild --quiet --profile fmu --lib --no-default-features \
    --features parallel --target "$target.$glibc" >&2
lib="$root/target/$target/fmu/libmps_solid.so"
[[ -f "$lib" ]] || { echo "build-fmu-lib: $lib was not built" >&2; exit 1; }
echo "$lib"
