"""The packed FMUs under fmpy: validation, the paper's cases 1 and 2 through simulate_fmu, a
communication step that does not divide the stop time, rollback with get/set FMU state.

Run by scripts/fmu_tests.sh, which packs scenes/*.json and tests/data/small*.json into target/fmu/
(MPS_FMU_DIR overrides the directory).
"""
import json
import math
import os
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Slave
from fmpy.validation import validate_fmu

ROOT = Path(__file__).resolve().parents[2]
FMU_DIR = Path(os.environ.get("MPS_FMU_DIR", ROOT / "target" / "fmu"))
FMUS = sorted(FMU_DIR.glob("*.fmu"))


def fmu_path(name):
    p = FMU_DIR / f"{name}.fmu"
    if not p.exists():
        pytest.fail(f"{p} missing: run scripts/fmu_tests.sh (it packs scenes/ and tests/data/)")
    return str(p)


def scene_of(fmu):
    with zipfile.ZipFile(fmu) as z:
        return json.loads(z.read("resources/scene.json"))


def test_fmus_were_packed():
    names = {p.stem for p in FMUS}
    scenes = {json.loads(p.read_text())["name"] for p in (ROOT / "scenes").glob("*.json")}
    assert scenes <= names, f"missing FMUs for {scenes - names} in {FMU_DIR}"


@pytest.mark.parametrize("fmu", FMUS, ids=[p.stem for p in FMUS])
def test_validate_fmu_reports_nothing(fmu):
    assert validate_fmu(str(fmu)) == []
    md = read_model_description(str(fmu))
    assert md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate
    with zipfile.ZipFile(fmu) as z:
        names = set(z.namelist())
    ident = md.coSimulation.modelIdentifier
    for f in ["modelDescription.xml", f"binaries/linux64/{ident}.so", "resources/scene.json",
              "documentation/index.html"]:
        assert f in names


def paper_ramp(t, period):
    """Eq. (46)."""
    return np.where(t <= 0.2 * period, 0.5 - 0.5 * np.cos(5 * np.pi * t / period), 1.0)


def test_case1_gravity_ramp_as_input_matches_closed_form():
    fmu = fmu_path("case1_column")
    scene = scene_of(fmu)
    g = scene["gravity"]["vector"]
    period = scene["gravity"]["paper_ramp_period"]
    t = np.linspace(0.0, scene["end_time"], 2001)
    ramp = paper_ramp(t, period)
    signals = np.array(
        list(zip(t, g[0] * ramp, g[1] * ramp, g[2] * ramp)),
        dtype=[("time", np.float64), ("gravity_x", np.float64), ("gravity_y", np.float64),
               ("gravity_z", np.float64)],
    )
    probes = [p for p in scene["probes"]]
    names = [f"{p['name']}.{c}" for p in probes for c in ("ux", "uz")]
    # gravity_source = 2: gravity from the inputs (the scene's own law, the same ramp, is the
    # default of this scene).
    res = simulate_fmu(fmu, stop_time=scene["end_time"], output_interval=scene["output_interval"],
                       input=signals, output=names + ["support.reaction_z"],
                       start_values={"gravity_source": 2})
    assert math.isclose(res["time"][-1], scene["end_time"])
    m = scene["bodies"][0]["material"]
    rho, e, nu, gz = m["density"], m["young"], m["poisson"], abs(g[2])
    length = -min(b["min"][2] for b in scene["bodies"][0]["boxes"])
    rg = rho * gz
    stations = []
    for p in probes:
        x, y, z = p["point"]
        s = -z
        ux_cf = -nu * rg * x * (length - s) / e
        uz_cf = -(rg * (length * s - 0.5 * s * s) / e - nu * rg * (x * x + y * y) / (2 * e))
        stations.append((s, res[f"{p['name']}.ux"][-1], ux_cf, res[f"{p['name']}.uz"][-1], uz_cf))
    far = [st for st in stations if st[0] >= 0.2 - 1e-9]
    err_ux = max(abs(u - c) for _, u, c, _, _ in far) / max(abs(c) for _, _, c, _, _ in far)
    err_uz = max(abs(u - c) for _, _, _, u, c in far) / max(abs(c) for _, _, _, _, c in far)
    print(f"case 1 through fmpy: error ux {err_ux:.4f}, uz {err_uz:.4f}")
    assert err_ux <= 0.03, stations
    assert err_uz <= 0.03, stations


