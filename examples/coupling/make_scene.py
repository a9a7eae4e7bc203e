"""Writes the cantilever scene of the coupling examples (scenes/cantilever_payload.json).

A plane-strain 2D cantilever, L x h, clamped at x = 0 like case 2 (a layer of particles on the
clamp face and two wall layers behind it, all clamped), a load region on the last column of
particles (x = L - dp/2) and a probe at the tip. `n` is the number of particles through the
thickness; the resolution study (resolution.py) writes the same scene at other n.

    python examples/coupling/make_scene.py [--n 16] [--out scenes/cantilever_payload.json]
"""
import argparse
import json
import os
from pathlib import Path

LENGTH = 1.0  # m
HEIGHT = 0.1  # m
DENSITY = 1000.0  # kg/m3
YOUNG = 1.0e8  # Pa
POISSON = 0.3


def scene(n: int, name: str = "cantilever_payload") -> dict:
    dp = HEIGHT / n
    h2 = HEIGHT / 2
    return {
        "name": name,
        "description": (
            f"Coupling example (examples/coupling): plane-strain cantilever L = {LENGTH} m, "
            f"h = {HEIGHT} m ({n} particles through the thickness), rho {DENSITY}, E {YOUNG:g}, "
            f"nu {POISSON}; clamped at x = 0 (the layer on the clamp face and 2 wall layers behind "
            "it), no gravity by default (gravity_source 2, inputs 0); a load region 'tip' on the "
            "last column of particles (x = L - dp/2) takes the payload's force and gives its mean "
            "displacement/velocity; a load region 'mid' (0.45 <= x <= 0.55) for a time-series load (wave); "
            "probe 'end' at (L, 0). 2D: forces per metre of depth."
        ),
        "dimension": 2,
        "particle_spacing": dp,
        "solver": {"model": "corrected", "damping": 0.0},
        "gravity": {"vector": [0.0, 0.0]},
        "bodies": [
            {
                "name": "beam",
                "material": {"density": DENSITY, "young": YOUNG, "poisson": POISSON},
                "boxes": [
                    {"min": [0.0, -h2], "max": [LENGTH, h2]},
                    {"min": [-2.5 * dp, -h2], "max": [0.5 * dp, h2]},
                ],
            }
        ],
        "boundaries": [
            {
                "name": "clamp",
                "kind": "clamped",
                "body": "beam",
                "region": {"min": [-2.5 * dp, -h2], "max": [0.25 * dp, h2]},
            }
        ],
        "loads": [
            {"name": "tip", "body": "beam", "region": {"min": [LENGTH - dp, -h2], "max": [LENGTH, h2]}},
            {"name": "mid", "body": "beam", "region": {"min": [0.45, -h2], "max": [0.55, h2]}},
        ],
        "probes": [{"name": "end", "point": [LENGTH, 0.0]}],
        "end_time": 1.0,
        "output_interval": 0.001,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=12, help="particles through the thickness")
    ap.add_argument("--name", default="cantilever_payload")
    ap.add_argument("--out", default="scenes/cantilever_payload.json")
    a = ap.parse_args()
    # The scene names its JSON Schema (relative to the file) so that editors check it; mps
    # ignores the key.
    schema = Path(__file__).resolve().parents[2] / "schema" / "scene.schema.json"
    named = {"$schema": os.path.relpath(schema, Path(a.out).resolve().parent), **scene(a.n, a.name)}
    with open(a.out, "w") as f:
        json.dump(named, f, indent=2)
        f.write("\n")


if __name__ == "__main__":
    main()
