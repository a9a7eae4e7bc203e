#!/usr/bin/env python3
"""3D linear-elasticity FEM reference for paper Case 2 (clamped-pinned beam).

Beam along x, L = 1 m, square section b = h = 0.225 m centred on the x axis,
rho = 1000 kg/m^3, E = 6 MPa, nu = 0.3, gravity 9.81 m/s^2 along -z.

Supports:
  x = 0 : clamped, u = 0 on the whole face (both variants).
  x = L : "face" variant (the reference): u_y = u_z = 0 on the whole face,
          u_x free.  "line" variant: u_y = u_z = 0 only on the line z = 0
          (all y) of that face; a line support is singular in a 3D continuum
          and is not expected to converge with refinement.

Discretisation: structured hexahedral meshes of triquadratic 27-node elements
(scikit-fem MeshHex + ElementVector(ElementHex2)), consistent mass, 3x3x3
Gauss quadrature (intorder=5).  Every element of a tensor mesh is the same
box, so the element matrices are computed once by scikit-fem on a one-element
mesh and scattered; at the coarsest level this is checked against scikit-fem's
own global assembly.

Per mesh:
  1. Lowest eigenpairs of K phi = omega^2 M phi (shift-invert about 0, i.e. the
     lowest modes, one sparse LU of K shared with the static solve); modes are
     classified by their kinetic-energy split over u_x/u_y/u_z; within a
     degenerate cluster (y/z bending of the square section) the basis is
     rotated so that the z-bending mode is pure.
  2. Static deflection under self weight, sampled along the axis y = z = 0.
  3. Peak of u_z(t) for gravity applied suddenly at t = 0 from rest, undamped,
     t in [0, 0.5] s, by modal superposition:
        u(t) = sum_k phi_k (phi_k^T f) / omega_k^2 (1 - cos omega_k t).
     The reported value uses the retained modes plus the static remainder of
     the others (mode-acceleration form: u = u_static - sum_k ... cos(omega_k t),
     exact but for the vibration of the unretained modes); the pure truncated
     sum is reported too as a check.
  4. Euler-Bernoulli and Timoshenko beam values (Timoshenko frequency from its
     frequency equation; cross-checked with a fine 1D Timoshenko FE model).

Usage:
  .venv-fem/bin/python tools/fem_reference.py            # full run, writes reference/case2_fem.json
  .venv-fem/bin/python tools/fem_reference.py --quick    # coarse levels only, writes nothing unless --out
Any run with --quick/--levels/--line-levels/--modes writes JSON only to an explicit --out.
"""

import argparse
import functools
import json
import math
import os
import platform
import sys
import time

import numpy as np
import scipy
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.optimize import brentq, minimize_scalar

import skfem
from skfem import (Basis, BilinearForm, ElementHex2, ElementQuad2, ElementVector,
                   LinearForm, MeshHex, MeshQuad, asm)
from skfem.helpers import dot
from skfem.models.elasticity import lame_parameters, linear_elasticity

# ---------------------------------------------------------------- problem
L = 1.0
B = 0.225          # section width (y) = height (z)
RHO = 1000.0
E = 6.0e6
NU = 0.3
G_ACC = 9.81
T_END = 0.5        # s, window for the peak dynamic deflection
X_MID = 0.5
X_04 = 0.4
INTORDER = 5       # 3x3x3 Gauss: exact for the consistent mass of Hex2 on boxes

A = B * B
I_SEC = B ** 4 / 12.0
G_SHEAR = E / (2.0 * (1.0 + NU))
KAPPA = 10.0 * (1.0 + NU) / (12.0 + 11.0 * NU)

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEFAULT_OUT = os.path.join(REPO, "reference", "case2_fem.json")


def sig(x, n=7):
    """Round to n significant digits (keeps the JSON stable across BLAS noise)."""
    if x is None:
        return None
    if isinstance(x, (list, tuple)):
        return [sig(v, n) for v in x]
    x = float(x)
    if x == 0.0 or not math.isfinite(x):
        return x
    return float(f"{x:.{n - 1}e}")


# ---------------------------------------------------------------- assembly
# Generic part (also used by tools/fem_bending.py): linear elasticity with
# consistent mass and a body force -rho g along the last axis (z in 3D, y in
# 2D plane strain) on a tensor mesh of triquadratic Hex27 / biquadratic Quad9
# elements.  Every element is a box, so the element matrices are computed by
# scikit-fem on a one-element mesh, once per distinct box size, and scattered.
LAM, MU = lame_parameters(E, NU)


def tensor_mesh(coords):
    """MeshHex (3 coordinate arrays) or MeshQuad (2) of the tensor grid."""
    return (MeshHex if len(coords) == 3 else MeshQuad).init_tensor(*coords)


def vector_element(dim):
    return ElementVector(ElementHex2() if dim == 3 else ElementQuad2())


def forms(lam, mu, rho, g, dim):
    @BilinearForm
    def mass(u, v, w):
        return rho * dot(u, v)

    @LinearForm
    def gravity(v, w):
        return -rho * g * v[dim - 1]

    return linear_elasticity(lam, mu), mass, gravity


