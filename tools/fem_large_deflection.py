#!/usr/bin/env python3
"""Nonlinear 3D FEM reference for the cantilever at large deflection, with the solver's own laws.

The slender cantilever of tools/fem_bending.py (x in [0, 1] m, square section 0.1 x 0.1 m
centred on the x axis, rho = 1000 kg/m^3, E = 1e8 Pa, nu = 0.3, clamped at x = 0, u = 0) under a
dead gravity load along -z (rho g per unit undeformed volume, direction fixed) at the levels of
the elastica reference: g = 9.81 (linear check) and g = 216 / 361 / 580 m/s^2 (tip deflection
30 / 45 / 60 % of L in the elastica).  Finite strain, total Lagrangian, with the two strain
energy laws of src/physics/law.rs:

  * Saint Venant-Kirchhoff: S = 2 mu E + lambda tr(E) I, E = (F^T F - I) / 2;
  * compressible neo-Hookean (docs/model.md, Eq. (NH1)):
    W = mu/2 (J^(-2/3) I1 - 3) + K/4 (J^2 - 1 - 2 ln J), K = lambda + 2 mu / 3,
    S = mu J^(-2/3) (I - I1/3 C^-1) + K/2 (J^2 - 1) C^-1.

The elastica (tools/fem_bending.py) has a linear moment-curvature law and an inextensible,
shear-free axis; this reference has neither simplification, so the difference between the
particle solver and it is the solver's discretisation error at large deflection, and the
difference between it and the elastica is the part of the elastica comparison that belongs to
the reference (issue 7).

Discretisation: triquadratic Hex27 elements on the graded tensor meshes of
tools/fem_bending.py (nx = 5 ny, ny = nz across, graded to the clamp and the faces), 3x3x3
Gauss points.  Element arrays are assembled here with numpy (shape function gradients from
scikit-fem's scalar Hex27 basis): the internal force P : grad N and the consistent tangent
dP/dF = delta S + F (dS/dE) F^T.  The neo-Hookean tangent is analytic and is checked against
central differences of S at start-up.  Newton's method with load continuation (g increments of
at most --dg, halved on failure); converged when the residual is below 1e-9 of the load and the
last correction below 1e-10 of the displacement.  Richardson extrapolation over the three finest
meshes (fem_reference.richardson, h = 1/ny).

Usage:
  .venv-fem/bin/python tools/fem_large_deflection.py           # writes reference/cantilever3d_nonlinear_fem.json
  .venv-fem/bin/python tools/fem_large_deflection.py --quick   # ny = 1, 2, 3; writes only with --out
"""

import argparse
import os
import sys
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from skfem import Basis, ElementHex2, MeshHex
from skfem.models.elasticity import lame_parameters

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fem_bending as fb  # noqa: E402  (problem data, meshes, elastica, versions)
import fem_reference as fr  # noqa: E402  (Richardson, rounding, JSON writing)

P = fb.CANT
LEVELS_G = (fb.G_ACC, 216.0, 361.0, 580.0)   # m/s^2: the linear check and the elastica levels
LAWS = ("saint_venant_kirchhoff", "neo_hookean")
DEFAULT_OUT = os.path.join(fr.REPO, "reference", "cantilever3d_nonlinear_fem.json")
CHUNK = 256                                   # elements per block of the tangent assembly

log = fb.log


# ---------------------------------------------------------------- material laws
def green(F):
    """Green strain of F (..., 3, 3), written as (H + H^T + H^T H) / 2 with H = F - I."""
    H = F - np.eye(3)
    return 0.5 * (H + np.swapaxes(H, -1, -2) + np.swapaxes(H, -1, -2) @ H)


def svk(F, lam, mu):
    """S and dS/dE (..., 3, 3, 3, 3) of Saint Venant-Kirchhoff."""
    E = green(F)
    I = np.eye(3)
    S = 2.0 * mu * E + lam * np.trace(E, axis1=-2, axis2=-1)[..., None, None] * I
    C4 = (lam * np.einsum("ij,kl->ijkl", I, I)
          + mu * (np.einsum("ik,jl->ijkl", I, I) + np.einsum("il,jk->ijkl", I, I)))
    return S, np.broadcast_to(C4, S.shape[:-2] + (3, 3, 3, 3))


