"""Runs the beam + payload (+ wave load) co-simulation with the plain fmpy master of cosim.py.

    .venv/bin/python examples/coupling/run_fmpy.py [--fmu-dir target/coupling] [--step 0.001]
        [--stop 0.5] [--algorithm gauss-seidel|jacobi] [--order 1|2] [--wave]
        [--payload m=10 k=40000 c=0 x0=-0.01 g=0]

Build the FMUs first with examples/coupling/build.sh. --order 2 (Gauss-Seidel only) extrapolates
the payload's force into the beam with fmi2SetRealInputDerivatives and moves the payload's
attachment linearly over the step; --wave adds the irregular wave load (wave.py) on `mid`.
"""
import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cosim import run, total_energy  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fmu-dir", default="target/coupling")
    ap.add_argument("--step", type=float, default=0.001)
    ap.add_argument("--stop", type=float, default=0.5)
    ap.add_argument("--algorithm", default="gauss-seidel", choices=["gauss-seidel", "jacobi"])
    ap.add_argument("--order", type=int, default=2, choices=[1, 2])
    ap.add_argument("--wave", action="store_true")
    ap.add_argument("--payload", nargs="*", default=["m=10", "k=40000", "x0=-0.01"],
                    help="payload start values name=value")
    a = ap.parse_args()
    payload = {k: float(v) for k, v in (s.split("=") for s in a.payload)}
    d = a.fmu_dir
    r = run(os.path.join(d, "cantilever_payload.fmu"), os.path.join(d, "Payload.fmu"), a.step, a.stop,
            a.algorithm, payload=payload, order=a.order,
            wave_fmu=os.path.join(d, "Wave.fmu") if a.wave else None)
    e = total_energy(r)
    print(f"fmpy {a.algorithm} (order {a.order}) H = {a.step} s to t = {r.t[-1]:.4f} s in {r.wall:.2f} s wall")
    print(f"tip.uy = {r['tip.uy'][-1]:.6e} m, payload force = {r['force'][-1]:.4f} N/m, "
          f"clamp reaction = {r['clamp.reaction_y'][-1]:.4f} N/m, energy {e[0]:.5f} -> {e[-1]:.5f} J/m")


if __name__ == "__main__":
    main()