@functools.lru_cache(maxsize=None)
def _unit_box_matrices(dim, lam, mu, rho, g, volumetric="full"):
    """Matrices on the unit box, split by the derivative directions (p of the trial,
    q of the test function): sum_pq form_pq = lam div u div v + 2 mu eps(u):eps(v).
    On a box with edges h the stiffness is sum_pq V / (h_p h_q) K_pq, V = prod h.

    volumetric="p1disc": the lam term uses the element-wise L2 projection of
    div u onto P1 = {1, x, y(, z)} (the displacement form of the mixed Q2-P1disc
    element with the pressure condensed per element; inf-sup stable, free of
    volumetric locking as nu -> 1/2)."""
    b1 = Basis(tensor_mesh([np.array([0.0, 1.0])] * dim), vector_element(dim),
               intorder=INTORDER)
    ed1 = b1.element_dofs[:, 0]
    lam_full = lam if volumetric == "full" else 0.0

    def part(p, q):
        @BilinearForm
        def form(u, v, w):
            out = (lam_full * u.grad[p, p] * v.grad[q, q]
                   + mu * u.grad[q, p] * v.grad[p, q])
            if p == q:
                out = out + mu * sum(u.grad[a, p] * v.grad[a, p] for a in range(dim))
            return out
        return asm(form, b1).toarray()[np.ix_(ed1, ed1)]

    kpq = {(p, q): part(p, q) for p in range(dim) for q in range(dim)}
    if volumetric == "p1disc":
        xq = b1.global_coordinates().value[:, 0, :]          # dim x nqp
        wq = b1.dx[0]
        qq = np.vstack([np.ones_like(wq)] + [xq[a] - 0.5 for a in range(dim)])
        Gi = np.linalg.inv((qq * wq) @ qq.T)
        # Bp[k, j] = int q_k d(phi_j)_p / dx_p   (local DOF order j)
        Bp = [np.array([(qq * wq) @ b1.basis[j][0].grad[p, p, 0] for j in range(b1.Nbfun)]).T
              for p in range(dim)]
        for (p, q) in kpq:
            kpq[p, q] = kpq[p, q] + lam * Bp[q].T @ Gi @ Bp[p]
    elif volumetric != "full":
        raise ValueError(volumetric)
    _, mf, ff = forms(lam, mu, rho, g, dim)
    return kpq, asm(mf, b1).toarray()[np.ix_(ed1, ed1)], asm(ff, b1)[ed1]


def element_matrices(h, lam=LAM, mu=MU, rho=RHO, g=G_ACC, scaled=False, volumetric="full"):
    """Stiffness, mass and body-force vector of one box element with edges h.
    Direct: scikit-fem on a one-element mesh of that box.  scaled: from the
    unit-box parts (cheap for graded meshes with many distinct boxes; equal to
    the direct matrices to round-off, checked by assemble_tensor(check=True)).
    volumetric: see _unit_box_matrices (anything but "full" implies scaled)."""
    dim = len(h)
    if scaled or volumetric != "full":
        kpq, m1, f1 = _unit_box_matrices(dim, float(lam), float(mu), float(rho), float(g),
                                         volumetric)
        vol = float(np.prod(h))
        ke = sum(vol / (h[p] * h[q]) * k for (p, q), k in kpq.items())
        return ke, vol * m1, vol * f1
    b1 = Basis(tensor_mesh([np.array([0.0, hi]) for hi in h]), vector_element(dim),
               intorder=INTORDER)
    ed1 = b1.element_dofs[:, 0]
    kf, mf, ff = forms(lam, mu, rho, g, dim)
    ke = asm(kf, b1).toarray()[np.ix_(ed1, ed1)]
    me = asm(mf, b1).toarray()[np.ix_(ed1, ed1)]
    fe = asm(ff, b1)[ed1]
    return ke, me, fe


def assemble_tensor(coords, lam, mu, rho, g, check=False, scaled=False, volumetric="full",
                    box=None):
    """Mesh, basis, K, M, f on the tensor mesh of `coords` (2 or 3 node-coordinate
    arrays, possibly graded).  check: compare with scikit-fem's own global assembly
    (volumetric="full" only); scaled, volumetric: see element_matrices; box: the
    exact element edges of a uniform mesh (default: from the node coordinates)."""
    return assemble_boxes(tensor_mesh(coords), lam, mu, rho, g, check, scaled, volumetric, box)


