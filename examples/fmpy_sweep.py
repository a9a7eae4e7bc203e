#!/usr/bin/env python3
"""Run one FMU many times from fmpy, reusing one instance: a sweep over a parameter.

    scripts/setup_python.sh                        # .venv with fmpy (once)
    .venv/bin/python examples/fmpy_sweep.py FMU [--param NAME] [--values 1e6,2e6,4e6]
        [--output tip.uz] [--stop 0.05] [--step 0.001]

Instantiates the FMU once, then for each value calls fmpy.simulate_fmu with the instance
(fmu_instance) and the value as a start value, and resets the instance after each run. The
instance builds its model once per parameter set and takes the set-up's longest stage, the
default operator's closure, from the FMU (`mps pack` ships it) or from its earlier build (no
parameter changes the geometry); a run with the parameters of the run before rewinds the model
built for them instead of building. Prints,
per run, the value, the output's final and largest absolute value and the run's wall time.
Default --param: the first body's Young's modulus.
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np
from fmpy import extract, instantiate_fmu, read_model_description, simulate_fmu


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("fmu", help="an FMU packed by `mps pack`")
    ap.add_argument("--param", help="parameter to vary (default: the first body's .young)")
    ap.add_argument("--values", default="1e6,2e6,4e6,1e6", help="comma-separated values")
    ap.add_argument("--output", help="output to report (default: the first Real output)")
    ap.add_argument("--stop", type=float, default=0.05, help="stop time (s)")
    ap.add_argument("--step", type=float, default=0.001, help="communication step (s)")
    args = ap.parse_args()
    md = read_model_description(args.fmu)
    names = [v.name for v in md.modelVariables]
    param = args.param or next((n for n in names if n.endswith(".young")), None)
    output = args.output or next(
        (v.name for v in md.modelVariables if v.causality == "output" and v.type == "Real"), None)
    if param not in names or output not in names:
        print(f"no parameter {param!r} or output {output!r} in {args.fmu}", file=sys.stderr)
        return 2
    values = [float(v) for v in args.values.split(",")]
    unzipped = extract(args.fmu)
    inst = instantiate_fmu(unzipped, md, "CoSimulation")
    print(f"{param:>24} {output + ' end':>16} {output + ' max|.|':>16} {'wall (s)':>9}")
    try:
        for value in values:
            t0 = time.perf_counter()
            res = simulate_fmu(unzipped, model_description=md, fmu_instance=inst,
                               stop_time=args.stop, output_interval=args.step,
                               output=[output], start_values={param: value})
            wall = time.perf_counter() - t0
            inst.reset()
            y = res[output]
            print(f"{value:24.6g} {y[-1]:16.6e} {np.max(np.abs(y)):16.6e} {wall:9.3f}")
    finally:
        inst.freeInstance()
    return 0


if __name__ == "__main__":
    sys.exit(main())
