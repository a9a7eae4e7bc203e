#!/usr/bin/env python3
"""Williams exponent of the clamped edge of a cantilever, and the convergence order it allows.

Where a clamped face (u = 0) meets a traction-free face at a right angle, the elastic field near
the edge is u ~ r^lam U(theta) with the smallest lam > 0 of the Williams eigenproblem of a 90 deg
wedge, clamped on one side and free on the other (plane strain across a straight edge of a 3D
body; the antiplane mode there has lam = pi / (2 alpha) = 1, no singularity).  Stresses go as
r^(lam - 1).  With uniform refinement, the energy error of any method of order >= lam falls as
h^(2 lam), and so does the error of a functional whose dual problem has the same singularity
(the tip deflection under gravity, the first frequency): the order a uniform particle spacing
can show on the clamped cantilever (issue 7).

Airy stress function phi = r^(lam+1) [A cos(lam+1)t + B sin(lam+1)t + C cos(lam-1)t +
D sin(lam-1)t] (Williams 1952; Barber, Elasticity, ch. 11), kappa = 3 - 4 nu (plane strain):
  sigma_tt ~ A cos(lam+1)t + B sin(lam+1)t + C cos(lam-1)t + D sin(lam-1)t
  sigma_rt ~ (lam+1)(A sin(lam+1)t - B cos(lam+1)t) + (lam-1)(C sin(lam-1)t - D cos(lam-1)t)
  2 mu u_r ~ -(lam+1)(A cos(lam+1)t + B sin(lam+1)t) + (kappa-lam)(C cos(lam-1)t + D sin(lam-1)t)
  2 mu u_t ~ (lam+1)(A sin(lam+1)t - B cos(lam+1)t) + (kappa+lam)(C sin(lam-1)t - D cos(lam-1)t)
Clamped at t = 0 (u_r = u_t = 0), free at t = alpha (sigma_tt = sigma_rt = 0): a 4x4 determinant
in lam.  lam = 1 is a spurious root (the basis degenerates: sin(lam-1)t = 0) and is skipped.

Checks: the displacements against the Airy stresses through plane-strain Hooke's law (central
differences), and lam = 1/2 for the free-free crack (alpha = 2 pi) and the clamped-clamped one
(rigid line inclusion).

Usage: .venv-fem/bin/python tools/edge_singularity.py [nu ...]   (default 0, 0.3, 0.3975, 0.499)
"""

import math
import sys

import numpy as np
from scipy.optimize import brentq


def rows(lam, t, kind, kappa):
    a, b = (lam + 1) * t, (lam - 1) * t
    if kind == "free":
        return [[np.cos(a), np.sin(a), np.cos(b), np.sin(b)],
                [(lam + 1) * np.sin(a), -(lam + 1) * np.cos(a),
                 (lam - 1) * np.sin(b), -(lam - 1) * np.cos(b)]]
    return [[-(lam + 1) * np.cos(a), -(lam + 1) * np.sin(a),
             (kappa - lam) * np.cos(b), (kappa - lam) * np.sin(b)],
            [(lam + 1) * np.sin(a), -(lam + 1) * np.cos(a),
             (kappa + lam) * np.sin(b), -(kappa + lam) * np.cos(b)]]


def det(lam, alpha, side0, side1, kappa):
    m = np.array(rows(lam, 0.0, side0, kappa) + rows(lam, alpha, side1, kappa), dtype=complex)
    return np.linalg.det(m)


def smallest_exponent(nu, alpha=math.pi / 2):
    """Smallest real lam in (0, 2), lam != 1, of the clamped-free wedge (plane strain)."""
    kappa = 3.0 - 4.0 * nu

    def f(x):
        return det(x, alpha, "clamped", "free", kappa).real

    xs = np.linspace(1e-3, 2.0, 4001)
    fs = [f(x) for x in xs]
    for x0, x1, f0, f1 in zip(xs, xs[1:], fs, fs[1:]):
        if f0 * f1 < 0:
            r = brentq(f, x0, x1, xtol=1e-14)
            if abs(r - 1.0) > 1e-6:
                return r
    return None


def fields(lam, coef, kappa, r, t):
    """Airy function phi and the displacements 2 mu (u_r, u_t) of the docstring's expansion."""
    A, B, C, D = coef
    a, b = (lam + 1) * t, (lam - 1) * t
    phi = r ** (lam + 1) * (A * np.cos(a) + B * np.sin(a) + C * np.cos(b) + D * np.sin(b))
    ur = r ** lam * (-(lam + 1) * (A * np.cos(a) + B * np.sin(a))
                     + (kappa - lam) * (C * np.cos(b) + D * np.sin(b)))
    ut = r ** lam * ((lam + 1) * (A * np.sin(a) - B * np.cos(a))
                     + (kappa + lam) * (C * np.sin(b) - D * np.cos(b)))
    return phi, ur, ut


def self_checks():
    """The displacement formulas against the Airy stresses through plane-strain Hooke's law
    (all derivatives by central differences, 2 mu = 1), and the crack exponents: lam = 1/2 for
    the free-free crack (Williams) and for the clamped-clamped one (rigid line inclusion)."""
    nu, lam, r, t, h = 0.3, 0.63, 0.7, 0.4, 1e-4
    kappa = 3.0 - 4.0 * nu
    coef = (0.3, -0.8, 0.5, 1.1)

    def F(i, rr, tt):
        return fields(lam, coef, kappa, rr, tt)[i]

    def d_r(i, rr, tt):
        return (F(i, rr + h, tt) - F(i, rr - h, tt)) / (2 * h)

    def d_t(i, rr, tt):
        return (F(i, rr, tt + h) - F(i, rr, tt - h)) / (2 * h)

    phi_rr = (F(0, r + h, t) - 2 * F(0, r, t) + F(0, r - h, t)) / h ** 2
    phi_tt = (F(0, r, t + h) - 2 * F(0, r, t) + F(0, r, t - h)) / h ** 2
    s_rr = d_r(0, r, t) / r + phi_tt / r ** 2
    s_tt = phi_rr
    s_rt = -(d_t(0, r + h, t) / (r + h) - d_t(0, r - h, t) / (r - h)) / (2 * h)
    e_rr = d_r(1, r, t)
    e_tt = F(1, r, t) / r + d_t(2, r, t) / r
    e_rt = 0.5 * (d_t(1, r, t) / r + d_r(2, r, t) - F(2, r, t) / r)
    tr = s_rr + s_tt
    dev = max(abs(e_rr - (s_rr - nu * tr)), abs(e_tt - (s_tt - nu * tr)), abs(e_rt - s_rt))
    if dev > 1e-6 * max(abs(s_rr), abs(s_tt), abs(s_rt)):
        raise RuntimeError(f"displacements do not match the Airy stresses ({dev:.1e})")
    for side in ("free", "clamped"):
        scale = abs(det(0.3, 2 * math.pi, side, side, kappa))
        if abs(det(0.5, 2 * math.pi, side, side, kappa)) > 1e-12 * max(scale, 1.0):
            raise RuntimeError(f"{side}-{side} crack: det(1/2) != 0")


def main(argv):
    self_checks()
    nus = [float(a) for a in argv] or [0.0, 0.3, 0.3975, 0.499]
    print("checks passed: displacements vs Airy stresses, crack exponents 1/2")
    print("| nu | lam (clamped-free 90 deg, plane strain) | stress ~ r^(lam-1) | functional order 2 lam |")
    print("|---|---|---|---|")
    for nu in nus:
        lam = smallest_exponent(nu)
        print(f"| {nu} | {lam:.4f} | r^{lam - 1:+.3f} | {2 * lam:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