def assemble_boxes(mesh, lam, mu, rho, g, check=False, scaled=False, volumetric="full",
                   box=None):
    """Mesh, basis, K, M, f on a MeshQuad / MeshHex whose elements are all axis-aligned
    boxes with the vertex order of tensor_mesh (a tensor mesh, or one with elements
    removed); element matrices by box size (see assemble_tensor)."""
    dim = mesh.p.shape[0]
    basis = Basis(mesh, vector_element(dim), intorder=INTORDER)
    pe = mesh.p[:, mesh.t]                                   # dim x verts x ne
    hs = pe.max(axis=1) - pe.min(axis=1)                    # box edges per element
    _, first, gid = np.unique(np.round(hs.T, 12), axis=0, return_index=True,
                              return_inverse=True)
    if box is not None:
        if len(first) != 1 or np.abs(hs[:, 0] - np.asarray(box)).max() > 1e-12:
            raise ValueError("box given for a mesh that is not uniform with those edges")
        mats = [element_matrices(tuple(box), lam, mu, rho, g, scaled, volumetric)]
    else:
        mats = [element_matrices(tuple(hs[:, e]), lam, mu, rho, g, scaled, volumetric)
                for e in first]
    gid = gid.ravel()
    ed = basis.element_dofs
    n, ne = ed.shape
    rows = np.broadcast_to(ed[:, None, :], (n, n, ne)).ravel()
    cols = np.broadcast_to(ed[None, :, :], (n, n, ne)).ravel()
    N = basis.N

    def values(j):
        if len(mats) == 1:
            return np.broadcast_to(mats[0][j][..., None], mats[0][j].shape + (ne,))
        return np.moveaxis(np.stack([m[j] for m in mats])[gid], 0, -1)

    K = sp.coo_matrix((values(0).ravel(), (rows, cols)), shape=(N, N)).tocsr()
    M = sp.coo_matrix((values(1).ravel(), (rows, cols)), shape=(N, N)).tocsr()
    f = np.bincount(ed.ravel(), weights=values(2).ravel(), minlength=N)
    if check and volumetric == "full":
        kf, mf, ff = forms(lam, mu, rho, g, dim)
        K2, M2, f2 = asm(kf, basis), asm(mf, basis), asm(ff, basis)
        ek = abs(K - K2).max() / abs(K2).max()
        em = abs(M - M2).max() / abs(M2).max()
        ef = np.abs(f - f2).max() / np.abs(f2).max()
        # round-off only; strongly graded meshes (tiny, stretched elements) reach ~1e-12
        if max(ek, em, ef) > 1e-11:
            raise RuntimeError(f"fast assembly mismatch: K {ek:.1e} M {em:.1e} f {ef:.1e}")
        # total weight must be exact
        vol = np.prod(hs, axis=0).sum()
        assert abs(f.sum() + rho * g * vol) < 1e-9 * rho * g * vol
    return mesh, basis, K, M, f


def mesh_sizes(ny):
    nx = int(round(L / (B / ny)))
    return nx, ny, ny


def build_coords(ny):
    nx, ny_, nz = mesh_sizes(ny)
    return [np.linspace(0.0, L, nx + 1), np.linspace(-B / 2, B / 2, ny_ + 1),
            np.linspace(-B / 2, B / 2, nz + 1)], (nx, ny_, nz)


def dof_components(basis):
    """The displacement component (0, 1, 2) of every DOF of a vector basis."""
    comp = np.empty(basis.N, dtype=int)
    for c, idx in enumerate(basis.split_indices()):
        comp[idx] = c
    return comp


def constrained_dofs(basis, support):
    xyz = basis.doflocs
    comp = dof_components(basis)
    tol = 1e-9
    clamp = np.abs(xyz[0]) < tol
    end = np.abs(xyz[0] - L) < tol
    if support == "face":
        pin = end & (comp >= 1)
    elif support == "line":
        pin = end & (np.abs(xyz[2]) < tol) & (comp >= 1)
        if not pin.any():
            raise RuntimeError("no DOFs on the line z = 0 at x = L")
    else:
        raise ValueError(support)
    return np.flatnonzero(clamp | pin), comp


# ---------------------------------------------------------------- analysis
def tidy_modes(w2, V, Mc, cf, xyz, fc, us):
    """M-orthonormalise the eigenvectors V (in place, w2 ascending), classify them.

    Inside a degenerate cluster (y/z bending of a square section) the basis is
    rotated so that the mode with the most u_z (last-component) content comes
    first and is pure.  Sign convention: phi^T f >= 0 (f the gravity load);
    if that is ~0, the largest |component| is positive.  cf: component (0..dim-1)
    of each free DOF, xyz: DOF locations.  Returns (modes, V, pf = V^T f)."""
    dim = int(cf.max()) + 1
    # component mass matrices (M couples only like components)
    Mcomp = []
    for c in range(dim):
        d = (cf == c).astype(float)
        Mcomp.append(sp.diags(d) @ Mc @ sp.diags(d))
    if dim == 3:
        r_rot = np.where(cf == 1, -xyz[2], 0.0) + np.where(cf == 2, xyz[1], 0.0)
        J_rot = r_rot @ (Mc @ r_rot)

    # M-orthonormalise and, inside degenerate clusters, rotate to pure u_z content
    i = 0
    while i < len(w2):
        j = i + 1
        while j < len(w2) and abs(w2[j] - w2[i]) <= 1e-6 * w2[i]:
            j += 1
        if j - i > 1:
            Vc = V[:, i:j]
            Q = Vc.T @ (Mc @ Vc)
            Lc = np.linalg.cholesky(Q)
            Vc = np.linalg.solve(Lc, Vc.T).T
            Qz = Vc.T @ (Mcomp[-1] @ Vc)
            ev, R = np.linalg.eigh(Qz)
            V[:, i:j] = Vc @ R[:, ::-1]       # most u_z first
            w2[i:j] = w2[i:j].mean()
        i = j
    nrm = np.sqrt(np.einsum("ij,ij->j", V, Mc @ V))
    V = V / nrm
    # sign convention: phi^T f >= 0; if ~0, largest |component| positive
    pf = V.T @ fc
    for k in range(V.shape[1]):
        s = pf[k]
        if abs(s) < 1e-9 * np.abs(pf).max():
            s = V[np.argmax(np.abs(V[:, k])), k]
        if s < 0:
            V[:, k] *= -1
            pf[k] *= -1

    modes = []
    counts = {}
    for k in range(V.shape[1]):
        fr = [float(V[:, k] @ (Mcomp[c] @ V[:, k])) for c in range(dim)]
        rot = float((V[:, k] @ (Mc @ r_rot)) ** 2 / J_rot) if dim == 3 else 0.0
        kind = classify(fr + [0.0] * (3 - dim), rot)
        counts[kind] = counts.get(kind, 0) + 1
        modes.append({
            "f_hz": math.sqrt(max(w2[k], 0.0)) / (2 * math.pi),
            "type": f"{kind} {counts[kind]}",
            "ke_fraction_xyz": fr,
            "torsion_participation": rot,
            "z_load_participation": float(pf[k] ** 2 / w2[k] / (us @ fc)),
        })
    return modes, V, pf


