#!/usr/bin/env python3
"""Throughput of tools/sweep.py: runs per hour of case 3 (scenes/case3_collision.json, dp 0.05) on a
LocalCluster of 1 and of 2 workers (one solver thread per run), and the parallel efficiency
rate(2) / (2 rate(1)). A run is shortened to --end seconds of simulated time; the rate of full
1.7 s runs is scaled by end / 1.7 (the cost per simulated second is about constant once the cube
is in contact; the first 0.07 s are cheaper, so the scaled figure is slightly optimistic).

    python tools/sweep_bench.py --end 0.4 --runs 4
"""
import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import sweep  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--end", type=float, default=0.4, help="simulated time per run (s)")
    ap.add_argument("--runs", type=int, default=4, help="runs per measurement")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--mps", type=Path, default=sweep.DEFAULT_MPS)
    a = ap.parse_args()
    base = sweep.ROOT / "scenes" / "case3_collision.json"
    full = 1.7
    results = {}
    for w in a.workers:
        # Distinct scenes (eps_max 0.080, 0.0801, ...) so that no run is skipped as done.
        table = [{"end_time": a.end, "solver.fracture_strain": round(0.08 + 1e-4 * (k + 10 * w), 6)}
                 for k in range(a.runs)]
        with tempfile.TemporaryDirectory() as d:
            out = Path(d) / "bench.csv"
            t0 = time.perf_counter()
            df = sweep.sweep(table, out, base=base, workers=w, mode="case3", mps=a.mps.resolve(),
                             threads=1, progress=False)
            wall = time.perf_counter() - t0
        ok = int((df.status == "ok").sum())
        per_run = df["elapsed_s"].mean()
        rate = ok / wall * 3600 * (a.end / full)
        results[w] = rate
        print(f"workers {w}: {ok}/{len(df)} ok, {a.runs} runs of {a.end} s in {wall:.1f} s wall "
              f"(mean {per_run:.1f} s per run, {df['steps'].mean():.0f} steps): "
              f"{ok / wall * 3600:.0f} short runs/h = {rate:.0f} full (1.7 s) runs/h")
    if 1 in results and 2 in results:
        print(f"parallel efficiency 1 -> 2 workers: {results[2] / (2 * results[1]):.2f} "
              f"(speed-up {results[2] / results[1]:.2f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
