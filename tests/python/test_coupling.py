"""Coupled runs of the beam FMU (scenes/cantilever_payload.json) with the load-model FMUs of
examples/coupling (payload and wave, built here with pythonfmu), under the plain fmpy master
(examples/coupling/cosim.py) and under libcosim (libcosimpy, OspSystemStructure.xml).

Accuracy checks with their tolerances:
* static: a damped hanging payload deflects the tip as a point load m g does in Timoshenko beam
  theory (plane strain, shear correction 5/6), within 3% (the particle model at 12 particles
  through the thickness is ~1% soft in bending, see examples/coupling/resolution.py); the force
  the payload model sees equals the clamp reaction to 1% (static equilibrium of a weightless beam);
* dynamic: the lowest frequency of beam + payload within 3% of a Timoshenko beam FE model with the
  payload's spring and mass (examples/coupling/reference.py), and within 3% of the 2-DOF model
  (the beam's first mode as a modal oscillator, from the FE static stiffness and frequency);
* convergence: at communication steps 2, 1, 0.5, 0.25 ms the observed order is 1 for zero-order
  hold (Jacobi, Gauss-Seidel) and 2 for Gauss-Seidel with linear extrapolation (input derivatives);
* energy: beam kinetic + strain energy + payload energy within 1% over 10 periods at 1 ms,
  undamped (Gauss-Seidel, 2nd order);
* libcosim's fixed-step algorithm and the fmpy Jacobi loop give the same states.

Run by scripts/fmu_tests.sh (the beam FMU comes from MPS_FMU_DIR, default target/fmu).
"""
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
EX = ROOT / "examples" / "coupling"
sys.path.insert(0, str(EX))
import analysis  # noqa: E402
import cosim  # noqa: E402
from reference import Beam, two_dof_frequencies  # noqa: E402

FMU_DIR = Path(os.environ.get("MPS_FMU_DIR", ROOT / "target" / "fmu"))
SCENE = ROOT / "scenes" / "cantilever_payload.json"
M, K, G = 10.0, 4.0e4, 9.81  # payload: kg/m, N/m per m, m/s2
X0 = -0.01  # initial payload displacement of the free-vibration runs (m)


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    """Directory with the beam FMU and the payload and wave FMUs built by pythonfmu."""
    beam = FMU_DIR / "cantilever_payload.fmu"
    if not beam.exists():
        pytest.fail(f"{beam} missing: run scripts/fmu_tests.sh (it packs scenes/)")
    d = tmp_path_factory.mktemp("coupling")
    shutil.copy(beam, d / beam.name)
    for model in ("payload", "wave"):
        subprocess.run([sys.executable, "-m", "pythonfmu", "build", "-f", str(EX / f"{model}.py"), "-d", str(d)],
                       check=True, capture_output=True)
    return d


@pytest.fixture(scope="module")
def beam_ref():
    return Beam.from_scene(str(SCENE))


def run(fmus, H, T, algorithm="gauss-seidel", order=2, **kw):
    return cosim.run(str(fmus / "cantilever_payload.fmu"), str(fmus / "Payload.fmu"), H, T, algorithm,
                     order=order, **kw)


@pytest.fixture(scope="module")
def free_vibration(fmus, beam_ref):
    """Undamped beam + payload released from x0 = -1 cm, 10 periods of the lowest mode at 1 ms."""
    f1 = beam_ref.frequencies(M, K)[0]
    T = 2e-3 * round(10.5 / f1 / 2e-3)  # a whole number of records of 2 ms
    return run(fmus, 1e-3, T, payload=dict(m=M, k=K, x0=X0), record_every=2)


def test_static_hanging_payload_matches_timoshenko_and_clamp_reaction(fmus, beam_ref):
    # payload hung with its spring at the static stretch, the beam at rest: damped to static
    # (beam 60 1/s mass-proportional, payload damper critical for the payload alone)
    r = run(fmus, 1e-3, 0.5, beam={"solver.damping": 60.0},
            payload=dict(m=M, k=K, c=2 * math.sqrt(K * M), g=G, x0=-M * G / K), record_every=10)
    u = r["tip.uy"]
    assert abs(u[-1] - u[-6]) < 1e-3 * abs(u[-1]), "not static after 0.5 s"
    ref = -beam_ref.tip_deflection(M * G)
    assert u[-1] / ref - 1 == pytest.approx(0.0, abs=0.03), (u[-1], ref)
    force, reaction = r["force"][-1], r["clamp.reaction_y"][-1]
    assert force == pytest.approx(-M * G, rel=1e-3)
    assert -reaction == pytest.approx(force, rel=0.01), (force, reaction)
    print(f"static: tip {u[-1]:.6e} m vs Timoshenko {ref:.6e} m ({u[-1] / ref - 1:+.2%}); "
          f"payload force {force:.4f} N/m, clamp reaction {reaction:.4f} N/m")


