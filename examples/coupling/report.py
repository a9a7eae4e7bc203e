"""Figures and plots of the coupling report (examples/coupling/README.md): convergence in the
communication step, the largest stable communication step against the coupling stiffness, energy
of the undamped coupled run, and the cost of coupling (benchmark). Needs matplotlib in the venv
(`.venv/bin/pip install matplotlib`; the tests do not use it).

    examples/coupling/build.sh
    .venv/bin/python examples/coupling/report.py [convergence] [stability] [energy] [bench]

Writes target/coupling/report/*.json and examples/coupling/figures/*.png.
"""
import json
import math
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import analysis  # noqa: E402
import cosim  # noqa: E402
from reference import Beam  # noqa: E402

ROOT = os.path.abspath(os.path.join(HERE, "..", ".."))
FMUS = os.path.join(ROOT, "target", "coupling")
BEAM = os.path.join(FMUS, "cantilever_payload.fmu")
PAYLOAD = os.path.join(FMUS, "Payload.fmu")
OUT = os.path.join(FMUS, "report")
FIG = os.path.join(HERE, "figures")
M, K, X0 = 10.0, 4.0e4, -0.01
STEPS = [2e-3, 1e-3, 5e-4, 2.5e-4]
ALGS = [("jacobi", 1), ("gauss-seidel", 1), ("gauss-seidel", 2)]


def save(name, data):
    os.makedirs(OUT, exist_ok=True)
    with open(os.path.join(OUT, name + ".json"), "w") as f:
        json.dump(data, f, indent=1)


def load(name):
    with open(os.path.join(OUT, name + ".json")) as f:
        return json.load(f)


def convergence():
    data = {}
    for alg, order in ALGS:
        res = [cosim.run(BEAM, PAYLOAD, H, 0.1, alg, payload=dict(m=M, k=K, x0=X0), order=order,
                         record_every=int(round(2e-3 / H))) for H in STEPS]
        d, p = analysis.orders(STEPS, [np.concatenate([r["x"], r["tip.uy"]]) for r in res])
        data[f"{alg} {order}"] = {"differences": d, "orders": p,
                                  "t": res[-1].t.tolist(), "x": [r["x"].tolist() for r in res]}
        print(alg, order, d, p)
    save("convergence", data)


def stable(alg, order, k, H, T=0.3):
    """True if the coupled run (payload m = 10, spring k, initial spring force 400 N/m) stays
    bounded over T: no solver error, energy below twice its start."""
    try:
        r = cosim.run(BEAM, PAYLOAD, H, T, alg, payload=dict(m=M, k=k, x0=-400.0 / k), order=order,
                      record_every=max(1, int(round(2e-3 / H))))
    except Exception as e:  # the beam FMU's blow-up/overlap error, or the payload's
        return False, str(e)[:80]
    e = cosim.total_energy(r)
    ok = bool(np.all(np.isfinite(e)) and np.abs(e).max() < 2 * abs(e[0]))
    return ok, f"max energy ratio {np.abs(e).max() / abs(e[0]):.3g}"


def stability():
    ks = [4e4, 4e5, 4e6, 4e7]
    data = []
    for alg, order in [("gauss-seidel", 1), ("gauss-seidel", 2), ("jacobi", 1)]:
        for k in ks:
            H, last_ok, note = 1.25e-4, None, ""
            while H <= 0.0641:
                ok, note = stable(alg, order, k, H)
                print(alg, order, k, H, ok, note, flush=True)
                if not ok:
                    break
                last_ok, H = H, 2 * H
            while last_ok is None and H > 1.6e-5:  # unstable at 0.125 ms: halve down to one solver step
                H2 = H / 2
                ok, note2 = stable(alg, order, k, H2)
                print(alg, order, k, H2, ok, note2, flush=True)
                if ok:
                    last_ok = H2
                else:
                    H, note = H2, note2
            if last_ok is not None and H <= 0.0641:  # one bisection between last stable and first unstable
                mid = math.sqrt(last_ok * H)
                ok, _ = stable(alg, order, k, mid)
                if ok:
                    last_ok = mid
            data.append({"algorithm": alg, "order": order, "k": k, "largest_stable": last_ok,
                         "first_unstable": H if H <= 0.0641 else None, "note": note})
            save("stability", data)


def stability_low():
    """Completes stability.json: where 0.125 ms was already unstable, halves the step down to the
    beam's solver step (1/64 ms)."""
    data = load("stability")
    for row in data:
        H = row["first_unstable"]
        while row["largest_stable"] is None and H and H > 1.6e-5:
            ok, note = stable(row["algorithm"], row["order"], row["k"], H / 2)
            print(row["algorithm"], row["order"], row["k"], H / 2, ok, note, flush=True)
            if ok:
                row["largest_stable"] = H / 2
            else:
                H = H / 2
                row["first_unstable"], row["note"] = H, note
        save("stability", data)


