#!/usr/bin/env python3
"""FEM references for bending: a slender 3D cantilever and the 2D oscillating plate.

1. `cantilever`: 3D cantilever, x in [0, 1] m, square section b = h = 0.1 m centred
   on the x axis, rho = 1000 kg/m^3, E = 1e8 Pa, nu = 0.3, clamped at x = 0 (u = 0),
   free elsewhere, gravity 9.81 m/s^2 along -z.  Linear elasticity, 27-node hexes:
     - the lowest 12 modes (z-bending f1, first 8 labelled, first torsion);
     - static deflection under self weight: u_z on the axis (tip and 201 samples)
       and averaged over the tip face;
     - the first peak of the tip's u_z when gravity is applied suddenly (modal
       superposition over 40 modes with the static remainder of the others);
     - f1 and torsion again for nu = 0.499, with the displacement Hex27 element
       (which locks in bending) and with the mixed Q2-P1disc element (pressure
       condensed per element; locking-free);
     - an inextensible Euler-Bernoulli elastica under the dead load q = rho g b h
       (shooting, cross-checked with solve_bvp) at three load levels, with the
       linear EB and linear 3D FEM tip deflections at the same loads.
   Writes reference/cantilever3d_fem.json.
2. `plate`: the 2D oscillating plate of Gray, Monaghan & Swift (2001) in plane
   strain: x in [0, 0.2] m, y in [-0.01, 0.01] m, rho = 1000, E = 2e6 Pa,
   nu = 0.3975, clamped at x = 0, 9-node quadrilaterals:
     - the lowest 6 modes (f1 and first 4 labelled), the first mode shape along
       the axis (201 samples, 1 at the tip);
     - static u_y under a body force -9.81 m/s^2 along y (tip and 201 samples);
     - the first peak of the tip's u_y when that body force is applied suddenly (30 modes);
     - thin-plate theory f1 and the GMS initial velocity profile.
   Writes reference/plate2d_fem.json.

Meshes: tensor meshes, graded towards the clamp and the lateral faces by a fixed
mapping of a uniform parameter grid, x = L xi^1.5 and y = (b/2) sin(pi eta / 2)
(z likewise), so refining the parameter grid gives a consistent family for the
Richardson extrapolation (h = 1/ny).  Elements have the aspect ~2 in x.  Element
matrices come from tools/fem_reference.py (scikit-fem, consistent mass, full
Gauss quadrature), checked against scikit-fem's global assembly on the coarsest
mesh.  Modes: eigsh in shift-invert about 0 with one SuperLU factorisation of K
shared with the static solve; modes are classified and the degenerate y/z pairs
rotated as in fem_reference.py.

Usage:
  .venv-fem/bin/python tools/fem_bending.py cantilever    # writes reference/cantilever3d_fem.json
  .venv-fem/bin/python tools/fem_bending.py plate         # writes reference/plate2d_fem.json
  .venv-fem/bin/python tools/fem_bending.py all
  .venv-fem/bin/python tools/fem_bending.py all --quick   # coarse smoke run; writes only with --out-dir
"""

import argparse
import json
import math
import os
import platform
import sys
import time

import numpy as np
import scipy
import scipy.sparse.linalg as spla
from scipy.integrate import solve_bvp, solve_ivp
from scipy.optimize import brentq

import skfem
from skfem import FacetBasis, LinearForm, asm
from skfem.models.elasticity import lame_parameters

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fem_reference as fr  # noqa: E402  (shared assembly, mode tidying, Richardson, rounding)

REPO = fr.REPO
G_ACC = 9.81
NAXIS = 201                      # axis samples written to the JSON
PEAK_MODES_CANT = 40             # modes for the sudden-gravity peak (second eigsh)
PEAK_MODES_PLATE = 30
PEAK_DOC = ("gravity applied suddenly at t = 0 from rest, undamped: modal superposition "
            "u(t) = u_static - sum_k phi_k (phi_k^T f / omega_k^2) cos(omega_k t) over the "
            "lowest modes of a second eigsh (the static remainder of the others kept: "
            "mode-acceleration form); 'first peak' = the extremum over t in [0, 1/f1] (the "
            "first period of the mesh's own f1), also the extremum over [0, 5/f1]; '_modal' "
            "holds the truncation checks (half the modes; the pure truncated sum)")
X_POWER = 1.5                    # x = L xi^1.5 (grading towards the clamp)
ASPECT = 2.0                     # element length in x / mean element width: nx = 5 ny

# ---------------------------------------------------------------- problems
CANT = {"L": 1.0, "b": 0.1, "h": 0.1, "rho": 1000.0, "E": 1.0e8, "nu": 0.3}
NU_INCOMP = 0.499
ELASTICA_TARGETS = (0.30, 0.45, 0.60)      # tip deflection / L
PLATE = {"L": 0.2, "H": 0.02, "rho": 1000.0, "E": 2.0e6, "nu": 0.3975}
# first root of 1 + cos(kL) cosh(kL) = 0 (refined below with brentq)
KL1 = brentq(lambda k: 1.0 + math.cos(k) * math.cosh(k), 1.8, 1.95, xtol=1e-15)


def log(*a):
    print(*a, flush=True)


def graded(n, a, b, kind):
    """n elements on [a, b]: 'clamp' -> a + (b-a) xi^X_POWER, 'faces' -> sine clustering."""
    t = np.linspace(0.0, 1.0, n + 1)
    if kind == "clamp":
        s = t ** X_POWER
    elif kind == "faces":
        s = 0.5 * (1.0 + np.sin(np.pi * (t - 0.5)))
    else:
        s = t
    x = a + (b - a) * s
    x[0], x[-1] = a, b
    return x


def coords_for(ny, Lx, widths):
    """Tensor grid: nx = Lx ny / (ASPECT width) elements along x (graded to the clamp),
    ny across each width (graded to the faces)."""
    w0 = widths[0]
    nx = int(round(Lx / (ASPECT * w0 / ny)))
    cs = [graded(nx, 0.0, Lx, "clamp")] + [graded(ny, -w / 2, w / 2, "faces") for w in widths]
    return cs, [nx] + [ny] * len(widths)