def test_case1_scene_gravity_law_survives_interpolated_inputs():
    # Issue 8.9: fmpy interpolates a constant input -9.81 to -9.809999999999999, which used to
    # replace the scene's Eq. (46) ramp by sudden gravity (support reaction 18.9 N -> 239 N at
    # t = 0.03 s). With the default gravity_source = 1 the scene's law stays in force.
    fmu = fmu_path("case1_column")
    scene = scene_of(fmu)
    g = scene["gravity"]["vector"]
    t = np.array([0.0, 0.0137, 0.05])
    signals = np.array(
        [(ti, -0.0, g[1], g[2]) for ti in t],
        dtype=[("time", np.float64), ("gravity_x", np.float64), ("gravity_y", np.float64),
               ("gravity_z", np.float64)],
    )
    kw = dict(stop_time=0.03, output_interval=0.001, output=["support.reaction_z"])
    with_input = simulate_fmu(fmu, input=signals, **kw)
    without = simulate_fmu(fmu, **kw)
    assert np.array_equal(with_input["support.reaction_z"], without["support.reaction_z"])
    # The ramp: at t = 0.03 s the reaction is far below the weight it reaches at full gravity.
    print(f"support reaction at t = 0.03 s: {without['support.reaction_z'][-1]:.2f} N")
    assert abs(without["support.reaction_z"][-1]) < 50.0


def dominant_frequency(t, u, f_lo, f_hi):
    """Least-squares sinusoid fit u ~ a + b cos(2 pi f t) + c sin(2 pi f t): grid, then golden section."""
    def residual(f):
        w = 2 * np.pi * f
        a = np.column_stack([np.ones_like(t), np.cos(w * t), np.sin(w * t)])
        x, *_ = np.linalg.lstsq(a, u, rcond=None)
        return float(np.sum((u - a @ x) ** 2))

    grid = f_lo * (f_hi / f_lo) ** (np.arange(801) / 800)
    best = grid[int(np.argmin([residual(f) for f in grid]))]
    step = (f_hi / f_lo) ** (1 / 800)
    a, b = best / step, best * step
    g = 0.5 * (math.sqrt(5) - 1)
    for _ in range(60):
        c, d = b - g * (b - a), a + g * (b - a)
        if residual(c) < residual(d):
            b = d
        else:
            a = c
    return 0.5 * (a + b), residual(0.5 * (a + b)) / float(np.sum((u - u.mean()) ** 2))


def test_case2_first_frequency_matches_fem():
    fmu = fmu_path("case2_beam")
    scene = scene_of(fmu)
    res = simulate_fmu(fmu, stop_time=scene["end_time"], output_interval=scene["output_interval"],
                       output=["max.uz"])
    t, u = res["time"], res["max.uz"]
    assert np.all(np.isfinite(u)) and u.min() < 0
    f, rel_residual = dominant_frequency(t, u, 0.5 / scene["end_time"] * 4.0,
                                         0.25 / scene["output_interval"])
    assert rel_residual < 0.2, f"poor sinusoid fit ({rel_residual})"
    ref = ROOT / "reference" / "case2_fem.json"
    if not ref.exists():
        pytest.skip(f"no FEM reference yet ({ref}); measured f1 = {f:.3f} Hz")
    f1 = json.loads(ref.read_text())["converged"]["f1_hz"]
    print(f"case 2 through fmpy: f1 = {f:.4f} Hz, FEM {f1:.4f} Hz, error {f / f1 - 1:+.4f}")
    assert abs(f / f1 - 1) <= 0.03