def classify(fr, rot):
    fx, fy, fz = fr
    if fz > 0.6:
        return "bending-z"
    if fy > 0.6:
        return "bending-y"
    if fx > 0.6:
        return "axial"
    if rot > 0.5 * max(fy, fz, 1e-300) or abs(fy - fz) < 0.15:
        return "torsion"
    return "mixed"


def solve_mesh(ny, support, nmodes, check=False, log=print):
    t0 = time.time()
    coords, shape = build_coords(ny)
    nx, nyy, nz = shape
    mesh, basis, K, M, f = assemble_tensor(coords, LAM, MU, RHO, G_ACC, check=check,
                                           box=(L / nx, B / nyy, B / nz))
    D, comp = constrained_dofs(basis, support)
    free = np.setdiff1d(np.arange(basis.N), D)
    Kc = K[free][:, free].tocsc()
    Mc = M[free][:, free].tocsr()
    fc = f[free]
    cf = comp[free]
    t_asm = time.time() - t0

    t0 = time.time()
    lu = spla.splu(Kc, permc_spec="COLAMD")
    t_lu = time.time() - t0

    # static
    t0 = time.time()
    us = lu.solve(fc)

    # lowest modes: shift-invert about 0 with the LU of K
    op = spla.LinearOperator(Kc.shape, matvec=lu.solve, dtype=float)
    w2, V = spla.eigsh(Kc, k=nmodes, M=Mc, sigma=0.0, OPinv=op, which="LM",
                       v0=np.ones(Kc.shape[0]), tol=1e-12)
    order = np.argsort(w2)
    w2, V = w2[order], V[:, order]
    t_eig = time.time() - t0

    modes, V, pf = tidy_modes(w2, V, Mc, cf, basis.doflocs[:, free], fc, us)
    iz = next((k for k, md in enumerate(modes) if md["type"].startswith("bending-z")), None)
    if iz is None:
        raise RuntimeError("no z-bending mode among the computed modes")
    f1 = modes[iz]["f_hz"]

    # axis sampling (y = z = 0)
    def full(v):
        out = np.zeros(basis.N)
        out[free] = v
        return out

    xs = np.linspace(0.0, L, 4001)
    pts = np.vstack([xs, np.zeros_like(xs), np.zeros_like(xs)])
    P = basis.probes(pts).tocsr()[2 * len(xs):3 * len(xs)]   # u_z rows
    uz_axis = P @ full(us)
    k = int(np.argmin(uz_axis))
    if 0 < k < len(xs) - 1:          # parabola through the 3 samples around the minimum
        y0, y1, y2 = uz_axis[k - 1:k + 2]
        dx = xs[1] - xs[0]
        den = y0 - 2 * y1 + y2
        delta = 0.5 * (y0 - y2) / den if den != 0 else 0.0
        x_max = xs[k] + delta * dx
        uz_max = y1 - 0.25 * (y0 - y2) * delta
    else:
        x_max, uz_max = xs[k], uz_axis[k]
    Pq = basis.probes(np.array([[x_max, X_MID, X_04], [0.0] * 3, [0.0] * 3])).tocsr()[6:9]
    uq_static = Pq @ full(us)
    uq_modes = Pq @ np.vstack([full(V[:, j]) for j in range(V.shape[1])]).T   # 3 x nmodes
    amp = pf / w2                                                          # a_k

    omega = np.sqrt(w2)

    def peak(p, nm, corrected=True):
        dt = min(2e-4, 2 * math.pi / omega[nm - 1] / 40)
        static = uq_static[p] if corrected else (uq_modes[p, :nm] * amp[:nm]).sum()
        return modal_peak(static, uq_modes[p, :nm], amp[:nm], omega[:nm], T_END, dt)

    nm = V.shape[1]
    pk, tpk = peak(0, nm)
    pk_mid, tpk_mid = peak(1, nm)
    pk_half, _ = peak(0, max(1, nm // 2))
    pk_modal, _ = peak(0, nm, corrected=False)
    static_modal = float((uq_modes[0] * amp).sum())
    t_post = time.time() - t0 - t_eig

    nx, nyy, nz = shape
    res = {
        "support": support,
        "nx_ny_nz": [nx, nyy, nz],
        "elements": int(mesh.t.shape[1]),
        "dofs": int(basis.N),
        "free_dofs": int(len(free)),
        "h": B / ny,
        "hx": L / nx,
        "f1_hz": f1,
        "f1_mode_index": iz + 1,
        "static_max_uz_m": float(uz_max),
        "static_max_x_m": float(x_max),
        "static_uz_mid_m": float(uq_static[1]),
        "static_uz_x04_m": float(uq_static[2]),
        "peak_dynamic_uz_m": pk,
        "peak_dynamic_t_s": tpk,
        "peak_dynamic_uz_mid_m": pk_mid,
        "peak_dynamic_mid_t_s": tpk_mid,
        "dynamic_amplification": pk / uz_max,
        "modal": {
            "modes_used": nm,
            "highest_mode_hz": float(omega[-1] / (2 * math.pi)),
            "peak_dynamic_uz_half_modes_m": pk_half,
            "peak_dynamic_uz_truncated_sum_m": pk_modal,
            "static_uz_truncated_sum_m": static_modal,
        },
        "frequencies_hz": [md["f_hz"] for md in modes[:10]],
        "modes": modes[:10],
        "timing_s": {"assembly": t_asm, "lu": t_lu, "eigs": t_eig, "post": t_post},
    }
    log(f"  [{support}] ny={ny}: {basis.N} dofs, asm {t_asm:.1f}s, LU {t_lu:.1f}s, "
        f"eig {t_eig:.1f}s; f1 = {f1:.5f} Hz")
    return res


def modal_response(static, modes, amp, omega, t):
    """u(t) at one probe for a load applied suddenly at t = 0 from rest, undamped:
    u(t) = static - sum_k modes_k amp_k cos(omega_k t), with modes_k the probe value of the
    M-normalised mode k and amp_k = phi_k^T f / omega_k^2.  With static = the full static
    solution this is the retained modes plus the static remainder of the others (the
    mode-acceleration form); with static = sum_k modes_k amp_k it is the truncated sum."""
    c = np.cos(np.outer(np.atleast_1d(t), omega))
    dyn = (c * (modes * amp)).sum(axis=1)
    return static - dyn


def modal_peak(static, modes, amp, omega, t_end, dt, direction=-1):
    """Extremum of modal_response over t in [0, t_end] (the minimum for direction < 0, the
    maximum otherwise): sampled every dt, then refined by a bounded scalar minimisation
    around the best sample.  Returns (peak, t_peak)."""
    sgn = 1.0 if direction < 0 else -1.0

    def resp(t):
        u = modal_response(static, modes, amp, omega, t)
        return u if direction < 0 else -u

    ts = np.arange(0.0, t_end + 0.5 * dt, dt)
    u = resp(ts)
    j = int(np.argmin(u))
    lo, hi = max(0.0, ts[j] - dt), min(t_end, ts[j] + dt)
    res = minimize_scalar(lambda t: resp(t)[0], bounds=(lo, hi), method="bounded",
                          options={"xatol": 1e-10})
    if res.fun < u[j]:
        return float(sgn * res.fun), float(res.x)
    return float(sgn * u[j]), float(ts[j])


def richardson(hs, vs):
    """f = f_inf + C h^p through the last three points; returns (f_inf, p) or (None, None)."""
    if len(hs) < 3:
        return None, None
    (h1, h2, h3), (v1, v2, v3) = hs[-3:], vs[-3:]
    d12, d23 = v1 - v2, v2 - v3
    if d23 == 0 or d12 / d23 <= 0:
        return None, None
    r = d12 / d23

    def g(p):
        return (h1 ** p - h2 ** p) / (h2 ** p - h3 ** p) - r

    try:
        p = brentq(g, 0.2, 12.0)
    except ValueError:
        return None, None
    C = d23 / (h2 ** p - h3 ** p)
    return v3 - C * h3 ** p, p


# ---------------------------------------------------------------- beam theory
def euler_bernoulli():
    lam1 = 3.9266
    f1 = lam1 ** 2 / (2 * math.pi * L ** 2) * math.sqrt(E * I_SEC / (RHO * A))
    q = RHO * G_ACC * A
    w185 = q * L ** 4 / (185.0 * E * I_SEC)
    # exact EB clamped-pinned: w = q x^2 (3L^2 - 5Lx + 2x^2) / (48 EI)
    xi = (15.0 - math.sqrt(33.0)) / 16.0
    w_exact = q * L ** 4 * xi ** 2 * (3 - 5 * xi + 2 * xi ** 2) / (48 * E * I_SEC)
    w_mid = q * L ** 4 / (192.0 * E * I_SEC)
    return {
        "euler_bernoulli_f1_hz": f1,
        "euler_bernoulli_period_s": 1.0 / f1,
        "euler_bernoulli_static_max_m": -w185,
        "euler_bernoulli_static_max_exact_m": -w_exact,
        "euler_bernoulli_static_max_x_m": xi * L,
        "euler_bernoulli_static_mid_m": -w_mid,
    }


def timoshenko_det(omega):
    kGA = KAPPA * G_SHEAR * A
    EI = E * I_SEC
    a2 = kGA * EI
    a1 = kGA * RHO * I_SEC * omega ** 2 + RHO * A * omega ** 2 * EI
    a0 = RHO * A * omega ** 2 * (RHO * I_SEC * omega ** 2 - kGA)
    disc = math.sqrt(a1 * a1 - 4 * a2 * a0)
    S1 = (-a1 + disc) / (2 * a2)
    S2 = (-a1 - disc) / (2 * a2)
    if S1 <= 0:
        raise ValueError("above the second-spectrum cut-off")
    al, be = math.sqrt(S1), math.sqrt(-S2)
    c = RHO * omega ** 2 / (KAPPA * G_SHEAR)
    ch, sh = math.cosh(al * L), math.sinh(al * L)
    cs, sn = math.cos(be * L), math.sin(be * L)
    # w = A1 cosh + A2 sinh + A3 cos + A4 sin;  psi' = w'' + c w
    Mx = np.array([
        [1.0, 0.0, 1.0, 0.0],                                          # w(0)
        [0.0, (al ** 2 + c) / al, 0.0, -(c - be ** 2) / be],           # psi(0)
        [ch / ch, sh / ch, cs, sn],                                    # w(L)   (hyperbolic cols scaled)
        [(al ** 2 + c) * ch / ch, (al ** 2 + c) * sh / ch,
         (c - be ** 2) * cs, (c - be ** 2) * sn],                      # psi'(L): M = 0
    ])
    return np.linalg.det(Mx)


def timoshenko_f1():
    f_eb = euler_bernoulli()["euler_bernoulli_f1_hz"]
    fs = np.linspace(0.05 * f_eb, 1.2 * f_eb, 2000)
    d = [timoshenko_det(2 * math.pi * f) for f in fs]
    for k in range(len(fs) - 1):
        if d[k] == 0.0 or d[k] * d[k + 1] < 0:
            fr = brentq(lambda f: timoshenko_det(2 * math.pi * f), fs[k], fs[k + 1],
                        xtol=1e-13)
            return fr
    raise RuntimeError("no Timoshenko root found")


def timoshenko_fe(n=4000):
    """1D Timoshenko beam FE (linear, reduced-integration shear, consistent mass)
    as a cross-check of the frequency equation; also gives the static deflection."""
    le = L / n
    kGA = KAPPA * G_SHEAR * A
    EI = E * I_SEC
    nd = 2 * (n + 1)                   # dofs: w0, psi0, w1, psi1, ...
    kb = EI / le * np.array([[0, 0, 0, 0], [0, 1, 0, -1], [0, 0, 0, 0], [0, -1, 0, 1]], float)
    bs = np.array([-1 / le, -0.5, 1 / le, -0.5])            # w' - psi at midpoint
    ks = kGA * le * np.outer(bs, bs)
    ke = kb + ks
    mw = RHO * A * le / 6 * np.array([[2, 1], [1, 2]])
    mp = RHO * I_SEC * le / 6 * np.array([[2, 1], [1, 2]])
    me = np.zeros((4, 4))
    me[np.ix_([0, 2], [0, 2])] = mw
    me[np.ix_([1, 3], [1, 3])] = mp
    fe = np.array([-RHO * G_ACC * A * le / 2, 0, -RHO * G_ACC * A * le / 2, 0])
    e = np.arange(n)
    dofs = np.stack([2 * e, 2 * e + 1, 2 * e + 2, 2 * e + 3], 1)
    r = np.repeat(dofs, 4, 1).ravel()
    c = np.tile(dofs, (1, 4)).ravel()
    K = sp.coo_matrix((np.tile(ke.ravel(), n), (r, c)), shape=(nd, nd)).tocsc()
    M = sp.coo_matrix((np.tile(me.ravel(), n), (r, c)), shape=(nd, nd)).tocsc()
    f = np.zeros(nd)
    np.add.at(f, dofs.ravel(), np.tile(fe, n))
    fixed = [0, 1, 2 * n]
    free = np.setdiff1d(np.arange(nd), fixed)
    Kc, Mc = K[free][:, free].tocsc(), M[free][:, free].tocsc()
    w2 = spla.eigsh(Kc, k=1, M=Mc, sigma=0.0, which="LM", v0=np.ones(len(free)),
                    return_eigenvectors=False)
    u = np.zeros(nd)
    u[free] = spla.spsolve(Kc, f[free])
    w = u[0::2]
    xs = np.linspace(0, L, n + 1)
    k = int(np.argmin(w))
    return {
        "f1_hz": float(math.sqrt(w2[0]) / (2 * math.pi)),
        "static_max_m": float(w[k]),
        "static_max_x_m": float(xs[k]),
        "static_mid_m": float(np.interp(X_MID, xs, w)),
    }


# ---------------------------------------------------------------- report
ROW_KEYS = ["f1_hz", "static_max_uz_m", "static_max_x_m", "static_uz_mid_m",
            "static_uz_x04_m", "peak_dynamic_uz_m", "peak_dynamic_uz_mid_m"]


def table(rows, title, log):
    log(f"\n{title}")
    hdr = (f"{'nx x ny x nz':>13} {'elems':>6} {'dofs':>7} {'h [m]':>8} {'f1 [Hz]':>9} "
           f"{'df1 %':>7} {'uz_max [mm]':>11} {'x_max':>6} {'uz(0.5)':>8} {'uz(0.4)':>8} "
           f"{'peak [mm]':>9} {'peak(0.5)':>9}")
    log(hdr)
    log("-" * len(hdr))
    for i, r in enumerate(rows):
        df = "" if i == 0 else f"{100 * (r['f1_hz'] / rows[i - 1]['f1_hz'] - 1):+.3f}"
        nxyz = "x".join(str(v) for v in r["nx_ny_nz"])
        log(f"{nxyz:>13} {r['elements']:>6} {r['dofs']:>7} {r['h']:>8.5f} {r['f1_hz']:>9.5f} "
            f"{df:>7} {1e3 * r['static_max_uz_m']:>11.5f} {r['static_max_x_m']:>6.4f} "
            f"{1e3 * r['static_uz_mid_m']:>8.5f} {1e3 * r['static_uz_x04_m']:>8.5f} "
            f"{1e3 * r['peak_dynamic_uz_m']:>9.5f} {1e3 * r['peak_dynamic_uz_mid_m']:>9.5f}")


def rounded(obj):
    if isinstance(obj, dict):
        return {k: rounded(v) for k, v in obj.items() if k != "timing_s"}
    if isinstance(obj, list):
        return [rounded(v) for v in obj]
    if isinstance(obj, float):
        # every physical value here is far above 1e-12; below that it is round-off
        # (e.g. the z participation of a y mode), written as 0 to keep the file stable
        return 0.0 if abs(obj) < 1e-12 else sig(obj)
    return obj


def write_json(out, data, log=print):
    """Writes an already rounded reference to `out` (creating its directory), one space indent."""
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    with open(out, "w") as fh:
        json.dump(data, fh, indent=1)
        fh.write("\n")
    log(f"wrote {out}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true",
                    help="coarse levels only (ny = 2,3,4; line support 2,4)")
    ap.add_argument("--levels", type=int, nargs="+",
                    help="elements across the section for the face-support sequence "
                         "(default 2 4 6 8 10)")
    ap.add_argument("--line-levels", type=int, nargs="+",
                    help="levels for the line-support variant (even numbers; default 2 4 6 8)")
    ap.add_argument("--modes", type=int, default=30, help="modes for the modal superposition")
    ap.add_argument("--out", help=f"JSON output; without it only the default full run writes "
                                  f"{os.path.relpath(DEFAULT_OUT, REPO)}")
    args = ap.parse_args(argv)

    levels = args.levels or ([2, 3, 4] if args.quick else [2, 4, 6, 8, 10])
    line_levels = args.line_levels or ([2, 4] if args.quick else [2, 4, 6, 8])
    if any(n % 2 for n in line_levels):
        ap.error("--line-levels must be even (a node line is needed at z = 0)")
    # only the default full run may overwrite the committed reference file
    default_run = not (args.quick or args.levels or args.line_levels or args.modes != 30)
    out = args.out or (DEFAULT_OUT if default_run else None)

    def log(*a):
        print(*a, flush=True)

    t_start = time.time()
    log("Case 2: clamped-pinned beam, 3D linear elasticity, Hex27 (ElementHex2) elements")
    log(f"L={L} m, b=h={B} m, rho={RHO}, E={E}, nu={NU}, g={G_ACC} along -z")

    bt = euler_bernoulli()
    f_tim = timoshenko_f1()
    tfe = timoshenko_fe()
    bt.update({
        "timoshenko_f1_hz": f_tim,
        "timoshenko_period_s": 1.0 / f_tim,
        "timoshenko_shear_coefficient": KAPPA,
        "timoshenko_fe_check_f1_hz": tfe["f1_hz"],
        "timoshenko_static_max_m": tfe["static_max_m"],
        "timoshenko_static_max_x_m": tfe["static_max_x_m"],
        "timoshenko_static_mid_m": tfe["static_mid_m"],
    })
    log(f"Euler-Bernoulli f1 = {bt['euler_bernoulli_f1_hz']:.4f} Hz, static max "
        f"qL^4/(185EI) = {1e3 * bt['euler_bernoulli_static_max_m']:.4f} mm")
    log(f"Timoshenko (kappa={KAPPA:.4f}) f1 = {f_tim:.4f} Hz "
        f"(1D FE check {tfe['f1_hz']:.4f} Hz), static max {1e3 * tfe['static_max_m']:.4f} mm "
        f"at x = {tfe['static_max_x_m']:.3f}")
    if abs(tfe["f1_hz"] / f_tim - 1) > 1e-4:
        raise RuntimeError("Timoshenko frequency equation and 1D FE disagree")

    log("\nface support at x = L (u_y = u_z = 0 on the whole face):")
    rows = [solve_mesh(n, "face", args.modes, check=(i == 0), log=log)
            for i, n in enumerate(levels)]
    log("\nline support at x = L (u_y = u_z = 0 on z = 0 only):")
    lrows = [solve_mesh(n, "line", min(args.modes, 20), log=log) for n in line_levels]

    table(rows, "Face support (reference): convergence", log)
    fin = rows[-1]
    log("\nFinest mesh, lowest modes:")
    for k, md in enumerate(fin["modes"]):
        fr = md["ke_fraction_xyz"]
        log(f"  {k + 1:2d}  {md['f_hz']:9.4f} Hz  {md['type']:<12} KE x/y/z = "
            f"{fr[0]:.3f}/{fr[1]:.3f}/{fr[2]:.3f}  z-load share {md['z_load_participation']:.4f}")
    table(lrows, "Line support at x = L (not expected to converge)", log)

    hs = [r["h"] for r in rows]
    conv = {k: fin[k] for k in ["nx_ny_nz", "elements", "dofs", "h"] + ROW_KEYS +
            ["peak_dynamic_t_s", "peak_dynamic_mid_t_s", "dynamic_amplification"]}
    conv["period_s"] = 1.0 / fin["f1_hz"]
    fr_, p_ = richardson(hs, [r["f1_hz"] for r in rows])
    if fr_ is not None:
        conv["f1_richardson_hz"] = fr_
        conv["f1_richardson_order"] = p_
        conv["f1_finest_rel_error_est"] = fin["f1_hz"] / fr_ - 1
    sr_, sp_ = richardson(hs, [r["static_max_uz_m"] for r in rows])
    if sr_ is not None:
        conv["static_max_uz_richardson_m"] = sr_
        conv["static_max_uz_richardson_order"] = sp_
    if len(rows) > 1:
        conv["f1_change_last_refinement"] = fin["f1_hz"] / rows[-2]["f1_hz"] - 1
    conv["modes"] = fin["modes"]

    log("\nConverged reference (finest mesh):")
    log(f"  f1 = {fin['f1_hz']:.5f} Hz (T = {1 / fin['f1_hz']:.5f} s)"
        + (f", Richardson {fr_:.5f} Hz (order {p_:.2f}), finest error est "
           f"{100 * conv['f1_finest_rel_error_est']:+.4f} %" if fr_ is not None else ""))
    log(f"  static max u_z = {1e3 * fin['static_max_uz_m']:.5f} mm at x = "
        f"{fin['static_max_x_m']:.4f} m; u_z(0.5) = {1e3 * fin['static_uz_mid_m']:.5f} mm; "
        f"u_z(0.4) = {1e3 * fin['static_uz_x04_m']:.5f} mm")
    log(f"  peak dynamic u_z = {1e3 * fin['peak_dynamic_uz_m']:.5f} mm at t = "
        f"{fin['peak_dynamic_t_s']:.4f} s (x = {fin['static_max_x_m']:.4f}); at x = 0.5: "
        f"{1e3 * fin['peak_dynamic_uz_mid_m']:.5f} mm; amplification "
        f"{fin['dynamic_amplification']:.4f}")
    md = fin["modal"]
    log(f"  modal check: {md['modes_used']} modes up to {md['highest_mode_hz']:.1f} Hz; "
        f"peak with half the modes {1e3 * md['peak_dynamic_uz_half_modes_m']:.5f} mm; "
        f"pure truncated sum {1e3 * md['peak_dynamic_uz_truncated_sum_m']:.5f} mm "
        f"(its static {1e3 * md['static_uz_truncated_sum_m']:.5f} mm)")
    log(f"\ntotal run time {time.time() - t_start:.1f} s")

    if out:
        lfin = lrows[-1]
        data = {
            "case": "paper Case 2: clamped-pinned beam under gravity (3D linear elasticity FEM reference)",
            "problem": {
                "length_m": L, "width_m": B, "height_m": B,
                "section": "y, z in [-0.1125, 0.1125] (centred on the x axis)",
                "rho_kg_m3": RHO, "E_pa": E, "nu": NU, "g_m_s2": G_ACC,
                "gravity_direction": "-z",
                "bc_x0": "clamped: u = 0 on the whole face x = 0",
                "bc_xL": "face support: u_y = u_z = 0 on the whole face x = L, u_x free",
                "axis": "y = z = 0",
                "dynamic": f"gravity applied suddenly at t = 0 from rest, undamped, peak over t in [0, {T_END}] s",
                "sign": "deflections negative = downward (-z)",
            },
            "method": {
                "code": "tools/fem_reference.py",
                "elements": "structured hexahedral mesh, 27-node triquadratic (scikit-fem ElementVector(ElementHex2))",
                "quadrature": "3x3x3 Gauss (intorder 5)",
                "mass": "consistent",
                "eigensolver": "scipy eigsh, shift-invert about 0 (lowest modes), SuperLU",
                "f1_mode": "lowest mode whose kinetic energy is > 60 % in u_z (z bending); its y-bending twin is degenerate for the face support",
                "dynamic": "modal superposition, retained modes + static remainder of the others (mode-acceleration form); pure truncated sum reported under 'modal'",
                "richardson": "f = f_inf + C h^p through the three finest meshes, h = b / ny",
                "versions": {"python": platform.python_version(), "numpy": np.__version__,
                             "scipy": scipy.__version__, "scikit-fem": skfem.__version__},
            },
            "meshes": [{k: v for k, v in r.items() if k not in ("modes", "timing_s")} for r in rows],
            "converged": conv,
            "pinned_line": {
                "bc_xL": "u_y = u_z = 0 only on the line z = 0 (all y) of the face x = L, everything else free",
                "note": "a line support is singular in a 3D continuum: the support softens as the mesh is refined and f1 and the deflections do not converge; these numbers depend on the mesh and only show the trend",
                "meshes": [{k: v for k, v in r.items() if k not in ("modes", "timing_s")} for r in lrows],
                "finest_modes": lfin["modes"],
            },
            "beam_theory": bt,
        }
        write_json(out, rounded(data), log)
    return 0


if __name__ == "__main__":
    sys.exit(main())
