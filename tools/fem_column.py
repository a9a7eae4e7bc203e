#!/usr/bin/env python3
"""3D linear-elasticity FEM reference for paper Case 1 (column hanging under its own weight).

Column 0.2 m x 0.2 m x 1.0 m: x, y in [-0.1, 0.1], z in [-1, 0]; rho = 1000 kg/m^3,
E = 10 MPa, nu = 0.3, gravity 9.81 m/s^2 along -z.  Static, linear, small strain.

Supports:
  z = 0 : clamped, u = 0 (all three components) on the whole face.
  all other faces free.
The clamp also stops the lateral (Poisson) contraction, so the stress is singular along the
clamped edges and corners of the face z = 0; away from the clamp the solution relaxes (Saint-
Venant decay over about one width) to the closed form of a freely contracting bar,
  u_x = -nu rho g x (L - s) / E,  u_z = -[rho g (L s - s^2/2) - nu rho g (x^2 + y^2)/2] / E,
s = -z, plus a rigid axial offset that the clamp's boundary layer carries down the column.
The project's closed form (src/studies/cases.rs `case1_closed_form`) is ported here as
`closed_form` and compared with the FEM on the probe lines.

Outputs: u_x and u_z on the line x = 0.1 (the side face), y = 0 at the stations
s = -z = 0.1, 0.2, ..., 1.0 m, also on x = 0.0875, y = 0; the support reaction (it must
equal the weight rho g 0.2^2 1.0 = 392.4 N).

Discretisation: quarter model x, y in [0, 0.1] with the symmetry conditions u_x = 0 on x = 0
and u_y = 0 on y = 0 (checked against the full section on the coarsest mesh).  Structured
hexahedral meshes of triquadratic 27-node elements (scikit-fem ElementVector(ElementHex2)),
3x3x3 Gauss quadrature; element matrices and assembly from tools/fem_reference.py
(`assemble_tensor`, checked against scikit-fem's own global assembly on the coarsest mesh).
Level n (n even) has n x n elements across the quarter section and
  x = 0.1 sin(pi xi / 2), y likewise (xi uniform in [0, 1]; graded towards the free faces
        x = 0.1, y = 0.1 that meet the clamp in the singular edges),
  z: every station s = 0.1 k is a node plane (probes at nodes on every level);
     s in [0, 0.1]: n elements, s = 0.1 tau^2 (tau uniform; graded towards the clamp),
     s in [0.1, 0.4]: n/2 uniform elements per 0.1 m,
     s in [0.4, 1.0]: ceil(n/4) uniform elements per 0.1 m (the field there is the
        closed form plus an offset, which triquadratic elements represent exactly, plus
        an end effect decayed below 1e-6 of u).
The mapping is the same on every level, so the levels form one family for Richardson
extrapolation with h = 1/n (three finest meshes).  Linear solve: SuperLU (scipy splu,
no pivoting, K is SPD) after a geometric nested-dissection ordering of the DOFs on the
node grid (separators on element faces), which needs about half the fill and a third of
the time of COLAMD here; one step of iterative refinement.  Reaction: the z component of
K u - f summed over the clamped DOFs, times 4.

Usage:
  nice .venv-fem/bin/python tools/fem_column.py          # full run (levels 4 6 8 10 12), writes reference/case1_fem.json
  nice .venv-fem/bin/python tools/fem_column.py --quick  # levels 2 4 6 (~10 s), writes nothing unless --out
Any run with --quick/--levels writes JSON only to an explicit --out.  The full run takes about
2.5 min on the shared 2-core machine and 9.7 GB peak memory, almost all of it the finest level
(n = 12, 182k DOFs, ~85 s); n = 16 does not fit in 23 GB.
"""

import argparse
import os
import platform
import sys
import time

import numpy as np
import scipy
import scipy.sparse.linalg as spla

import skfem
from skfem.models.elasticity import lame_parameters

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fem_reference as fr  # noqa: E402  (shared assembly and Richardson)

# ---------------------------------------------------------------- problem
L = 1.0            # column length (m), z in [-L, 0]
HALF = 0.1         # half width (m), x, y in [-HALF, HALF]
RHO = 1000.0
E = 10.0e6
NU = 0.3
G_ACC = 9.81
WEIGHT = RHO * G_ACC * (2 * HALF) ** 2 * L
STATIONS = np.round(0.1 * np.arange(1, 11), 12)         # s = -z (m)
LINES = {"x0.1_y0": (0.1, 0.0), "x0.0875_y0": (0.0875, 0.0)}
MAIN_LINE = "x0.1_y0"
LAM, MU = lame_parameters(E, NU)