def beam_alone():
    """The beam FMU's own first frequency (free vibration after a sudden tip force, undamped) and
    static tip stiffness (damped, resolution.py), and the 2-DOF model built from them."""
    from reference import two_dof_frequencies
    from resolution import static_deflection

    beam = Beam.from_scene(os.path.join(ROOT, "scenes", "cantilever_payload.json"))
    r = cosim.run_beam_alone(BEAM, 2e-3, 0.8, force=-1000.0)
    f1 = analysis.lowest_frequency(r.t, r["tip.uy"])
    u, _, _ = static_deflection(BEAM, -1000.0)
    k_tip = 1000.0 / abs(u)
    data = {"f1_fmu": f1, "f1_fe": beam.frequencies()[0], "k_tip_fmu": k_tip,
            "k_tip_timoshenko": 1.0 / beam.tip_deflection(1.0),
            "two_dof_from_fmu": two_dof_frequencies(k_tip, f1, M, K).tolist()}
    print(data)
    save("beam_alone", data)


def energy():
    beam = Beam.from_scene(os.path.join(ROOT, "scenes", "cantilever_payload.json"))
    f1 = beam.frequencies(M, K)[0]
    data = {}
    for alg, order in ALGS:
        r = cosim.run(BEAM, PAYLOAD, 1e-3, 2e-3 * round(10.5 / f1 / 2e-3), alg, payload=dict(m=M, k=K, x0=X0), order=order,
                      record_every=2)
        e = cosim.total_energy(r)
        data[f"{alg} {order}"] = {"t": r.t.tolist(), "energy": e.tolist(), "drift": analysis.energy_drift(e),
                                  "x": r["x"].tolist(), "u": r["tip.uy"].tolist(),
                                  "lowest_frequency": analysis.lowest_frequency(r.t, r["x"]),
                                  "wall": r.wall}
        print(alg, order, "drift", data[f"{alg} {order}"]["drift"], "f", data[f"{alg} {order}"]["lowest_frequency"])
    data["reference_fe"] = beam.frequencies(M, K).tolist()
    save("energy", data)


def bench(T=0.5, H=1e-3, repeats=3):
    """Wall time of the coupled run at 1 ms against the beam FMU alone stepped at 1 ms (fmpy), the
    minimum over `repeats` interleaved repetitions (the machine is shared), and the cost of the
    master + payload alone (the same loop with the beam's doStep replaced by nothing)."""
    sys.path.insert(0, HERE)
    import run_libcosim

    pay = dict(m=M, k=K, x0=X0)
    runs = {
        "beam FMU alone (fmpy loop)": lambda: cosim.run_beam_alone(BEAM, H, T, force=-400.0).wall,
        "beam + payload, fmpy Jacobi (hold)": lambda: cosim.run(BEAM, PAYLOAD, H, T, "jacobi", payload=pay).wall,
        "beam + payload, fmpy Gauss-Seidel (linear)": lambda: cosim.run(
            BEAM, PAYLOAD, H, T, "gauss-seidel", payload=pay, order=2).wall,
        "beam + payload, libcosim fixed step (Jacobi)": lambda: run_libcosim.run(FMUS, H, T, payload=pay).wall,
    }
    rows = {k: [] for k in runs}
    for _ in range(repeats):
        for k, f in runs.items():
            rows[k].append(f())
    # the coupling's own cost: payload FMU + master calls without the beam's work
    p = cosim.Fmu(PAYLOAD, "payload")
    p.init(**pay)
    t0 = time.perf_counter()
    for i in range(int(round(T / H))):
        p.set(u=0.0, v=0.0)
        p.s.doStep(i * H, H)
        p.get("force", "force_rate")
    payload_only = time.perf_counter() - t0
    p.free()
    best = {k: min(v) for k, v in rows.items()}
    base = best["beam FMU alone (fmpy loop)"]
    save("bench", {"T": T, "H": H, "rows": rows, "best": best, "payload_and_master_only": payload_only,
                   "cpu": os.cpu_count(), "load": os.getloadavg(),
                   "measured_at": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())})
    for k, v in best.items():
        print(f"{k}: {v:.2f} s ({v / base - 1:+.1%})")
    print(f"payload FMU + master calls alone: {payload_only:.3f} s ({payload_only / base:.1%} of the beam)")


def coupling_mode(k):
    """Frequency (rad/s) of the FE mode of beam + payload that holds most of the energy of the
    stability runs' start (spring stretched by 400 N / k, everything at rest)."""
    beam = Beam.from_scene(os.path.join(ROOT, "scenes", "cantilever_payload.json"))
    Kf, Mf, _ = beam.fe(elements=240, payload_mass=M, spring=k)
    Li = np.linalg.inv(np.linalg.cholesky(Mf))
    w2, V = np.linalg.eigh(Li @ Kf @ Li.T)
    phi = Li.T @ V
    q0 = np.zeros(Kf.shape[0])
    q0[-1] = -400.0 / k
    e = 0.5 * w2 * (phi.T @ Mf @ q0) ** 2
    return float(math.sqrt(w2[np.argmax(e)]))