# ---------------------------------------------------------------- solver
def solve(coords, E, nu, rho, g, nmodes, volumetric="full", check=False, label="",
          peak_modes=0):
    """Clamped at x = 0; static solve under -rho g (last axis) and lowest modes."""
    t0 = time.time()
    lam, mu = lame_parameters(E, nu)
    mesh, basis, K, M, f = fr.assemble_tensor(coords, lam, mu, rho, g, check=check,
                                              scaled=True, volumetric=volumetric)
    fixed = np.abs(basis.doflocs[0]) <= 1e-12
    return solve_system(mesh, basis, K, M, f, fixed, nmodes, label=label, t_start=t0,
                        peak_modes=peak_modes)


def solve_system(mesh, basis, K, M, f, fixed, nmodes, label="", t_start=None, peak_modes=0,
                 permc_spec="COLAMD", perm=None):
    """Static solve K u = f and the lowest nmodes modes of K phi = omega^2 M phi with the
    DOFs `fixed` (bool mask) held at 0: one SuperLU factorisation of K (no pivoting, K is
    SPD), eigsh in shift-invert about 0 with a fixed start vector, modes tidied and
    classified by fr.tidy_modes.  peak_modes > 0: a second eigsh with that many modes
    (the first result is left as it is) for modal superposition (res["peak_basis"]).
    res["lu"] and res["free"] allow further load cases.  perm: a function that reorders
    the free DOFs (e.g. a nested dissection); SuperLU then keeps that order."""
    t0 = time.time() if t_start is None else t_start
    comp = fr.dof_components(basis)
    free = np.flatnonzero(~fixed)
    if perm is not None:
        free = perm(free)
        permc_spec = "NATURAL"
    Kc = K[free][:, free].tocsc()
    Mc = M[free][:, free].tocsr()
    fc = f[free]
    t_asm = time.time() - t0
    t0 = time.time()
    # K is SPD: no pivoting, symmetric mode (much less fill than the default for nu -> 1/2)
    lu = spla.splu(Kc, permc_spec=permc_spec, diag_pivot_thresh=0.0,
                   options={"SymmetricMode": True})
    t_lu = time.time() - t0
    t0 = time.time()
    us = lu.solve(fc)
    op = spla.LinearOperator(Kc.shape, matvec=lu.solve, dtype=float)
    w2, V = spla.eigsh(Kc, k=nmodes, M=Mc, sigma=0.0, OPinv=op, which="LM",
                       v0=np.ones(Kc.shape[0]), tol=1e-12)
    order = np.argsort(w2)
    w2, V = w2[order], V[:, order]
    modes, V, pf = fr.tidy_modes(w2, V, Mc, comp[free], basis.doflocs[:, free], fc, us)
    peak_basis = None
    if peak_modes:
        w2p, Vp = spla.eigsh(Kc, k=peak_modes, M=Mc, sigma=0.0, OPinv=op, which="LM",
                             v0=np.ones(Kc.shape[0]), tol=1e-12)
        order = np.argsort(w2p)
        w2p, Vp = w2p[order], Vp[:, order]
        Vp = Vp / np.sqrt(np.einsum("ij,ij->j", Vp, Mc @ Vp))
        peak_basis = {"w2": w2p, "V": Vp}
    t_eig = time.time() - t0

    def full(v):
        out = np.zeros(basis.N)
        out[free] = v
        return out

    res = {"mesh": mesh, "basis": basis, "u": full(us), "V": V, "full": full,
           "modes": modes, "dofs": int(basis.N), "elements": int(mesh.t.shape[1]),
           "lu_nnz": int(lu.L.nnz + lu.U.nnz), "lu": lu, "free": free, "f": f, "w2": w2, "pf": pf,
           "peak_basis": peak_basis,
           "timing_s": {"assembly": t_asm, "lu": t_lu, "static_and_eigs": t_eig}}
    log(f"  {label}: {basis.N} dofs, asm {t_asm:.1f}s, LU {t_lu:.1f}s "
        f"(nnz {res['lu_nnz']:.2e}), eig {t_eig:.1f}s")
    return res


