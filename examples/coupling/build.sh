#!/usr/bin/env bash
# Builds the coupling example's FMUs into target/coupling/: the beam (scenes/cantilever_payload.json
# packed with `mps pack`), the payload and the wave load (pythonfmu), next to which run_libcosim.py
# writes its OspSystemStructure.xml. Needs the project's .venv (scripts/setup_python.sh).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$root"
out="$root/target/coupling"
mkdir -p "$out"
scripts/setup_python.sh
cargo build --release --quiet
target/release/mps pack scenes/cantilever_payload.json --out "$out/cantilever_payload.fmu"
for model in payload wave; do
    .venv/bin/pythonfmu build -f "examples/coupling/$model.py" -d "$out" > /dev/null
done
ls "$out"/*.fmu