REPO = fr.REPO
DEFAULT_OUT = os.path.join(REPO, "reference", "case1_fem.json")


def log(*a):
    print(*a, flush=True)


def closed_form(x, y, s):
    """Port of src/studies/cases.rs `case1_closed_form`: (u_x, u_z) at (x, y, z = -s) (m)."""
    rg = RHO * G_ACC
    ux = -NU * rg * x * (L - s) / E
    us = rg * (L * s - 0.5 * s * s) / E - NU * rg * (x * x + y * y) / (2.0 * E)
    return ux, -us


# ---------------------------------------------------------------- mesh
def z_nodes(n):
    """Node coordinates z (ascending) of level n: see the module docstring."""
    segs = [0.1 * np.linspace(0.0, 1.0, n + 1) ** 2]
    for j in range(1, 10):
        m = n // 2 if j <= 3 else -(-n // 4)
        segs.append(0.1 * j + np.linspace(0.0, 0.1, m + 1)[1:])
    s = np.concatenate(segs)
    s[-1] = L
    return np.sort(-s)


def coords_for(n, full=False):
    """Tensor grid of level n: quarter section (default) or the full section (mirrored)."""
    xi = np.linspace(0.0, 1.0, n + 1)
    x = HALF * np.sin(0.5 * np.pi * xi)
    x[0], x[-1] = 0.0, HALF
    if full:
        x = np.concatenate([-x[:0:-1], x])
    z = z_nodes(n)
    return [x, x.copy(), z], [len(x) - 1, len(x) - 1, len(z) - 1]


def nd_order(ijk, leaf=64):
    """Geometric nested dissection of DOFs with integer node-grid coordinates ijk (3 x N).
    The box is split across its longest extent on an even grid plane (an element face of
    the Hex27 mesh), so the two halves share no element; the plane's DOFs go last."""
    out = []

    def rec(idx):
        sub = ijk[:, idx]
        lo, hi = sub.min(axis=1), sub.max(axis=1)
        a = int(np.argmax(hi - lo))
        if len(idx) <= leaf or hi[a] - lo[a] < 4:
            out.append(idx)
            return
        m = (lo[a] + hi[a]) // 2
        if m % 2:
            m += 1 if m + 1 < hi[a] else -1
        v = sub[a]
        rec(idx[v < m])
        rec(idx[v > m])
        out.append(idx[v == m])

    rec(np.arange(ijk.shape[1]))
    perm = np.concatenate(out)
    assert len(perm) == ijk.shape[1] and len(np.unique(perm)) == len(perm)
    return perm


# ---------------------------------------------------------------- solve
def solve_level(n, full=False, check=False):
    t0 = time.time()
    coords, shape = coords_for(n, full)
    mesh, basis, K, M, f = fr.assemble_tensor(coords, LAM, MU, RHO, G_ACC, check=check,
                                              scaled=True)
    del M
    X = basis.doflocs
    comp = fr.dof_components(basis)
    tol = 1e-12
    clamp = np.abs(X[2]) < tol
    fixed = clamp.copy()
    if not full:
        fixed |= (np.abs(X[0]) < tol) & (comp == 0)
        fixed |= (np.abs(X[1]) < tol) & (comp == 1)
    free = np.flatnonzero(~fixed)
    ijk = np.array([np.unique(np.round(X[a], 12), return_inverse=True)[1].ravel()
                    for a in range(3)])
    free = free[nd_order(ijk[:, free])]
    Kc = K[free][:, free].tocsc()
    fc = f[free]
    t_asm = time.time() - t0

    t0 = time.time()
    lu = spla.splu(Kc, permc_spec="NATURAL", diag_pivot_thresh=0.0,
                   options={"SymmetricMode": True})
    lu_nnz = int(lu.L.nnz + lu.U.nnz)
    uc = lu.solve(fc)
    res0 = np.abs(Kc @ uc - fc).max() / np.abs(fc).max()
    uc += lu.solve(fc - Kc @ uc)                         # one step of iterative refinement
    res1 = np.abs(Kc @ uc - fc).max() / np.abs(fc).max()
    del lu, Kc
    t_lu = time.time() - t0

    u = np.zeros(basis.N)
    u[free] = uc
    r = K @ u - f
    sym = 1.0 if full else 4.0
    reaction = [float(sym * r[clamp & (comp == c)].sum()) for c in range(3)]
    if not full:
        reaction[0] = reaction[1] = 0.0                  # zero by symmetry in the full model

    lines = {}
    for name, (x0, y0) in LINES.items():
        pts = np.vstack([np.full(len(STATIONS), x0), np.full(len(STATIONS), y0), -STATIONS])
        P = basis.probes(pts).tocsr()
        m = len(STATIONS)
        lines[name] = {"ux_m": P[0:m] @ u, "uz_m": P[2 * m:3 * m] @ u}
    row = {"n": n, "mesh_n": shape, "elements": int(mesh.t.shape[1]), "dofs": int(basis.N),
           "free_dofs": int(len(free)), "h": 1.0 / n, "lu_nnz": lu_nnz,
           "relative_residual": float(res1), "reaction_N": reaction, "lines": lines,
           "timing_s": {"assembly": t_asm, "lu_and_solve": t_lu}}
    log(f"  n={n:2d} ({'x'.join(map(str, shape))}{', full section' if full else ''}): "
        f"{basis.N} dofs, asm {t_asm:.1f}s, LU+solve {t_lu:.1f}s (nnz {lu_nnz:.2e}), "
        f"residual {res0:.1e} -> {res1:.1e}, R_z = {reaction[2]:.6f} N, "
        f"u_z(s=1) = {lines[MAIN_LINE]['uz_m'][-1]:.9e}")
    return row