def stability_table():
    """Markdown table of the stability scan with the coupling mode's frequency."""
    s = load("stability")
    ks = sorted({r["k"] for r in s})
    algs = [("gauss-seidel", 1), ("jacobi", 1), ("gauss-seidel", 2)]
    print("| k (N/m per m) | coupling mode (Hz) | " + " | ".join(
        f"{a} {'hold' if o == 1 else 'linear'}: H_max (ms), omega H" for a, o in algs) + " |")
    print("|---" * (2 + len(algs)) + "|")
    for k in ks:
        w = coupling_mode(k)
        cells = []
        for a, o in algs:
            r = next(r for r in s if r["k"] == k and r["algorithm"] == a and r["order"] == o)
            h = r["largest_stable"]
            cells.append(f"{h * 1e3:.3g}, {w * h:.2f}" if h else "< 0.0156 (one solver step)")
        print(f"| {k:.0e} | {w / (2 * math.pi):.1f} | " + " | ".join(cells) + " |")


def plots():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(FIG, exist_ok=True)
    if os.path.exists(os.path.join(OUT, "convergence.json")):
        c = load("convergence")
        fig, ax = plt.subplots(figsize=(5.5, 4))
        hs = np.array(STEPS[1:])
        for key, v in c.items():
            ax.loglog(hs * 1e3, np.array(v["differences"]) * 1e3, "o-",
                      label=f"{key.replace(' 1', ', hold').replace(' 2', ', linear')} (orders "
                            + ", ".join(f"{p:.2f}" for p in v["orders"]) + ")")
        ax.loglog(hs * 1e3, 0.3 * (hs / hs[0]) * np.array(c["jacobi 1"]["differences"])[0] * 1e3 / 0.3, "k:",
                  label="order 1")
        ax.loglog(hs * 1e3, (hs / hs[0]) ** 2 * np.array(c["gauss-seidel 2"]["differences"])[0] * 1e3, "k--",
                  label="order 2")
        ax.set_xlabel("communication step H (ms)")
        ax.set_ylabel("max |y(H) - y(2H)| over 0.1 s (mm)")
        ax.set_title("Convergence in the communication step")
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(os.path.join(FIG, "convergence.png"), dpi=110)
    if os.path.exists(os.path.join(OUT, "stability.json")):
        s = load("stability")
        fig, ax = plt.subplots(figsize=(5.5, 4))
        for alg, order, mk in [("gauss-seidel", 1, "o"), ("gauss-seidel", 2, "s"), ("jacobi", 1, "^")]:
            rows = [r for r in s if r["algorithm"] == alg and r["order"] == order and r["largest_stable"]]
            if rows:
                ax.loglog([r["k"] for r in rows], [r["largest_stable"] * 1e3 for r in rows], mk + "-",
                          label=f"{alg}, {'hold' if order == 1 else 'linear'}")
        ks = sorted({r["k"] for r in s})
        ax.loglog(ks, [0.1 / coupling_mode(k) * 1e3 for k in ks], "k--", label="rule 0.1 / omega_c")
        ax.set_xlabel("coupling stiffness k (N/m per m)")
        ax.set_ylabel("largest stable communication step (ms)")
        ax.set_title("Stability of the explicit coupling")
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(os.path.join(FIG, "stability.png"), dpi=110)
    if os.path.exists(os.path.join(OUT, "energy.json")):
        e = load("energy")
        fig, ax = plt.subplots(figsize=(5.5, 4))
        for key in [f"{a} {o}" for a, o in ALGS]:
            v = e[key]
            en = np.array(v["energy"])
            ax.plot(v["t"], (en / en[0] - 1) * 100, label=f"{key.replace(' 1', ', hold').replace(' 2', ', linear')}")
        ax.set_ylim(-5, 30)
        ax.set_xlabel("t (s)")
        ax.set_ylabel("energy change (%)")
        ax.set_title("Undamped beam + payload, H = 1 ms")
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(os.path.join(FIG, "energy.png"), dpi=110)
        fig, ax = plt.subplots(figsize=(6.5, 3.2))
        v = e["gauss-seidel 2"]
        ax.plot(v["t"], np.array(v["x"]) * 1e3, label="payload x")
        ax.plot(v["t"], np.array(v["u"]) * 1e3, label="tip u")
        ax.set_xlabel("t (s)")
        ax.set_ylabel("mm")
        ax.set_title("Free vibration, Gauss-Seidel linear, H = 1 ms")
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(os.path.join(FIG, "free_vibration.png"), dpi=110)


if __name__ == "__main__":
    what = sys.argv[1:] or ["convergence", "energy", "stability", "stability_low", "beam_alone", "bench"]
    for w in what:
        if w == "table":
            stability_table()
        elif w != "plots":
            globals()[w]()
    plots()