def neo_hookean(F, lam, mu):
    """S and dS/dE (..., 3, 3, 3, 3) of the compressible neo-Hookean law of law.rs."""
    I = np.eye(3)
    C = np.swapaxes(F, -1, -2) @ F
    J2 = np.linalg.det(C)
    if np.any(~(J2 > 0.0)):
        raise FloatingPointError("neo-Hookean: det C <= 0 at a Gauss point")
    Ci = np.linalg.inv(C)
    I1 = np.trace(C, axis1=-2, axis2=-1)
    j23 = J2 ** (-1.0 / 3.0)
    K = lam + 2.0 * mu / 3.0
    e = (..., None, None)
    S = mu * j23[e] * (I - I1[e] / 3.0 * Ci) + 0.5 * K * (J2 - 1.0)[e] * Ci
    # dS/dC (symmetric in its last pair), then dS/dE = 2 dS/dC.
    outer = np.einsum("...ij,...kl->...ijkl", I - I1[e] / 3.0 * Ci, Ci)
    ci_ci = np.einsum("...ij,...kl->...ijkl", Ci, Ci)
    ci_d = np.einsum("...ij,kl->...ijkl", Ci, I)
    sym = 0.5 * (np.einsum("...ik,...lj->...ijkl", Ci, Ci)
                 + np.einsum("...il,...kj->...ijkl", Ci, Ci))
    f = (..., None, None, None, None)
    T = (-mu / 3.0 * j23[f] * outer - mu / 3.0 * j23[f] * ci_d + 0.5 * K * J2[f] * ci_ci
         + (mu * j23 * I1 / 3.0 - 0.5 * K * (J2 - 1.0))[f] * sym)
    return S, 2.0 * T


LAW_FN = {"saint_venant_kirchhoff": svk, "neo_hookean": neo_hookean}


def check_tangents(lam, mu):
    """dS/dE of both laws against central differences of S at a general F (rel. error < 1e-6)."""
    rng = np.random.default_rng(7)
    F = np.eye(3) + 0.15 * rng.standard_normal((3, 3))
    for name, fn in LAW_FN.items():
        _, C4 = fn(F, lam, mu)
        E0 = green(F)
        # S depends on F only through E: perturb E and take F = chol(I + 2E)^T
        num = np.zeros((3, 3, 3, 3))
        h = 1e-6
        for k in range(3):
            for l in range(3):
                dE = np.zeros((3, 3))
                dE[k, l] += 0.5 * h
                dE[l, k] += 0.5 * h
                Sp = fn(np.linalg.cholesky(np.eye(3) + 2 * (E0 + dE)).T, lam, mu)[0]
                Sm = fn(np.linalg.cholesky(np.eye(3) + 2 * (E0 - dE)).T, lam, mu)[0]
                num[:, :, k, l] = (Sp - Sm) / (2 * h)
        err = np.abs(num - C4).max() / np.abs(C4).max()
        if err > 1e-6:
            raise RuntimeError(f"{name}: tangent differs from central differences by {err:.1e}")
        log(f"  tangent check {name}: max rel. deviation {err:.1e}")


