"""Resolution study of the cantilever scene: static tip deflection under a tip load against
Timoshenko beam theory, for n particles through the thickness.

    .venv/bin/python examples/coupling/resolution.py [--n 8 12 16]

Each n: the scene (make_scene.py) packed with `mps pack` into target/coupling/, the FMU run with
mass-proportional damping (60 1/s, about critical for the first mode) under a tip force of
-1 kN/m until static; the load region's mean displacement is compared with the Timoshenko
deflection at the load region (x = a = L - dp/2; plane strain, shear correction 5/6).
"""
import argparse
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import make_scene  # noqa: E402
from cosim import Fmu  # noqa: E402
from reference import Beam  # noqa: E402

import json  # noqa: E402
import time  # noqa: E402

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))


def static_deflection(fmu: str, force: float, damping: float = 60.0, H: float = 0.005,
                      tol: float = 2e-4) -> tuple[float, float, float]:
    """Runs the damped beam FMU under a constant tip force until the tip displacement changes by
    less than tol (relative) over 0.1 s; returns (tip.uy, clamp.reaction_y, wall seconds)."""
    b = Fmu(fmu, "beam")
    b.init(**{"solver.damping": damping})
    b.set(**{"tip.fy": force})
    t, last, t0 = 0.0, None, time.perf_counter()
    while True:
        for _ in range(int(round(0.1 / H))):
            b.s.doStep(t, H)
            t += H
        u, r = b.get("tip.uy", "clamp.reaction_y")
        if last is not None and abs(u - last) < tol * abs(u):
            break
        last = u
    b.free()
    return u, r, time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, nargs="*", default=[8, 12, 16])
    a = ap.parse_args()
    out = os.path.join(ROOT, "target", "coupling")
    os.makedirs(out, exist_ok=True)
    print("| n through h | dp (m) | particles | tip deflection (mm) | Timoshenko (mm) | error |")
    print("|---|---|---|---|---|---|")
    for n in a.n:
        name = f"cantilever_n{n}"
        js = os.path.join(out, name + ".json")
        with open(js, "w") as f:
            json.dump(make_scene.scene(n, name), f)
        fmu = os.path.join(out, name + ".fmu")
        subprocess.run([os.path.join(ROOT, "target", "release", "mps"), "pack", js, "--out", fmu],
                       check=True, capture_output=True)
        u, _, _ = static_deflection(fmu, -1000.0)
        ref = -Beam.from_scene(js).tip_deflection(1000.0)
        particles = int(round(1.0 / (0.1 / n))) * n
        print(f"| {n} | {0.1 / n:.5f} | {particles} | {u * 1e3:.4f} | {ref * 1e3:.4f} | {u / ref - 1:+.2%} |")


if __name__ == "__main__":
    main()