def test_lowest_frequency_matches_beam_fe_and_two_dof_references(free_vibration, beam_ref):
    r = free_vibration
    f_x = analysis.lowest_frequency(r.t, r["x"])
    f_u = analysis.lowest_frequency(r.t, r["tip.uy"])
    f_fe = beam_ref.frequencies(M, K)[0]
    k_tip = 1.0 / beam_ref.tip_deflection(1.0)
    f_2dof = two_dof_frequencies(k_tip, beam_ref.frequencies()[0], M, K)[0]
    assert f_x == pytest.approx(f_u, rel=1e-3)
    assert f_x == pytest.approx(f_fe, rel=0.03), (f_x, f_fe)
    assert f_x == pytest.approx(f_2dof, rel=0.03), (f_x, f_2dof)
    print(f"dynamic: lowest {f_x:.4f} Hz, FE {f_fe:.4f} Hz ({f_x / f_fe - 1:+.2%}), "
          f"2-DOF {f_2dof:.4f} Hz ({f_x / f_2dof - 1:+.2%})")


def test_energy_of_undamped_coupled_system_within_one_percent_over_ten_periods(free_vibration, beam_ref):
    r = free_vibration
    assert r.t[-1] * beam_ref.frequencies(M, K)[0] >= 10.0
    e = cosim.total_energy(r)
    assert e[0] == pytest.approx(0.5 * K * X0**2)
    drift = analysis.energy_drift(e)
    assert drift < 0.01, drift
    print(f"energy: {e[0]:.5f} J/m, largest deviation {drift:.3%} over {r.t[-1]:.2f} s")


@pytest.mark.parametrize("algorithm,order", [("jacobi", 1), ("gauss-seidel", 1), ("gauss-seidel", 2)])
def test_convergence_order_in_the_communication_step(fmus, algorithm, order):
    steps = [2e-3, 1e-3, 5e-4, 2.5e-4]
    res = [run(fmus, H, 0.1, algorithm, order, payload=dict(m=M, k=K, x0=X0), record_every=int(round(2e-3 / H)))
           for H in steps]
    d, p = analysis.orders(steps, [np.concatenate([r["x"], r["tip.uy"]]) for r in res])
    assert all(a > b for a, b in zip(d, d[1:])), d
    for q in p:
        assert q == pytest.approx(order, abs=0.3), (d, p)
    print(f"convergence {algorithm} order {order}: differences {d} (m), observed orders {p}")


def test_libcosim_fixed_step_equals_fmpy_jacobi(fmus):
    sys.path.insert(0, str(EX))
    import run_libcosim

    H, T = 1e-3, 0.05
    payload = dict(m=M, k=K, x0=X0)
    lc = run_libcosim.run(str(fmus), H, T, payload=payload)
    fp = run(fmus, H, T, "jacobi", 1, payload=payload)
    # libcosim's record starts after its first step (t = H)
    for name in ("tip.uy", "x", "xdot", "clamp.reaction_y"):
        a, b = lc[name], fp[name][1:]
        assert np.allclose(a, b, rtol=0, atol=1e-9 * np.abs(b).max()), name
    assert np.allclose(lc.t, fp.t[1:])


def test_wave_load_on_mid_region_moves_the_beam(fmus):
    r = cosim.run(str(fmus / "cantilever_payload.fmu"), str(fmus / "Payload.fmu"), 1e-3, 0.1, "gauss-seidel",
                  payload=dict(m=M, k=K), wave_fmu=str(fmus / "Wave.fmu"), wave=dict(kind=2, hs=200.0, tp=0.25))
    assert np.all(np.isfinite(r["tip.uy"]))
    assert np.abs(r["wave"]).max() > 20.0
    assert np.abs(r["tip.uy"]).max() > 1e-5
    # with no payload offset the only load is the wave's: the clamp takes it (with inertia)
    assert np.abs(r["clamp.reaction_y"]).max() > 1.0


@pytest.mark.parametrize("script,args", [
    ("run_fmpy.py", ["--stop", "0.01", "--wave"]),
    ("run_libcosim.py", ["--stop", "0.01"]),
])
def test_example_scripts_run(fmus, script, args):
    out = subprocess.run([sys.executable, str(EX / script), "--fmu-dir", str(fmus), *args],
                         capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "tip.uy" in out.stdout