# ---------------------------------------------------------------- discretisation
class Cantilever:
    """Hex27 mesh of the cantilever with the arrays of the assembly; dof = 3 node + component."""

    def __init__(self, ny):
        coords, self.n = fb.coords_for(ny, P["L"], [P["b"], P["h"]])
        self.mesh = MeshHex.init_tensor(*coords)
        basis = Basis(self.mesh, ElementHex2(), intorder=fr.INTORDER)
        self.nodes = basis.doflocs                          # (3, Nn)
        self.nn = basis.N
        self.edofs = basis.element_dofs.T                   # (nel, 27)
        nb = self.edofs.shape[1]
        # G[e, q, a, k] = dN_a/dX_k, N[e, q, a], w[e, q] = Gauss weight x det J
        self.G = np.stack([basis.basis[a][0].grad for a in range(nb)], axis=0).transpose(2, 3, 0, 1)
        self.N = np.stack([basis.basis[a][0].value for a in range(nb)], axis=-1)
        self.w = basis.dx
        vol = self.w.sum()
        if abs(vol / (P["L"] * P["b"] * P["h"]) - 1.0) > 1e-12:
            raise RuntimeError(f"mesh volume {vol} is not L b h")
        ndof = 3 * self.nn
        self.ndof = ndof
        x = self.nodes
        fixed_nodes = np.flatnonzero(np.abs(x[0]) < 1e-12)
        fixed = np.concatenate([3 * fixed_nodes + c for c in range(3)])
        self.free = np.setdiff1d(np.arange(ndof), fixed)
        # unit body force -rho * 1 m/s^2 along z (scaled by g)
        fz = np.zeros(self.nn)
        np.add.at(fz, self.edofs, np.einsum("eq,eqa->ea", self.w, self.N))
        self.f_unit = np.zeros(ndof)
        self.f_unit[2::3] = -P["rho"] * fz
        d = np.hypot(np.hypot(x[0] - P["L"], x[1]), x[2])
        self.tip = int(np.argmin(d))
        if d[self.tip] > 1e-12:
            raise RuntimeError("no node on the axis at the tip")
        # sparsity pattern of the element blocks (dof a*3+i of element e)
        ed = (3 * self.edofs[:, :, None] + np.arange(3)).reshape(len(self.edofs), -1)  # (nel, 81)
        self.edof3 = ed
        self.rows = np.repeat(ed, ed.shape[1], axis=1).ravel()
        self.cols = np.tile(ed, (1, ed.shape[1])).ravel()

    def deformation(self, u, sl=slice(None)):
        Ue = u.reshape(-1, 3)[self.edofs[sl]]               # (nel, 27, 3)
        return np.eye(3) + np.einsum("eai,eqak->eqik", Ue, self.G[sl])

    def residual(self, u, g, law, lam, mu):
        """Internal minus external force (N) and the strain energy (J)."""
        F = self.deformation(u)
        S, _ = LAW_FN[law](F, lam, mu)
        Pk = F @ S
        fe = np.einsum("eq,eqik,eqak->eai", self.w, Pk, self.G)
        r = np.zeros(self.ndof)
        np.add.at(r, self.edof3, fe.reshape(len(fe), -1))
        return r - g * self.f_unit

    def tangent(self, u, law, lam, mu):
        vals = np.empty(self.rows.shape[0])
        nel, nb = self.edofs.shape
        blk = (3 * nb) ** 2
        I = np.eye(3)
        for s in range(0, nel, CHUNK):
            sl = slice(s, min(s + CHUNK, nel))
            F = self.deformation(u, sl)
            S, C4 = LAW_FN[law](F, lam, mu)
            # A_ikjl = dP_ik/dF_jl = delta_ij S_kl + F_im C_mknl F_jn
            A = (np.einsum("ij,eqkl->eqikjl", I, S)
                 + np.einsum("eqim,eqmknl,eqjn->eqikjl", F, C4, F, optimize=True))
            Aw = A * self.w[sl][:, :, None, None, None, None]
            GA = np.einsum("eqak,eqikjl->eqaijl", self.G[sl], Aw, optimize=True)
            Ke = np.einsum("eqaijl,eqbl->eaibj", GA, self.G[sl], optimize=True)
            vals[s * blk:sl.stop * blk] = Ke.reshape(-1)
        K = sp.csr_matrix((vals, (self.rows, self.cols)), shape=(self.ndof, self.ndof))
        return K


# ---------------------------------------------------------------- Newton with continuation
def newton(model, u, g, law, lam, mu, max_iter=30):
    fr_ = model.free
    fnorm = g * np.linalg.norm(model.f_unit[fr_])
    for it in range(1, max_iter + 1):
        r = model.residual(u, g, law, lam, mu)[fr_]
        K = model.tangent(u, law, lam, mu)[fr_][:, fr_].tocsc()
        # the tangent of a hyperelastic law is symmetric (positive definite at a stable state):
        # no pivoting, symmetric mode, as fem_bending.solve
        try:
            du = spla.splu(K, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                           options={"SymmetricMode": True}).solve(-r)
        except RuntimeError:            # singular factor: treat as a failed step
            return None, it
        if not np.all(np.isfinite(du)):
            return None, it
        u = u.copy()
        u[fr_] += du
        rn = np.linalg.norm(model.residual(u, g, law, lam, mu)[fr_])
        if rn < 1e-9 * fnorm and np.linalg.norm(du) < 1e-10 * np.linalg.norm(u[fr_]):
            return u, it
        if not np.isfinite(rn) or rn > 1e3 * fnorm:
            return None, it
    return None, max_iter


def solve_levels(ny, law, dg_max):
    lam, mu = lame_parameters(P["E"], P["nu"])
    t0 = time.time()
    m = Cantilever(ny)
    u = np.zeros(m.ndof)
    g_now, out, iters = 0.0, [], 0
    for g_target in LEVELS_G:
        while g_now < g_target:
            dg = min(dg_max, g_target - g_now)
            while True:
                try:
                    un, it = newton(m, u, g_now + dg, law, lam, mu)
                except FloatingPointError:
                    un, it = None, 0
                iters += it
                if un is not None:
                    break
                dg *= 0.5
                if dg < 1e-3:
                    raise RuntimeError(f"{law} ny={ny}: no convergence at g = {g_now:.3f}")
            u, g_now = un, g_now + dg
        tip = u[3 * m.tip:3 * m.tip + 3]
        out.append({"g_m_s2": g_target, "tip_ux_m": float(tip[0]), "tip_uz_m": float(tip[2])})
    dt = time.time() - t0
    log(f"  {law} ny={ny} ({'x'.join(map(str, m.n))}, {m.ndof} dofs): {iters} Newton "
        f"iterations, {dt:.1f} s; tip u_z " + " ".join(f"{o['tip_uz_m']:.7f}" for o in out))
    return {"ny": ny, "mesh_n": m.n, "dofs": int(m.ndof), "newton_iterations": iters,
            "levels": out, "timing_s": dt}