def sudden_load_peaks(res, rows, f_load=None, t_first=None, periods=5, label_modes=None):
    """Peak response at probes for the load f_load (default: the static load of `res`)
    applied suddenly at t = 0 from rest, undamped, by modal superposition over the modes
    of res["peak_basis"] (or res's own modes) plus the static remainder of the others.
    rows: sparse probe matrix (n_probes x N).  t_first: the first period 1/f1; the first
    peak is the extremum, in the direction of the static value, over t in [0, t_first];
    also over [0, periods t_first].  Returns per probe: static, first peak and its time,
    the peak over `periods` periods, and the first peak with half the modes and with
    the truncated modal sum (checks of the modal truncation)."""
    free, lu = res["free"], res["lu"]
    pb = res["peak_basis"] or {"w2": res["w2"], "V": res["V"]}
    w2, V = pb["w2"], pb["V"]
    if f_load is None:
        fc = res["f"][free]
        us_full = res["u"]
    else:
        fc = f_load[free]
        us_full = res["full"](lu.solve(fc))
    omega = np.sqrt(w2)
    amp = (V.T @ fc) / w2
    R = rows.tocsr()
    ust = R @ us_full
    um = (R[:, free] @ V)                               # n_probes x nm
    nm = V.shape[1]
    dt = min(t_first / 4000.0, 2 * math.pi / omega[-1] / 40)
    out = []
    for p in range(R.shape[0]):
        d = -1 if ust[p] < 0 else 1
        pk, tp = fr.modal_peak(ust[p], um[p], amp, omega, t_first, dt, d)
        pk5, tp5 = fr.modal_peak(ust[p], um[p], amp, omega, periods * t_first, dt, d)
        h = max(1, nm // 2)
        pkh, _ = fr.modal_peak(ust[p], um[p, :h], amp[:h], omega[:h], t_first,
                               min(t_first / 4000.0, 2 * math.pi / omega[h - 1] / 40), d)
        trunc = float((um[p] * amp).sum())
        pkt, _ = fr.modal_peak(trunc, um[p], amp, omega, t_first, dt, d)
        out.append({"static": float(ust[p]), "peak_first": pk, "peak_first_t_s": tp,
                    "peak_over_periods": pk5, "peak_over_periods_t_s": tp5,
                    "peak_first_half_modes": pkh, "peak_first_truncated_sum": pkt,
                    "static_truncated_sum": trunc})
    return out, {"modes_used": nm, "highest_mode_hz": float(omega[-1] / (2 * math.pi)),
                 "periods": periods}


def probe_rows(basis, pts, comp):
    """Rows of the probe matrix giving component `comp` at the points pts (dim x n)."""
    n = pts.shape[1]
    return basis.probes(pts).tocsr()[comp * n:(comp + 1) * n]


def first_of(modes, kind):
    return next((m["f_hz"] for m in modes if m["type"].startswith(kind)), None)


def convergence(hs, vals):
    """Richardson (three finest) for the values vals and the finest mesh's deviation."""
    lim, p = fr.richardson(hs, vals)
    out = {"finest": vals[-1], "richardson": lim, "order": p,
           "finest_minus_richardson_rel": (vals[-1] / lim - 1) if lim else None,
           "last_change_rel": (vals[-1] / vals[-2] - 1) if len(vals) > 1 else None}
    return out


def freq_of(row, label):
    return next((m["f_hz"] for m in row["modes"] if m["type"] == label), float("nan"))


def label_convergence(hs, rows, n):
    """Convergence of the finest mesh's first n modes, matched by label on every mesh."""
    return {lab: convergence(hs, [freq_of(r, lab) for r in rows])
            for lab in dict.fromkeys(m["type"] for m in rows[-1]["modes"][:n])}


def change_col(rows, key, i):
    return "" if i == 0 else f"{100 * (rows[i][key] / rows[i - 1][key] - 1):+.4f} %"


def print_table(rows, cols, title):
    """cols: list of (key, header, scale, fmt)."""
    log(f"\n{title}")
    hdr = f"{'mesh':>10} {'dofs':>7}" + "".join(f" {h:>14} {'change':>10}" for _, h, _, _ in cols)
    log(hdr)
    log("-" * len(hdr))
    for i, r in enumerate(rows):
        line = f"{'x'.join(map(str, r['mesh_n'])):>10} {r['dofs']:>7}"
        for k, _, s, fm in cols:
            line += f" {s * r[k]:>14{fm}} {change_col(rows, k, i):>10}"
        log(line)


def print_conv(name, c, scale=1.0, unit=""):
    if c["richardson"] is None:
        log(f"  {name}: finest {scale * c['finest']:.7g}{unit} (no Richardson estimate)")
        return
    log(f"  {name}: finest {scale * c['finest']:.7g}{unit}, Richardson "
        f"{scale * c['richardson']:.7g}{unit} (order {c['order']:.2f}), finest - Richardson "
        f"{100 * c['finest_minus_richardson_rel']:+.4f} %")


def versions():
    return {"python": platform.python_version(), "numpy": np.__version__,
            "scipy": scipy.__version__, "scikit-fem": skfem.__version__}


def strip(r):
    """Per-mesh JSON entry (drop the big arrays)."""
    return {k: v for k, v in r.items() if k not in ("uz_axis", "mode_uy_axis", "mode_ux_top",
                                                     "uy_axis")}


# ---------------------------------------------------------------- cantilever
def check_mixed_element(lam, mu):
    """Q2-P1disc element checks on one box: 6 rigid-body modes; the same energy as the
    displacement element for every complete quadratic field (div u in P1); less
    energy for a field whose divergence is not in P1."""
    h = (0.3, 0.2, 0.15)
    kf = fr.element_matrices(h, lam, mu, 1.0, 1.0)[0]
    km = fr.element_matrices(h, lam, mu, 1.0, 1.0, volumetric="p1disc")[0]
    b1 = fr.Basis(fr.tensor_mesh([np.array([0.0, hi]) for hi in h]), fr.vector_element(3))
    ed1 = b1.element_dofs[:, 0]
    X = b1.doflocs[:, ed1]
    comp = fr.dof_components(b1)
    cl = comp[ed1]
    rng = np.random.default_rng(1)
    mons = [np.ones(X.shape[1])] + [X[a] for a in range(3)] + \
        [X[a] * X[b] for a in range(3) for b in range(a, 3)]
    C = rng.normal(size=(3, len(mons)))
    u = np.array([C[c] @ np.array(mons) for c in range(3)])[cl, np.arange(len(cl))]
    ef, em = u @ kf @ u, u @ km @ u
    w = u + np.where(cl == 0, X[0] * X[1] ** 2, 0.0)       # div gets y^2
    ev = np.linalg.eigvalsh(km)
    ok = (abs(em / ef - 1) < 1e-12 and w @ km @ w < w @ kf @ w
          and np.sum(ev < 1e-10 * ev[-1]) == 6 and abs(km - km.T).max() < 1e-12 * abs(km).max())
    if not ok:
        raise RuntimeError("Q2-P1disc element check failed")
    return ("passed: 6 rigid-body modes, energy of complete quadratic fields equal to Hex27 "
            "(to 1e-12), lower energy for div u outside P1")


def cantilever_level(ny, nu, volumetric, nmodes, check, peak_modes=0):
    P = CANT
    coords, n = coords_for(ny, P["L"], [P["b"], P["h"]])
    r = solve(coords, P["E"], nu, P["rho"], G_ACC, nmodes, volumetric, check,
              label=f"nu={nu} {volumetric} ny={ny} ({'x'.join(map(str, n))})",
              peak_modes=peak_modes)
    modes = r["modes"]
    row = {"mesh_n": n, "elements": r["elements"], "dofs": r["dofs"], "h": 1.0 / ny,
           "f1_bending_z_hz": first_of(modes, "bending-z"),
           "f1_torsion_hz": first_of(modes, "torsion"),
           "f1_axial_hz": first_of(modes, "axial"),
           "frequencies_hz": [m["f_hz"] for m in modes[:8]],
           "mode_types": [m["type"] for m in modes[:8]],
           "timing_s": r["timing_s"]}
    if row["f1_bending_z_hz"] is None or row["f1_torsion_hz"] is None:
        raise RuntimeError("z-bending or torsion mode missing among the computed modes")
    basis, u = r["basis"], r["u"]
    xs = np.linspace(0.0, P["L"], NAXIS)
    uz = probe_rows(basis, np.vstack([xs, 0 * xs, 0 * xs]), 2) @ u
    # tip-face average of u_z
    fb = FacetBasis(r["mesh"], basis.elem, intorder=fr.INTORDER,
                    facets=r["mesh"].facets_satisfying(lambda x: np.abs(x[0] - P["L"]) < 1e-12))
    vz = asm(LinearForm(lambda v, w: v[2]), fb)
    area = vz[basis.split_indices()[2]].sum()
    assert abs(area / (P["b"] * P["h"]) - 1) < 1e-12
    row.update({"static_tip_uz_axis_m": float(uz[-1]),
                "static_tip_uz_face_avg_m": float(vz @ u / area),
                "uz_axis": uz})
    row["modes"] = modes[:8]
    if peak_modes:
        add_peak(row, r, probe_rows(basis, np.array([[P["L"]], [0.0], [0.0]]), 2),
                 "tip_uz_axis", row["f1_bending_z_hz"])
    return row


def add_peak(row, r, rows, name, f1):
    """row["peak_dynamic_<name>_m"] etc.: gravity applied suddenly at t = 0 (first peak,
    over the first period 1/f1), from sudden_load_peaks on one probe."""
    pk, info = sudden_load_peaks(r, rows, t_first=1.0 / f1)
    pk = pk[0]
    row[f"peak_dynamic_{name}_m"] = pk["peak_first"]
    row[f"peak_dynamic_{name}_t_s"] = pk["peak_first_t_s"]
    row[f"peak_dynamic_{name}_over_5_periods_m"] = pk["peak_over_periods"]
    row[f"peak_dynamic_{name}_over_5_periods_t_s"] = pk["peak_over_periods_t_s"]
    row[f"peak_dynamic_{name}_modal"] = dict(info, **{
        "static_full_m": pk["static"], "static_truncated_sum_m": pk["static_truncated_sum"],
        "peak_first_half_modes_m": pk["peak_first_half_modes"],
        "peak_first_truncated_sum_m": pk["peak_first_truncated_sum"]})


def elastica(alpha, n_samples=NAXIS):
    """Inextensible EB cantilever under a uniform dead load along -z, alpha = q L^3 / EI.
    theta(s) (downward rotation): theta'' = -alpha (1 - s) cos theta, theta(0) = 0,
    theta'(1) = 0; x' = cos theta, z' = -sin theta (s, x, z in units of L)."""
    def rhs(s, y):
        th, k = y[0], y[1]
        return [k, -alpha * (1.0 - s) * np.cos(th), np.cos(th), -np.sin(th)]

    def shoot(k0, dense=False):
        return solve_ivp(rhs, (0.0, 1.0), [0.0, k0, 0.0, 0.0], method="DOP853",
                         rtol=1e-13, atol=1e-15, dense_output=dense)

    k0 = brentq(lambda k: shoot(k).y[1, -1], 0.0, 0.5 * alpha, xtol=1e-15, rtol=1e-15)
    sol = shoot(k0, dense=True)
    ss = np.linspace(0.0, 1.0, n_samples)
    Y = sol.sol(ss)
    return {"root_curvature": k0, "tip_x": Y[2, -1], "tip_z": Y[3, -1], "tip_angle": Y[0, -1],
            "s": ss, "x": Y[2], "z": Y[3]}


def elastica_bvp(alpha):
    """solve_bvp cross-check of elastica(): returns (tip_x, tip_z)."""
    def f(s, y):
        return np.vstack([y[1], -alpha * (1.0 - s) * np.cos(y[0]), np.cos(y[0]), -np.sin(y[0])])

    def bc(ya, yb):
        return np.array([ya[0], ya[2], ya[3], yb[1]])

    s = np.linspace(0.0, 1.0, 401)
    y0 = np.vstack([0 * s, 0 * s, s, 0 * s])
    sol = solve_bvp(f, bc, s, y0, tol=1e-11, max_nodes=200000)
    if not sol.success:
        raise RuntimeError(f"solve_bvp failed: {sol.message}")
    return sol.y[2, -1], sol.y[3, -1]


def run_cantilever(levels, inc_levels, mix03_levels, nmodes):
    P = CANT
    t_start = time.time()
    A = P["b"] * P["h"]
    EI = P["E"] * P["b"] * P["h"] ** 3 / 12.0
    q = P["rho"] * G_ACC * A
    log("3D cantilever: L=1, b=h=0.1, rho=1000, E=1e8, clamped at x=0, gravity -z")

    def sequence(nu, vol, lv, peak_modes=0):
        rows = [cantilever_level(n, nu, vol, nmodes, check=(i == 0 and vol == "full"),
                                 peak_modes=peak_modes)
                for i, n in enumerate(lv)]
        return rows, [r["h"] for r in rows]

    def conv_of(hs, rows, keys):
        return {k: convergence(hs, [r[k] for r in rows]) for k in keys}

    rows, hs = sequence(P["nu"], "full", levels, PEAK_MODES_CANT)
    cols = [("f1_bending_z_hz", "f1 z [Hz]", 1, ".6f"), ("f1_torsion_hz", "torsion [Hz]", 1, ".5f"),
            ("static_tip_uz_axis_m", "tip uz [mm]", 1e3, ".6f"),
            ("static_tip_uz_face_avg_m", "face avg [mm]", 1e3, ".6f")]
    print_table(rows, cols, f"nu = {P['nu']}, Hex27 (displacement)")
    conv = conv_of(hs, rows, [c[0] for c in cols] + ["f1_axial_hz"])
    conv_modes = label_convergence(hs, rows, 8)
    for k, c in conv.items():
        print_conv(k, c, 1e3 if k.startswith("static") else 1.0)
    pkey = "peak_dynamic_tip_uz_axis_m"
    print_table(rows, [(pkey, "peak [mm]", 1e3, ".6f")],
                "first peak of u_z(L, 0, 0) under gravity applied suddenly")
    conv_peak = convergence(hs, [r[pkey] for r in rows])
    print_conv(pkey, conv_peak, 1e3)
    fin = rows[-1]
    # axis samples: the finest mesh and the change from the previous one
    uz_axis = fin["uz_axis"]
    axis_change = float(np.abs(uz_axis - rows[-2]["uz_axis"]).max() / abs(uz_axis).max())
    log("finest mesh, lowest 8 modes (Richardson by label):")
    for m in fin["modes"]:
        c = conv_modes[m["type"]]
        rich = "" if c["richardson"] is None else (
            f"  Richardson {c['richardson']:.5f} ({100 * c['finest_minus_richardson_rel']:+.4f} %)")
        log(f"  {m['f_hz']:10.5f} Hz  {m['type']:<12}{rich}")

    # near-incompressible
    mixed_check = check_mixed_element(*lame_parameters(P["E"], NU_INCOMP))
    log(f"Q2-P1disc element check {mixed_check}")
    inc = {}
    inc_cols = [("f1_bending_z_hz", "f1 z [Hz]", 1, ".6f"), ("f1_torsion_hz", "torsion [Hz]", 1, ".5f"),
                ("static_tip_uz_axis_m", "tip uz [mm]", 1e3, ".6f")]
    for vol in ("full", "p1disc"):
        r_, h_ = sequence(NU_INCOMP, vol, inc_levels)
        name = "Hex27 (displacement)" if vol == "full" else "Q2-P1disc (mixed, condensed)"
        print_table(r_, inc_cols, f"nu = {NU_INCOMP}, {name}")
        c_ = conv_of(h_, r_, [c[0] for c in inc_cols])
        for k, c in c_.items():
            print_conv(k, c, 1e3 if k.startswith("static") else 1.0)
        inc[vol] = {"element": name, "meshes": [strip(x) for x in r_], "convergence": c_}
    # mixed element at nu = 0.3: must agree with the displacement element's limit
    r_, h_ = sequence(P["nu"], "p1disc", mix03_levels)
    print_table(r_, cols, f"nu = {P['nu']}, Q2-P1disc (cross-check of the mixed element)")
    mix03 = {"meshes": [strip(x) for x in r_],
             "convergence": conv_of(h_, r_, [c[0] for c in cols])}
    for k, c in mix03["convergence"].items():
        print_conv(k, c, 1e3 if k.startswith("static") else 1.0)

    # elastica load levels
    log("\nelastica (inextensible EB, dead load):")
    lin = elastica(1e-4)
    assert abs(-lin["tip_z"] / (1e-4 / 8) - 1) < 1e-4, "elastica small-load limit"
    fem_tip = fin["static_tip_uz_axis_m"]                 # at g = 9.81
    fem_tip_face = fin["static_tip_uz_face_avg_m"]
    eb_tip = -q * P["L"] ** 4 / (8 * EI)
    ratio = fem_tip / eb_tip
    levels_out = []
    for t in ELASTICA_TARGETS:
        a_t = brentq(lambda a: -elastica(a, 2)["tip_z"] - t, 8 * t, 60 * t, xtol=1e-13)
        g_exact = a_t * EI / (P["rho"] * A * P["L"] ** 3)
        g_lvl = float(f"{g_exact:.3g}")
        alpha = g_lvl * P["rho"] * A * P["L"] ** 3 / EI
        el = elastica(alpha)
        bx, bz = elastica_bvp(alpha)
        if abs(bx - el["tip_x"]) > 1e-8 or abs(bz - el["tip_z"]) > 1e-8:
            raise RuntimeError(f"elastica shooting vs solve_bvp: {el['tip_x']} {bx} {el['tip_z']} {bz}")
        s = g_lvl / G_ACC
        lv = {
            "target_tip_deflection_over_L": t,
            "g_m_s2": g_lvl,
            "q_N_m": P["rho"] * g_lvl * A,
            "alpha_qL3_over_EI": alpha,
            "elastica_tip_uz_m": el["tip_z"] * P["L"],
            "elastica_tip_ux_m": (el["tip_x"] - 1.0) * P["L"],
            "elastica_tip_rotation_rad": el["tip_angle"],
            "elastica_tip_uz_over_L": el["tip_z"],
            "elastica_root_curvature_1_m": el["root_curvature"] / P["L"],
            "elastica_root_max_bending_strain": el["root_curvature"] / P["L"] * P["h"] / 2,
            "linear_eb_tip_uz_m": eb_tip * s,
            "linear_fem3d_tip_uz_axis_m": fem_tip * s,
            "linear_fem3d_tip_uz_face_avg_m": fem_tip_face * s,
            "elastica_x_fem_over_eb_tip_uz_m": el["tip_z"] * P["L"] * ratio,
            "elastica_x_fem_over_eb_tip_ux_m": (el["tip_x"] - 1.0) * P["L"] * ratio,
            "bvp_check_tip_ux_m": (bx - 1.0) * P["L"],
            "bvp_check_tip_uz_m": bz * P["L"],
            "shape": {"s_m": list(el["s"] * P["L"]),
                      "ux_m": list((el["x"] - el["s"]) * P["L"]),
                      "uz_m": list(el["z"] * P["L"])},
        }
        levels_out.append(lv)
        log(f"  target {t:.2f} L: g = {g_lvl:g} m/s^2 (alpha = {alpha:.5f}): tip u_z = "
            f"{1e3 * lv['elastica_tip_uz_m']:.4f} mm ({el['tip_z']:.5f} L), u_x = "
            f"{1e3 * lv['elastica_tip_ux_m']:.4f} mm; linear EB {1e3 * lv['linear_eb_tip_uz_m']:.3f} mm, "
            f"linear FEM {1e3 * lv['linear_fem3d_tip_uz_axis_m']:.3f} mm; root strain "
            f"{lv['elastica_root_max_bending_strain']:.4f}")

    wall = time.time() - t_start
    log(f"\ncantilever run time {wall:.1f} s")

    xs = np.linspace(0.0, P["L"], NAXIS)
    data = {
        "case": "slender 3D cantilever under self weight: linear-elasticity FEM reference, "
                "near-incompressible check, elastica load levels",
        "problem": {
            "length_m": P["L"], "width_m": P["b"], "height_m": P["h"],
            "section": "y, z in [-0.05, 0.05] (centred on the x axis)",
            "rho_kg_m3": P["rho"], "E_pa": P["E"], "nu": P["nu"], "g_m_s2": G_ACC,
            "gravity_direction": "-z",
            "bc_x0": "clamped: u = 0 on the whole face x = 0",
            "bc_other": "all other faces free",
            "axis": "y = z = 0",
            "sign": "deflections negative = downward (-z)",
            "EI_N_m2": EI, "q_N_m_at_g": q,
        },
        "method": {
            "code": "tools/fem_bending.py cantilever (assembly from tools/fem_reference.py)",
            "elements": "tensor hexahedral mesh of 27-node triquadratic elements "
                        "(scikit-fem ElementVector(ElementHex2)), consistent mass, 3x3x3 Gauss",
            "mesh": f"nx x ny x nz with nx = 5 ny, nz = ny; nodes x = L xi^{X_POWER} (graded "
                    "towards the clamp), y = (b/2) sin(pi eta/2) for eta in [-1, 1], z likewise "
                    "(graded towards the faces), xi, eta uniform",
            "richardson": "f = f_inf + C h^p through the three finest meshes, h = 1/ny",
            "eigensolver": "scipy eigsh, shift-invert about 0 (lowest 12 modes), SuperLU "
                           "(COLAMD, no pivoting) of K shared with the static solve",
            "mode_classification": "kinetic-energy split over u_x/u_y/u_z and torsional "
                                   "participation, as tools/fem_reference.py; the degenerate "
                                   "y/z bending pair is rotated so that the z mode is pure",
            "tip_face_average": "integral of u_z over the face x = L divided by b h",
            "peak_dynamic": PEAK_DOC + f" ({PEAK_MODES_CANT} modes; probe: the tip on the axis)",
            "near_incompressible": "nu = 0.499 with the displacement Hex27 element and with "
                                   "the mixed Q2-P1disc element (lam div u div v with div u "
                                   "projected element-wise onto P1 = {1, x, y, z}, i.e. the "
                                   "pressure condensed per element; inf-sup stable, no "
                                   "volumetric locking)",
            "mixed_element_check": mixed_check,
            "elastica": "inextensible Euler-Bernoulli elastica, theta'' = -(q/EI)(L - s) cos theta, "
                        "theta(0) = 0, theta'(L) = 0, dead (direction-fixed) load q = rho g b h per "
                        "unit undeformed length; shooting on theta'(0) with DOP853 (rtol 1e-13) "
                        "and brentq, cross-checked with scipy solve_bvp",
            "versions": versions(),
            "wall_time_s": round(wall),
        },
        "meshes": [strip(r) for r in rows],
        "converged": {
            "mesh_n": fin["mesh_n"], "dofs": fin["dofs"],
            "f1_bending_z_hz": fin["f1_bending_z_hz"],
            "period_s": 1.0 / fin["f1_bending_z_hz"],
            "f1_torsion_hz": fin["f1_torsion_hz"],
            "f1_axial_hz": fin["f1_axial_hz"],
            "static_tip_uz_axis_m": fin["static_tip_uz_axis_m"],
            "static_tip_uz_face_avg_m": fin["static_tip_uz_face_avg_m"],
            "peak_dynamic_tip_uz_axis_m": fin["peak_dynamic_tip_uz_axis_m"],
            "peak_dynamic_tip_uz_axis_t_s": fin["peak_dynamic_tip_uz_axis_t_s"],
            "peak_dynamic_tip_uz_axis_over_5_periods_m":
                fin["peak_dynamic_tip_uz_axis_over_5_periods_m"],
            "dynamic_amplification": fin["peak_dynamic_tip_uz_axis_m"] / fin["static_tip_uz_axis_m"],
            "peak_dynamic_convergence": conv_peak,
            "convergence": conv,
            "lowest_modes": [{"f_hz": m["f_hz"], "type": m["type"]} for m in fin["modes"]],
            "lowest_modes_convergence": conv_modes,
            "static_uz_axis": {"x_m": list(xs), "uz_m": list(uz_axis),
                               "max_rel_change_from_previous_mesh": axis_change},
        },
        "near_incompressible": {
            "nu": NU_INCOMP,
            "converged": {
                "element": "Q2-P1disc (mixed), finest mesh",
                "f1_bending_z_hz": inc["p1disc"]["meshes"][-1]["f1_bending_z_hz"],
                "f1_torsion_hz": inc["p1disc"]["meshes"][-1]["f1_torsion_hz"],
                "static_tip_uz_axis_m": inc["p1disc"]["meshes"][-1]["static_tip_uz_axis_m"],
                "f1_bending_z_richardson_hz": inc["p1disc"]["convergence"]["f1_bending_z_hz"]["richardson"],
                "f1_torsion_richardson_hz": inc["p1disc"]["convergence"]["f1_torsion_hz"]["richardson"],
                "displacement_hex27_finest_f1_bending_z_hz": inc["full"]["meshes"][-1]["f1_bending_z_hz"],
                "displacement_hex27_finest_f1_torsion_hz": inc["full"]["meshes"][-1]["f1_torsion_hz"],
                "note": "the displacement Hex27 element locks mildly in bending at nu = 0.499 "
                        "(too stiff, slow convergence of order ~1.8; its Richardson limit agrees "
                        "with the mixed element's); torsion is isochoric and converges with both",
            },
            "displacement_hex27": inc["full"],
            "mixed_q2_p1disc": inc["p1disc"],
            "mixed_q2_p1disc_at_nu_0_3_check": mix03,
        },
        "beam_theory": {
            "euler_bernoulli_f1_hz": KL1 ** 2 / (2 * math.pi * P["L"] ** 2)
            * math.sqrt(EI / (P["rho"] * A)),
            "euler_bernoulli_tip_uz_m": eb_tip,
            "fem_over_eb_tip_uz": ratio,
            "saint_venant_torsion_f1_hz_free_warping": saint_venant_torsion(P["nu"]),
        },
        "elastica": {
            "note": "dead load: gravity keeps its direction (-z) and its magnitude per unit "
                    "undeformed length; EI = E b h^3/12, q = rho g b h; inextensible, no shear; "
                    "ux, uz at the tip s = L; 'linear_*' are the linear values at the same g "
                    "(linear 3D FEM = finest-mesh value scaled by g/9.81); "
                    "'elastica_x_fem_over_eb' = elastica x (linear FEM / linear EB) with the "
                    "axis tip ratio",
            "fem_over_eb_tip_uz": ratio,
            "levels": levels_out,
        },
    }
    return data


def saint_venant_torsion(nu):
    """Clamped-free torsion f1 with free warping: (1/4L) sqrt(G J / (rho I_p)), square section."""
    P = CANT
    a = P["b"]
    # J of a square: k a^4, k = 1/3 (1 - 192/pi^5 sum tanh(n pi/2)/n^5 over odd n)
    ssum = sum(math.tanh(n * math.pi / 2) / n ** 5 for n in range(1, 200, 2))
    J = a ** 4 / 3.0 * (1.0 - 192.0 / math.pi ** 5 * ssum)
    Ip = a ** 4 / 6.0
    G = P["E"] / (2 * (1 + nu))
    return math.sqrt(G * J / (P["rho"] * Ip)) / (4 * P["L"])


# ---------------------------------------------------------------- plate
def plate_level(ny, nmodes, check):
    P = PLATE
    coords, n = coords_for(ny, P["L"], [P["H"]])
    r = solve(coords, P["E"], P["nu"], P["rho"], G_ACC, nmodes, "full", check,
              label=f"plate ny={ny} ({'x'.join(map(str, n))})", peak_modes=PEAK_MODES_PLATE)
    basis, u = r["basis"], r["u"]
    modes = [{"f_hz": m["f_hz"], "type": m["type"].replace("bending-y", "bending"),
              "ke_fraction_xy": m["ke_fraction_xyz"],
              "y_load_participation": m["z_load_participation"]} for m in r["modes"]]
    xs = np.linspace(0.0, P["L"], NAXIS)
    axis = np.vstack([xs, 0 * xs])
    top = np.vstack([xs, 0 * xs + P["H"] / 2])
    Py, Px_top = probe_rows(basis, axis, 1), probe_rows(basis, top, 0)
    uy = Py @ u
    i1 = next(k for k, m in enumerate(modes) if m["type"].startswith("bending"))
    ph = r["full"](r["V"][:, i1])
    ph_axis = Py @ ph
    scale = ph_axis[-1]
    row = {"mesh_n": n, "elements": r["elements"], "dofs": r["dofs"], "h": 1.0 / ny,
           "f1_hz": modes[i1]["f_hz"],
           "frequencies_hz": [m["f_hz"] for m in modes[:4]],
           "mode_types": [m["type"] for m in modes[:4]],
           "static_tip_uy_m": float(uy[-1]),
           "uy_axis": uy, "mode_uy_axis": ph_axis / scale, "mode_ux_top": (Px_top @ ph) / scale,
           "modes": modes[:6], "timing_s": r["timing_s"]}
    add_peak(row, r, probe_rows(basis, np.array([[P["L"]], [0.0]]), 1), "tip_uy", row["f1_hz"])
    return row


def gms_profile(x, L, kl):
    """f(x) / f(L) of Gray, Monaghan & Swift (2001)."""
    def f(xx):
        k = kl / L
        return ((math.cos(kl) + math.cosh(kl)) * (np.cosh(k * xx) - np.cos(k * xx))
                + (math.sin(kl) - math.sinh(kl)) * (np.sinh(k * xx) - np.sin(k * xx)))
    return f(x) / f(L)


def run_plate(levels, nmodes):
    P = PLATE
    t_start = time.time()
    log("2D plate (GMS 2001), plane strain: L=0.2, H=0.02, rho=1000, E=2e6, nu=0.3975")
    rows = [plate_level(n, nmodes, check=(i == 0)) for i, n in enumerate(levels)]
    hs = [r["h"] for r in rows]
    cols = [("f1_hz", "f1 [Hz]", 1, ".7f"), ("static_tip_uy_m", "tip uy [mm]", 1e3, ".7f")]
    print_table(rows, cols, "plate, Quad9 plane strain")
    fin = rows[-1]
    conv = {k: convergence(hs, [r[k] for r in rows]) for k, _, _, _ in cols}
    pkey = "peak_dynamic_tip_uy_m"
    print_table(rows, [(pkey, "peak [mm]", 1e3, ".7f")],
                "first peak of u_y(L, 0) under gravity applied suddenly")
    conv_peak = convergence(hs, [r[pkey] for r in rows])
    print_conv(pkey, conv_peak, 1e3)
    conv_modes = label_convergence(hs, rows, 4)
    for lab, c in conv_modes.items():
        print_conv(lab, c)
    for k, c in conv.items():
        print_conv(k, c, 1e3 if k.startswith("static") else 1.0)
    log("finest mesh, lowest modes:")
    for m in fin["modes"]:
        log(f"  {m['f_hz']:10.5f} Hz  {m['type']}")
    mode_change = float(np.abs(fin["mode_uy_axis"] - rows[-2]["mode_uy_axis"]).max())
    axis_change = float(np.abs(fin["uy_axis"] - rows[-2]["uy_axis"]).max() / abs(fin["uy_axis"]).max())

    E, nu, rho, H, L = P["E"], P["nu"], P["rho"], P["H"], P["L"]
    k = KL1 / L
    w_thin = math.sqrt(E * H ** 2 * k ** 4 / (12 * rho * (1 - nu ** 2)))
    k_brief = 1.875104 / L
    w_thin_brief = math.sqrt(E * H ** 2 * k_brief ** 4 / (12 * rho * (1 - nu ** 2)))
    D = E * H ** 3 / (12 * (1 - nu ** 2))
    eb_tip = -rho * G_ACC * H * L ** 4 / (8 * D)
    c0 = math.sqrt(E / (3 * (1 - 2 * nu) * rho))
    xs = np.linspace(0.0, L, NAXIS)
    gms = gms_profile(xs, L, KL1)
    log(f"thin-plate theory: omega = {w_thin:.6f} rad/s, f1 = {w_thin / (2 * math.pi):.6f} Hz, "
        f"T = {2 * math.pi / w_thin:.6f} s; FEM f1 / thin = {fin['f1_hz'] * 2 * math.pi / w_thin:.5f}")
    log(f"c0 = sqrt(E/(3(1-2nu)rho)) = {c0:.6f} m/s; plane-strain EB tip u_y = {1e3 * eb_tip:.6f} mm")
    log(f"max |FEM mode 1 - GMS profile| on the axis = {np.abs(fin['mode_uy_axis'] - gms).max():.2e}")
    wall = time.time() - t_start
    log(f"plate run time {wall:.1f} s")

    data = {
        "case": "2D oscillating plate of Gray, Monaghan & Swift (2001), plane strain: "
                "linear-elasticity FEM reference",
        "problem": {
            "length_m": L, "thickness_m": H, "section": "y in [-0.01, 0.01]",
            "rho_kg_m3": rho, "E_pa": E, "nu": nu,
            "plane": "plane strain (per unit depth)",
            "bc_x0": "clamped: u = 0 on the edge x = 0", "bc_other": "free",
            "static_load": "body force -9.81 m/s^2 along y (linear, small strain); "
                           "displacements are proportional to g",
            "axis": "y = 0", "sign": "deflections negative = downward (-y)",
        },
        "method": {
            "code": "tools/fem_bending.py plate (assembly from tools/fem_reference.py)",
            "elements": "tensor quadrilateral mesh of 9-node biquadratic elements "
                        "(scikit-fem ElementVector(ElementQuad2)), plane strain, consistent "
                        "mass, 3x3 Gauss",
            "mesh": f"nx x ny with nx = 5 ny; nodes x = L xi^{X_POWER}, "
                    "y = (H/2) sin(pi eta/2) for eta in [-1, 1], xi, eta uniform",
            "richardson": "f = f_inf + C h^p through the three finest meshes, h = 1/ny",
            "eigensolver": "scipy eigsh, shift-invert about 0 (lowest 6 modes), SuperLU",
            "peak_dynamic": PEAK_DOC + f" ({PEAK_MODES_PLATE} modes; probe: (L, 0)); linear, "
                            "so the peak per unit g is the value to use",
            "versions": versions(),
            "wall_time_s": round(wall),
        },
        "meshes": [strip(r) for r in rows],
        "converged": {
            "mesh_n": fin["mesh_n"], "dofs": fin["dofs"],
            "f1_hz": fin["f1_hz"], "omega1_rad_s": 2 * math.pi * fin["f1_hz"],
            "period_s": 1.0 / fin["f1_hz"],
            "lowest_modes": [{"f_hz": m["f_hz"], "type": m["type"]} for m in fin["modes"][:4]],
            "lowest_modes_convergence": conv_modes,
            "static_tip_uy_m": fin["static_tip_uy_m"],
            "static_tip_uy_per_unit_g_m_per_m_s2": fin["static_tip_uy_m"] / G_ACC,
            "peak_dynamic_tip_uy_m": fin["peak_dynamic_tip_uy_m"],
            "peak_dynamic_tip_uy_t_s": fin["peak_dynamic_tip_uy_t_s"],
            "peak_dynamic_tip_uy_per_unit_g_m_per_m_s2": fin["peak_dynamic_tip_uy_m"] / G_ACC,
            "peak_dynamic_tip_uy_over_5_periods_m": fin["peak_dynamic_tip_uy_over_5_periods_m"],
            "dynamic_amplification": fin["peak_dynamic_tip_uy_m"] / fin["static_tip_uy_m"],
            "peak_dynamic_convergence": conv_peak,
            "convergence": conv,
            "static_uy_axis": {"x_m": list(xs), "uy_m": list(fin["uy_axis"]),
                               "uy_per_unit_g": list(fin["uy_axis"] / G_ACC),
                               "max_rel_change_from_previous_mesh": axis_change},
            "mode1": {"x_m": list(xs),
                      "uy_axis": list(fin["mode_uy_axis"]),
                      "ux_top": list(fin["mode_ux_top"]),
                      "normalisation": "u_y(L, 0) = 1; ux_top is u_x at y = +H/2 with the "
                                       "same scaling (u_x(x, y) ~ (2y/H) ux_top(x))",
                      "max_abs_change_from_previous_mesh": mode_change,
                      "max_abs_diff_from_gms_profile": float(np.abs(fin["mode_uy_axis"] - gms).max())},
        },
        "thin_plate_theory": {
            "formula": "omega^2 = E H^2 k^4 / (12 rho (1 - nu^2)), k L = 1.875104",
            "kL": 1.875104, "kL_exact_root": KL1,
            "omega_rad_s": w_thin_brief, "f1_hz": w_thin_brief / (2 * math.pi),
            "period_s": 2 * math.pi / w_thin_brief,
            "fem_f1_over_thin_plate": fin["f1_hz"] * 2 * math.pi / w_thin_brief,
            "eb_static_tip_uy_m": eb_tip,
            "fem_static_over_eb": fin["static_tip_uy_m"] / eb_tip,
        },
        "gms_initial_velocity": {
            "formula": "v_y(x) = V_f c0 f(x)/f(L), f(x) = (cos kL + cosh kL)(cosh kx - cos kx) "
                       "+ (sin kL - sinh kL)(sinh kx - sin kx), v_x = 0",
            "c0_formula": "c0 = sqrt(E / (3 (1 - 2 nu) rho)) (bulk sound speed, as SPHinXsys "
                          "ElasticSolid::c0_ and PySPH get_speed_of_sound)",
            "c0_m_s": c0,
            "kL": KL1,
            "x_m": list(xs),
            "f_over_fL": list(gms),
            "note": "SPHinXsys writes the same shape as (M (cos kx - cosh kx) - N (sin kx - sinh kx))/Q "
                    "with M = sin kL + sinh kL, N = cos kL + cosh kL, Q = 2 (cos kL sinh kL - "
                    "sin kL cosh kL); the two agree where 1 + cos kL cosh kL = 0. SPHinXsys "
                    "(test_2d_oscillating_beam) uses kL = 1.875 and V_f = 0.05",
        },
    }
    return data


# ---------------------------------------------------------------- main
def write(data, path):
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, "w") as fh:
        json.dump(fr.rounded(data), fh, indent=1)
        fh.write("\n")
    log(f"wrote {path}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("what", choices=["cantilever", "plate", "all"])
    ap.add_argument("--quick", action="store_true", help="coarse meshes only (smoke run)")
    ap.add_argument("--out-dir", help="directory for the JSON files; without it only a full "
                                      "run writes, into reference/")
    args = ap.parse_args(argv)
    out_dir = args.out_dir or (None if args.quick else os.path.join(REPO, "reference"))
    if args.what in ("cantilever", "all"):
        if args.quick:
            d = run_cantilever([1, 2, 3], [1, 2, 3], [1, 2, 3], 12)
        else:
            d = run_cantilever([2, 4, 6, 8], [2, 4, 6, 8], [2, 4, 6], 12)
        if out_dir:
            write(d, os.path.join(out_dir, "cantilever3d_fem.json"))
    if args.what in ("plate", "all"):
        d = run_plate([2, 4, 8] if args.quick else [4, 8, 16, 32], 6)
        if out_dir:
            write(d, os.path.join(out_dir, "plate2d_fem.json"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
