#!/usr/bin/env bash
# Creates .venv at the repository root with the pinned Python packages of the FMU tests
# (fmpy, pytest with pytest-xdist, numpy; cargo-zigbuild and ziglang, which scripts/build-fmu-lib.sh uses to link
# the FMU binary against glibc 2.17; pythonfmu and libcosimpy for examples/coupling;
# dask[distributed], pandas, pyarrow and matplotlib for the parameter sweeps of tools/sweep.py
# and the reports). Idempotent: a venv whose pins match is left alone (fast path).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$root/.venv"
pins=(fmpy==0.3.32 pytest==8.3.5 pytest-xdist==3.8.0 numpy==2.2.6 cargo-zigbuild==0.24.1 ziglang==0.15.2
      pythonfmu==0.7.0 libcosimpy==0.0.6
      "dask[distributed]==2026.8.0" pandas==3.1.1 pyarrow==26.0.1 matplotlib==3.11.2)
stamp="$venv/.mps-pins"
want="${pins[*]}"
if [[ -x "$venv/bin/python" && -f "$stamp" && "$(cat "$stamp")" == "$want" ]]; then
    exit 0
fi
python3 -m venv "$venv"
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check "${pins[@]}"
"$venv/bin/python" -c "import fmpy, pytest, xdist, numpy, ziglang, pythonfmu, libcosimpy, dask.distributed, pandas, pyarrow, matplotlib"
echo "$want" > "$stamp"
echo "python environment ready: $venv ($want)"