def run(ny_levels, dg_max):
    lam, mu = lame_parameters(P["E"], P["nu"])
    check_tangents(lam, mu)
    t_start = time.time()
    EI = P["E"] * P["b"] * P["h"] ** 3 / 12.0
    A = P["b"] * P["h"]
    results = {}
    for law in LAWS:
        rows = [solve_levels(ny, law, dg_max) for ny in ny_levels]
        hs = [1.0 / r["ny"] for r in rows]
        conv = []
        for i, g in enumerate(LEVELS_G):
            entry = {"g_m_s2": g}
            for comp in ("tip_uz_m", "tip_ux_m"):
                vals = [r["levels"][i][comp] for r in rows]
                lim, p = fr.richardson(hs, vals)
                entry[comp] = {"finest": vals[-1], "richardson": lim, "order": p,
                               "last_change_rel": (vals[-1] - vals[-2]) / vals[-1]
                               if len(vals) > 1 and vals[-1] != 0 else None}
            el = fb.elastica(P["rho"] * g * A * P["L"] ** 3 / EI)
            entry["elastica_tip_uz_m"] = el["tip_z"] * P["L"]
            entry["elastica_tip_ux_m"] = (el["tip_x"] - 1.0) * P["L"]
            best = entry["tip_uz_m"]["richardson"] or entry["tip_uz_m"]["finest"]
            entry["fem_over_elastica_tip_uz"] = best / entry["elastica_tip_uz_m"]
            conv.append(entry)
        results[law] = {"meshes": [fb.strip(r) for r in rows], "converged": conv}
        log(f"{law}: g, tip u_z (finest, Richardson, order), over the elastica")
        for e in conv:
            z = e["tip_uz_m"]
            log(f"  {e['g_m_s2']:7.2f} {z['finest']:.7f} {z['richardson']} {z['order']} "
                f"{e['fem_over_elastica_tip_uz']:.5f}")
    return {
        "case": "3D cantilever under a dead gravity load, finite strain (issue 7)",
        "problem": {"length_m": P["L"], "width_m": P["b"], "height_m": P["h"],
                    "rho_kg_m3": P["rho"], "E_pa": P["E"], "nu": P["nu"],
                    "gravity_direction": "-z, dead (fixed direction, per undeformed volume)",
                    "bc_x0": "u = 0", "probe": "tip on the axis, (L, 0, 0)",
                    "g_levels_m_s2": list(LEVELS_G)},
        "method": {"code": "tools/fem_large_deflection.py", "elements": "Hex27, 3x3x3 Gauss",
                   "mesh": "tools/fem_bending.py graded tensor meshes, nx = 5 ny",
                   "solver": f"Newton, consistent tangent, g increments <= {dg_max} m/s^2",
                   "laws": {"saint_venant_kirchhoff": "S = 2 mu E + lambda tr(E) I",
                            "neo_hookean": "W = mu/2 (J^(-2/3) I1 - 3) + K/4 (J^2 - 1 - 2 ln J), "
                                           "K = lambda + 2 mu/3"},
                   "richardson": "three finest meshes, h = 1/ny",
                   "versions": fb.versions(),
                   "wall_time_s": time.time() - t_start},
        "laws": results,
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="ny = 1, 2, 3 (smoke run)")
    ap.add_argument("--levels", type=int, nargs="+", help="elements across (default 2 3 4 6)")
    ap.add_argument("--dg", type=float, default=60.0, help="largest g increment (m/s^2)")
    ap.add_argument("--out", help="JSON output; without it only the default full run writes "
                                  f"{os.path.relpath(DEFAULT_OUT, fr.REPO)}")
    args = ap.parse_args(argv)
    levels = args.levels or ([1, 2, 3] if args.quick else [2, 3, 4, 6])
    out = args.out or (None if (args.quick or args.levels) else DEFAULT_OUT)
    data = run(levels, args.dg)
    if out:
        fr.write_json(out, fr.rounded(data), log=log)
    return 0


if __name__ == "__main__":
    sys.exit(main())