def test_step_that_does_not_divide_the_stop_time():
    fmu = fmu_path("small3d")
    res = simulate_fmu(fmu, stop_time=0.1, output_interval=0.003, output=["tip.uz", "steps"])
    assert res["time"][-1] == pytest.approx(0.1, abs=1e-12)
    assert np.allclose(np.diff(res["time"][:-1]), 0.003)
    assert res["time"][-1] - res["time"][-2] < 0.003
    fine = simulate_fmu(fmu, stop_time=0.1, output_interval=0.001, output=["tip.uz"])
    # Different sub-step splits, same physics.
    assert res["tip.uz"][-1] == pytest.approx(fine["tip.uz"][-1], rel=0.02)


def outputs_of(md):
    return [v for v in md.modelVariables if v.causality == "output"]


def test_rollback_with_get_and_set_fmu_state():
    fmu = fmu_path("small3d")
    md = read_model_description(fmu)
    unzipdir = extract(fmu)
    reals = [v.valueReference for v in outputs_of(md) if v.type == "Real"]
    ints = [v.valueReference for v in outputs_of(md) if v.type == "Integer"]
    fz = next(v.valueReference for v in md.modelVariables if v.name == "tip_load.fz")
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="rollback")
    slave.instantiate()
    try:
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        h, t = 0.002, 0.0
        for _ in range(10):
            slave.doStep(t, h)
            t += h
        state = slave.getFMUstate()
        blob = slave.serializeFMUstate(state)
        t0 = t

        def run(t):
            out = []
            for k in range(10):
                if k == 5:
                    slave.setReal([fz], [-2.0])
                slave.doStep(t, h)
                t += h
                out.append((slave.getReal(reals), slave.getInteger(ints)))
            return out

        first = run(t0)
        slave.setFMUstate(state)
        assert slave.getReal([fz]) == [0.0]
        assert run(t0) == first
        restored = slave.deSerializeFMUstate(blob)
        slave.setFMUstate(restored)
        assert run(t0) == first
        slave.freeFMUstate(restored)
        slave.freeFMUstate(state)
        slave.terminate()
    finally:
        slave.freeInstance()


def test_instance_reused_with_reset_rewinds_instead_of_building(capfd):
    """fmpy's loop over one instance (simulate_fmu with fmu_instance, then reset): the same
    parameters rewind the model built for them (no second set-up, the same numbers bit for
    bit); other parameters build anew, taking the first build's closure (the parameters change
    no geometry), and the first ones come back as they were. The log is read from fmpy's own
    logger (stdout): a logger callback of ours would leave fmpy's logging proxy pointing at it
    once it is collected, and the next instance of the process would call it (a crash in
    fmpy's logging.so, not in the FMU)."""
    from fmpy import instantiate_fmu

    fmu = fmu_path("small3d")
    md = read_model_description(fmu)
    unzipdir = extract(fmu)
    inst = instantiate_fmu(unzipdir, md, "CoSimulation", debug_logging=True)
    young = next(v.name for v in md.modelVariables if v.name.endswith(".young"))
    try:
        def run(start_values):
            capfd.readouterr()
            res = simulate_fmu(unzipdir, model_description=md, fmu_instance=inst,
                               stop_time=0.02, output_interval=0.002, output=["tip.uz"],
                               start_values=start_values)
            inst.reset()
            out, err = capfd.readouterr()
            return res["tip.uz"], out + err

        first, log = run({})
        assert "built the model:" in log, log
        again, log = run({})
        assert "rewound the model built" in log, log
        assert "built the model:" not in log, log
        assert np.array_equal(again, first)
        stiff, log = run({young: 2 * scene_of(fmu)["bodies"][0]["material"]["young"]})
        assert "built the model:" in log, log
        assert "as an earlier set-up of this geometry closed them" in log, log
        assert not np.array_equal(stiff, first)
        back, _ = run({})
        assert np.array_equal(back, first)
    finally:
        inst.freeInstance()


