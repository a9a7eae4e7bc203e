#!/usr/bin/env python3
"""Pack a scene into an FMU and drive it from fmpy, step by step, as a co-simulation master does.

    scripts/setup_python.sh                        # .venv with fmpy (once)
    .venv/bin/python examples/fmpy_drive.py [SCENE] [--stop 0.2] [--step 0.001]

Packs SCENE (default tests/data/small2d.json) with the portable FMU binary
(scripts/build-fmu-lib.sh) into target/examples/<name>.fmu, lists its variables, then runs it
with fmpy's FMU2Slave: at each communication step it sets a tip load that grows in time and
reads the tip probe and the energies. For a one-call run, fmpy.simulate_fmu does the same.
"""
from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

ROOT = Path(__file__).resolve().parent.parent


def pack(scene: Path) -> Path:
    lib = subprocess.run([str(ROOT / "scripts" / "build-fmu-lib.sh")], check=True,
                         stdout=subprocess.PIPE, text=True).stdout.strip().splitlines()[-1]
    out = ROOT / "target" / "examples"
    out.mkdir(parents=True, exist_ok=True)
    subprocess.run(["cargo", "run", "--release", "--quiet", "--", "pack", str(scene),
                    "--lib", lib, "--out-dir", str(out)], check=True, cwd=ROOT)
    name = next(l for l in scene.read_text().splitlines() if '"name"' in l).split('"')[3]
    return out / f"{name}.fmu"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", nargs="?", type=Path, default=ROOT / "tests" / "data" / "small2d.json")
    ap.add_argument("--stop", type=float, default=0.2, help="stop time (s)")
    ap.add_argument("--step", type=float, default=0.001, help="communication step (s)")
    args = ap.parse_args()
    fmu = pack(args.scene)
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    print(f"{fmu.name}: {len(md.modelVariables)} variables")
    for v in md.modelVariables:
        if v.causality in ("input", "output"):
            print(f"  {v.causality:6} {v.name:24} {v.unit or '':6} {v.description or ''}")
    unzipped = extract(str(fmu))
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipped,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="beam")
    slave.instantiate()
    slave.setupExperiment(startTime=0.0, stopTime=args.stop)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    load = vr.get("tip_load.fy")
    t, n = 0.0, round(args.stop / args.step)
    print("t (s)     tip u_y (m)     strain energy (J/m)")
    for k in range(n):
        if load is not None:
            slave.setReal([load], [-2.0 * t / args.stop])  # N per metre of depth, ramped
        slave.doStep(currentCommunicationPoint=t, communicationStepSize=args.step)
        t = (k + 1) * args.step
        if (k + 1) % max(1, n // 10) == 0:
            uy, e = slave.getReal([vr["tip.uy"], vr["strain_energy"]])
            print(f"{t:.3f}    {uy:+.6e}    {e:.6e}")
    slave.terminate()
    slave.freeInstance()
    return 0


if __name__ == "__main__":
    sys.exit(main())