# ---------------------------------------------------------------- analysis
def converge(hs, seqs, scale):
    """Per station: Richardson over the three finest meshes.  converged = Richardson value
    if it exists with an order in [0.5, 6], otherwise the finest mesh; uncertainty =
    |converged - finest| (Richardson), else |finest - previous|; scale: max |u| on the line
    for the relative last change."""
    out = {k: [] for k in ("converged", "uncertainty", "finest", "richardson", "order",
                           "last_change_rel_to_line_max")}
    for vals in np.array(seqs).T:
        lim, p = fr.richardson(hs, list(vals))
        ok = lim is not None and 0.5 <= p <= 6.0
        out["converged"].append(lim if ok else vals[-1])
        out["uncertainty"].append(abs(lim - vals[-1]) if ok else abs(vals[-1] - vals[-2]))
        out["finest"].append(vals[-1])
        out["richardson"].append(lim)
        out["order"].append(p)
        out["last_change_rel_to_line_max"].append((vals[-1] - vals[-2]) / scale)
    return out


def sig_round(obj, n=9, zero=1e-15):
    """Round floats to n significant digits; |x| < zero (m, round-off) written as 0."""
    if isinstance(obj, dict):
        return {k: sig_round(v, n, zero) for k, v in obj.items() if k != "timing_s"}
    if isinstance(obj, (list, tuple)):
        return [sig_round(v, n, zero) for v in obj]
    if isinstance(obj, np.ndarray):
        return sig_round(obj.tolist(), n, zero)
    if isinstance(obj, (float, np.floating)):
        return 0.0 if abs(obj) < zero else fr.sig(obj, n)
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="levels 2 4 6 only (smoke run)")
    ap.add_argument("--levels", type=int, nargs="+",
                    help="elements across the quarter section, even (default 4 6 8 10 12)")
    ap.add_argument("--out", help=f"JSON output; without it only the default full run writes "
                                  f"{os.path.relpath(DEFAULT_OUT, REPO)}")
    args = ap.parse_args(argv)
    levels = args.levels or ([2, 4, 6] if args.quick else [4, 6, 8, 10, 12])
    if any(n % 2 or n < 2 for n in levels) or len(levels) < 3:
        ap.error("need at least three even levels")
    default_run = not (args.quick or args.levels)
    out = args.out or (DEFAULT_OUT if default_run else None)

    t_start = time.time()
    log("Case 1: column hanging under its own weight, 3D linear elasticity, Hex27 elements")
    log(f"0.2 x 0.2 x {L} m, rho={RHO}, E={E}, nu={NU}, g={G_ACC} along -z; clamped at z = 0; "
        f"weight {WEIGHT:.4f} N")

    # checks on the coarsest level: symmetry conditions against the full section
    n0 = levels[0]
    log("symmetry check (coarsest level, quarter vs full section):")
    q0 = solve_level(n0, check=True)
    f0 = solve_level(n0, full=True, check=True)
    sym_dev = max(float(np.abs(q0["lines"][k][c] - f0["lines"][k][c]).max()
                        / np.abs(f0["lines"][k][c]).max())
                  for k in LINES for c in ("ux_m", "uz_m"))
    sym_check = {"level": n0, "max_rel_difference_quarter_vs_full": sym_dev,
                 "full_section_reaction_N": f0["reaction_N"]}
    log(f"  max relative difference {sym_dev:.1e}; full-section reaction "
        f"{f0['reaction_N'][0]:.2e}, {f0['reaction_N'][1]:.2e}, {f0['reaction_N'][2]:.6f} N")
    if sym_dev > 1e-8:
        raise RuntimeError("quarter model does not reproduce the full section")

    log("levels:")
    rows = [q0] + [solve_level(n) for n in levels[1:]]
    hs = [r["h"] for r in rows]
    for r in rows:
        if abs(r["reaction_N"][2] / WEIGHT - 1) > 1e-8:
            raise RuntimeError(f"reaction {r['reaction_N'][2]} N != weight {WEIGHT} N")

    results = {}
    for name, (x0, y0) in LINES.items():
        cfx, cfz = closed_form(x0, y0, STATIONS)
        res = {"x_m": x0, "y_m": y0, "s_m": STATIONS,
               "closed_form": {"ux_m": cfx, "uz_m": cfz}}
        for c, cf in (("ux_m", cfx), ("uz_m", cfz)):
            seqs = [r["lines"][name][c] for r in rows]
            cv = converge(hs, seqs, float(np.abs(seqs[-1]).max()))
            u = np.array(cv["converged"])
            used = STATIONS >= 0.2 - 1e-9
            scale = np.abs(cf[used]).max()
            cv["minus_closed_form_m"] = u - cf
            cv["closed_form_error_rel_to_cf_max"] = (u - cf) / scale
            cv["closed_form_error_metric"] = float(np.abs(u - cf)[used].max() / scale)
            res[c.replace("_m", "")] = cv
        results[name] = res

    # report
    main_ = results[MAIN_LINE]
    log("\nline x = 0.1, y = 0 (side face); per mesh u_x / u_z (m):")
    hdr = f"{'s':>4} " + " ".join(f"{'n=' + str(r['n']):>14}" for r in rows) + \
        f" {'converged':>15} {'+-':>8} {'order':>5} {'closed form':>14} {'FEM-cf %':>9}"
    for c in ("ux", "uz"):
        log(f"{c}:")
        log(hdr)
        cv = main_[c]
        cf = main_["closed_form"][c + "_m"]
        scale = np.abs(cf[STATIONS >= 0.2 - 1e-9]).max()
        for i, s in enumerate(STATIONS):
            o = cv["order"][i]
            log(f"{s:4.1f} " + " ".join(f"{r['lines'][MAIN_LINE][c + '_m'][i]:14.7e}" for r in rows)
                + f" {cv['converged'][i]:15.9e} {cv['uncertainty'][i]:8.1e} "
                f"{'' if o is None else f'{o:5.2f}':>5} {cf[i]:14.7e} "
                f"{100 * (cv['converged'][i] - cf[i]) / scale:+9.4f}")
    for name, res in results.items():
        log(f"closed form vs FEM on {name}: error metric (max over s >= 0.2 of |u - u_cf| / "
            f"max |u_cf|): u_x {100 * res['ux']['closed_form_error_metric']:.4f} %, "
            f"u_z {100 * res['uz']['closed_form_error_metric']:.4f} %")
    wall = time.time() - t_start
    log(f"reaction R_z = {rows[-1]['reaction_N'][2]:.9f} N (weight {WEIGHT:.4f} N)")
    log(f"total run time {wall:.1f} s")

    if out:
        fin = rows[-1]
        i1, i2 = int(np.argmin(np.abs(STATIONS - 1.0))), int(np.argmin(np.abs(STATIONS - 0.2)))
        cfm = main_["closed_form"]
        sc_x = np.abs(cfm["ux_m"][1:]).max()
        sc_z = np.abs(cfm["uz_m"][1:]).max()
        data = {
            "case": "paper Case 1: column hanging from a clamped top face under its own weight "
                    "(3D linear elasticity FEM reference)",
            "problem": {
                "size_m": [2 * HALF, 2 * HALF, L],
                "domain": "x, y in [-0.1, 0.1], z in [-1, 0]",
                "rho_kg_m3": RHO, "E_pa": E, "nu": NU, "g_m_s2": G_ACC,
                "gravity_direction": "-z", "weight_N": WEIGHT,
                "bc_z0": "clamped: u = 0 (all components) on the whole face z = 0",
                "bc_other": "all other faces free",
                "analysis": "static, linear, small strain",
                "stations": "s = -z = 0.1, 0.2, ..., 1.0 m on the lines below",
                "sign": "u_z negative = downward (-z); u_x negative = inward on x = 0.1",
            },
            "method": {
                "code": "tools/fem_column.py (assembly and Richardson from tools/fem_reference.py)",
                "model": "quarter x, y in [0, 0.1] with u_x = 0 on x = 0 and u_y = 0 on y = 0; "
                         "reaction = 4 x sum of (K u - f)_z over the clamped DOFs",
                "elements": "tensor hexahedral mesh of 27-node triquadratic elements "
                            "(scikit-fem ElementVector(ElementHex2)), 3x3x3 Gauss",
                "mesh": "level n: n x n elements across the quarter section, x = 0.1 sin(pi xi/2) "
                        "(y likewise, graded towards the free faces); along z every station "
                        "s = 0.1 k is a node plane: s in [0, 0.1] n elements with s = 0.1 tau^2 "
                        "(graded towards the clamp), s in [0.1, 0.4] n/2 and s in [0.4, 1] "
                        "ceil(n/4) uniform elements per 0.1 m",
                "solver": "scipy splu (SuperLU, no pivoting) after a geometric nested-dissection "
                          "ordering, one step of iterative refinement",
                "richardson": "u = u_inf + C h^p through the three finest meshes, h = 1/n, per "
                              "station; 'converged' is the Richardson value when it exists with "
                              "0.5 <= p <= 6 (else the finest mesh), 'uncertainty' = |converged - "
                              "finest| (else the last change)",
                "closed_form": "src/cases.rs case1_closed_form(x, y, s): u_x = -nu rho g x (L - s)/E, "
                               "u_z = -[rho g (L s - s^2/2) - nu rho g (x^2 + y^2)/2]/E",
                "closed_form_error_metric": "max over s in {0.2, ..., 1.0} of |u_FEM - u_cf| / "
                                            "max over the same s of |u_cf|, separately for u_x "
                                            "and u_z (as src/report.rs line_error)",
                "checks": {"assembly": "fast tensor assembly equal to scikit-fem's global "
                                       "assembly on the coarsest mesh (1e-12)",
                           "symmetry": sym_check},
                "versions": {"python": platform.python_version(), "numpy": np.__version__,
                             "scipy": scipy.__version__, "scikit-fem": skfem.__version__},
                "wall_time_s": round(wall),
                "mesh_times_s": [round(r["timing_s"]["assembly"] + r["timing_s"]["lu_and_solve"], 1)
                                 for r in rows],
            },
            "meshes": [{k: v for k, v in r.items() if k != "timing_s"} for r in rows],
            "converged": {
                "finest_mesh_n": fin["mesh_n"], "finest_dofs": fin["dofs"],
                "reaction_z_N": fin["reaction_N"][2],
                "reaction_over_weight_minus_1": fin["reaction_N"][2] / WEIGHT - 1,
                "lines": results,
            },
            "closed_form_comparison": {
                "line": "x = 0.1, y = 0",
                "error_ux": main_["ux"]["closed_form_error_metric"],
                "error_uz": main_["uz"]["closed_form_error_metric"],
                "uz_s1_fem_m": main_["uz"]["converged"][i1],
                "uz_s1_closed_form_m": cfm["uz_m"][i1],
                "uz_s1_diff_rel_to_cf_max": (main_["uz"]["converged"][i1] - cfm["uz_m"][i1]) / sc_z,
                "ux_s02_fem_m": main_["ux"]["converged"][i2],
                "ux_s02_closed_form_m": cfm["ux_m"][i2],
                "ux_s02_diff_rel_to_cf_max": (main_["ux"]["converged"][i2] - cfm["ux_m"][i2]) / sc_x,
                "x0.0875_error_ux": results["x0.0875_y0"]["ux"]["closed_form_error_metric"],
                "x0.0875_error_uz": results["x0.0875_y0"]["uz"]["closed_form_error_metric"],
            },
        }
        fr.write_json(out, sig_round(data), log)
    return 0


if __name__ == "__main__":
    sys.exit(main())