def test_sweep_example_reuses_one_instance():
    """examples/fmpy_sweep.py on small3d: one row per value, the same numbers for a value run
    again after another."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, str(ROOT / "examples" / "fmpy_sweep.py"),
                          fmu_path("small3d"), "--output", "tip.uz", "--stop", "0.01",
                          "--values", "1e6,3e6,1e6"],
                         check=True, capture_output=True, text=True).stdout.splitlines()
    rows = [line.split() for line in out[1:]]
    assert len(rows) == 3, out
    assert rows[0][:3] == rows[2][:3] and rows[0][1] != rows[1][1], out


def test_case3_with_fractured_surface_contact_completes_and_breaks_after_contact():
    # The paper's case 3 through fmpy: the cube reaches the block at gap / speed = 0.07 s, so no
    # bond may break before that; bonds break afterwards (fracture_count rises from zero) and the
    # run with contact detection between fractured surfaces completes to 1.7 s.
    fmu = fmu_path("case3_collision")
    res = simulate_fmu(fmu, stop_time=1.7, output_interval=0.01,
                       output=["fracture_count", "fracture_energy"])
    t, n, released = res["time"], res["fracture_count"], res["fracture_energy"]
    assert t[-1] == pytest.approx(1.7, abs=1e-12)
    assert np.all(n[t < 0.07 - 1e-9] == 0)
    assert n[-1] > 0
    assert np.all(np.diff(n) >= 0), "broken bonds never heal"
    # The energy the breaks released: none before the first break, then positive and never
    # shrinking (a break releases energy and never creates it).
    assert np.all(released[n == 0] == 0.0)
    assert released[-1] > 0.0
    assert np.all(np.diff(released) >= 0.0)


def test_case3_without_fractured_surface_contact_breaks_and_never_returns_nan(capfd):
    # Without contact detection between fractured surfaces the broken parts of the block move
    # through each other with no force. Whether two of their particles come closer than the
    # overlap limit (0.5 l0) before 1.7 s is marginal in our set-up (closest approach ~0.4996
    # l0 at 1.616 s with one sub-step split, just above it with another; see docs/paper-cases.md), so the test
    # asserts what must hold either way: bonds break after contact, every output stays finite,
    # and if a step fails it fails with fmi2Error and a logged message naming the overlap
    # (the paper's run "stopped owing to the overlap of the particles").
    fmu = fmu_path("case3_collision_no_fracture_contact")
    md = read_model_description(fmu)
    unzipdir = extract(fmu)
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="case3")
    slave.instantiate(loggingOn=True)
    reals = [v.valueReference for v in outputs_of(md) if v.type == "Real"]
    count = next(v.valueReference for v in md.modelVariables if v.name == "fracture_count")
    try:
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        t, h, failed_at = 0.0, 0.01, None
        while t < 1.7 - 1e-9:
            try:
                slave.doStep(t, h)
            except Exception:  # fmpy raises on fmi2Error
                failed_at = t
                break
            t += h
            if t < 0.07 - 1e-9:
                assert slave.getInteger([count]) == [0]
            assert all(math.isfinite(v) for v in slave.getReal(reals))
        assert all(math.isfinite(v) for v in slave.getReal(reals))
        assert slave.getInteger([count])[0] > 0
    finally:
        slave.freeInstance()
    out, err = capfd.readouterr()
    if failed_at is not None:
        assert failed_at > 0.5, failed_at
        assert "overlap" in (out + err).lower(), out + err


def test_stl_bracket_runs_from_its_packed_mesh():
    """scenes/bracket_stl.json as an FMU: its STL is in the FMU's resources (the scene names it
    relative to resources/), the FMU reads it from there, and a force on the upright's top moves
    the top the way it pushes (issue 26)."""
    fmu = fmu_path("bracket_stl")
    with zipfile.ZipFile(fmu) as z:
        names = set(z.namelist())
        scene = json.loads(z.read("resources/scene.json"))
    mesh = scene["bodies"][0]["shapes"][0]["mesh"]["file"]
    assert f"resources/{mesh}" in names
    md = read_model_description(fmu)
    unzipdir = extract(fmu)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bracket")
    slave.instantiate()
    try:
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        slave.setReal([vr["top.fx"]], [2000.0])
        t, h = 0.0, 1e-4
        for _ in range(10):
            slave.doStep(t, h)
            t += h
        ux, uz = slave.getReal([vr["top.ux"], vr["top.uz"]])
        assert math.isfinite(ux) and math.isfinite(uz)
        assert ux > 0.0, ux
        slave.terminate()
    finally:
        slave.freeInstance()
