#!/usr/bin/env python3
"""Writes scenes/meshes/bracket.stl: an L-bracket as a closed binary STL in millimetres (as a CAD
export would be; the scene reads it with scale 0.001). Standard library only.

The profile in the x-z plane (mm): a base leg 120 long and 20 thick along x, an upright leg 20
thick and 100 high at x = 0, an inner fillet of radius 15 where they meet (16 segments) and a
10 mm chamfer at the outer corner; extruded 60 along y. Caps are ear-clipped; every triangle
faces outward (the script checks the enclosed volume against the profile's area times the width).

    python3 tools/make_bracket_stl.py [out.stl]
"""
import math
import struct
import sys

T, LB, HU, R, C, W = 20.0, 120.0, 100.0, 15.0, 10.0, 60.0


def profile():
    """The L profile counter-clockwise in (x, z), mm."""
    p = [(C, 0.0), (LB, 0.0), (LB, T), (T + R, T)]
    # Inner fillet from (T + R, T) to (T, T + R), centre (T + R, T + R), clockwise about it.
    n = 16
    for k in range(1, n):
        a = -math.pi / 2 - (math.pi / 2) * k / n
        p.append((T + R + R * math.cos(a), T + R + R * math.sin(a)))
    p += [(T, T + R), (T, HU), (0.0, HU), (0.0, C)]
    return p


def area(p):
    return 0.5 * sum(p[i][0] * p[(i + 1) % len(p)][1] - p[(i + 1) % len(p)][0] * p[i][1]
                     for i in range(len(p)))


def ear_clip(p):
    """Triangles (index triples, counter-clockwise) of a simple counter-clockwise polygon."""
    idx = list(range(len(p)))
    out = []

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    def inside(q, a, b, c):
        return cross(a, b, q) >= 0 and cross(b, c, q) >= 0 and cross(c, a, q) >= 0

    while len(idx) > 3:
        for k in range(len(idx)):
            i, j, l = idx[k - 1], idx[k], idx[(k + 1) % len(idx)]
            a, b, c = p[i], p[j], p[l]
            if cross(a, b, c) <= 1e-12:
                continue
            if any(inside(p[m], a, b, c) for m in idx if m not in (i, j, l)):
                continue
            out.append((i, j, l))
            del idx[k]
            break
        else:
            raise SystemExit("ear clipping failed: the profile is not simple")
    out.append(tuple(idx))
    return out


def triangles():
    p = profile()
    assert area(p) > 0
    # A profile point (x, z) at depth y -> 3D (x, y, z). The profile's counter-clockwise
    # sense in (x, z) faces -y (x cross z = -y), so the cap at y = 0 keeps it and the cap at
    # y = W is reversed.
    v = lambda q, y: (q[0], y, q[1])
    tris = []
    for (i, j, l) in ear_clip(p):
        tris.append((v(p[i], 0.0), v(p[j], 0.0), v(p[l], 0.0)))
        tris.append((v(p[i], W), v(p[l], W), v(p[j], W)))
    n = len(p)
    for i in range(n):
        a, b = p[i], p[(i + 1) % n]
        # The side quad of edge a -> b faces out of the counter-clockwise profile.
        tris.append((v(a, 0.0), v(b, W), v(b, 0.0)))
        tris.append((v(a, 0.0), v(a, W), v(b, W)))
    return tris, area(p) * W


def volume(tris):
    return sum(a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
               + a[2] * (b[0] * c[1] - b[1] * c[0]) for a, b, c in tris) / 6.0


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "scenes/meshes/bracket.stl"
    tris, expected = triangles()
    vol = volume(tris)
    assert abs(vol - expected) < 1e-9 * expected, (vol, expected)
    with open(out, "wb") as f:
        f.write(b"mps-solid L-bracket, mm, tools/make_bracket_stl.py".ljust(80, b" "))
        f.write(struct.pack("<I", len(tris)))
        for a, b, c in tris:
            u = [b[k] - a[k] for k in range(3)]
            w = [c[k] - a[k] for k in range(3)]
            nrm = [u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]]
            s = math.sqrt(sum(x * x for x in nrm)) or 1.0
            f.write(struct.pack("<12fH", *[x / s for x in nrm], *a, *b, *c, 0))
    print(f"{out}: {len(tris)} triangles, volume {vol:.1f} mm^3")


if __name__ == "__main__":
    main()
