"""A plain fmpy co-simulation master (FMU2Slave) for the beam FMU and its load models.

`run()` couples the beam FMU (scenes/cantilever_payload.json packed) to the payload FMU
(payload.py) at a fixed communication step H, optionally with a time-series load FMU (wave.py) on
the beam's `mid` region, with one of two algorithms:

* "jacobi": all FMUs step from the same inputs, then outputs are copied to inputs. This is what
  libcosim's fixed-step algorithm does, including the order of reading a direct-feedthrough output
  (the payload's force is read after its step, before its new inputs are set).
* "gauss-seidel": the beam steps first; the payload then steps with the beam's new tip motion, and
  its force (with the new tip motion) goes to the beam for the next step.

Both hold the inputs over a step (zero-order hold), so both converge at first order in H.
"""
import time
from dataclasses import dataclass, field

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

# Beam solver step: a divisor of every communication step used (0.25 ms / 16), below the automatic
# stable step of the 12-through-the-thickness scene (1.64e-5 s), so the beam's own time integration
# is the same whatever the communication step.
BEAM_DT = 1.5625e-5


class Fmu:
    """An FMU2Slave with variables by name."""

    def __init__(self, path: str, name: str, unpacked: dict = {}):
        self.md = read_model_description(path)
        if path not in unpacked:
            unpacked[path] = extract(path)
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.type = {v.name: v.type for v in self.md.modelVariables}
        self.s = FMU2Slave(guid=self.md.guid, unzipDirectory=unpacked[path],
                           modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=name)
        self.s.instantiate()

    def set(self, **values):
        for k, v in values.items():
            k = k.replace("__", ".")
            if self.type[k] == "Integer":
                self.s.setInteger([self.vr[k]], [int(v)])
            else:
                self.s.setReal([self.vr[k]], [float(v)])

    def get(self, *names) -> list:
        return self.s.getReal([self.vr[n] for n in names])

    def init(self, t0: float = 0.0, **params):
        self.s.setupExperiment(startTime=t0)
        self.set(**params)
        self.s.enterInitializationMode()
        self.s.exitInitializationMode()

    def free(self):
        self.s.terminate()
        self.s.freeInstance()


@dataclass
class Result:
    t: np.ndarray
    data: dict = field(default_factory=dict)
    wall: float = 0.0

    def __getitem__(self, k):
        return self.data[k]


BEAM_OUT = ["tip.uy", "tip.vy", "clamp.reaction_y", "kinetic_energy", "strain_energy", "end.uy"]
PAYLOAD_OUT = ["force", "x", "xdot", "energy", "dissipated"]


def run(beam_fmu: str, payload_fmu: str, H: float, T: float, algorithm: str = "jacobi",
        beam: dict | None = None, payload: dict | None = None, wave_fmu: str | None = None,
        wave: dict | None = None, record_every: int = 1, order: int = 1) -> Result:
    """Couples beam and payload (and a wave load on `mid` if wave_fmu) from 0 to T at step H.
    beam/payload/wave: start values by name ("solver.dt" may be written solver__dt)."""
    b = Fmu(beam_fmu, "beam")
    p = Fmu(payload_fmu, "payload")
    w = Fmu(wave_fmu, "wave") if wave_fmu else None
    b.init(**{"solver.dt": BEAM_DT, **(beam or {})})
    p.init(**{**(payload or {}), **({"extrapolate": 1} if order == 2 else {})})
    vr_fy = b.vr["tip.fy"]
    if w:
        w.init(**(wave or {}))
    n = int(round(T / H))
    t = 0.0
    rec_t, rec = [], {k: [] for k in BEAM_OUT + PAYLOAD_OUT + ["wave"]}

    def record(t):
        rec_t.append(t)
        for k, v in zip(BEAM_OUT, b.get(*BEAM_OUT)):
            rec[k].append(v)
        for k, v in zip(PAYLOAD_OUT, p.get(*PAYLOAD_OUT)):
            rec[k].append(v)
        rec["wave"].append(w.get("force")[0] if w else 0.0)

    # initial exchange: the payload sees the beam at rest, the beam the payload's initial force
    uy, vy = b.get("tip.uy", "tip.vy")
    p.set(u=uy, v=vy)
    b.set(**{"tip.fy": p.get("force")[0]})
    if w:
        b.set(**{"mid.fy": w.get("force")[0]})
    record(t)
    t0 = time.perf_counter()
    for i in range(n):
        if algorithm == "jacobi":
            b.s.doStep(t, H)
            p.s.doStep(t, H)
            if w:
                w.s.doStep(t, H)
            force = p.get("force")[0]  # new payload state, old tip motion (as libcosim reads it)
            uy, vy = b.get("tip.uy", "tip.vy")
            b.set(**{"tip.fy": force})
            p.set(u=uy, v=vy)
        elif algorithm == "gauss-seidel":
            if order == 2:
                b.s.setRealInputDerivatives([vr_fy], [1], [p.get("force_rate")[0]])
            b.s.doStep(t, H)
            if w:
                w.s.doStep(t, H)
            u0 = uy
            uy, vy = b.get("tip.uy", "tip.vy")
            if order == 2:  # the payload follows the tip linearly from u_n to u_n+1
                p.set(u=u0, v=(uy - u0) / H)
                p.s.doStep(t, H)
                p.set(u=uy, v=vy)
            else:
                p.set(u=uy, v=vy)
                p.s.doStep(t, H)
            b.set(**{"tip.fy": p.get("force")[0]})
        else:
            raise ValueError(f"unknown algorithm {algorithm!r}")
        if w:
            b.set(**{"mid.fy": w.get("force")[0]})
        t = (i + 1) * H
        if (i + 1) % record_every == 0 or i + 1 == n:
            record(t)
    wall = time.perf_counter() - t0
    for f in (b, p, w):
        if f:
            f.free()
    return Result(np.array(rec_t), {k: np.array(v) for k, v in rec.items()}, wall)


def run_beam_alone(beam_fmu: str, H: float, T: float, force: float = 0.0, beam: dict | None = None) -> Result:
    """The beam FMU alone under a constant tip force, stepped at H (the benchmark's baseline)."""
    b = Fmu(beam_fmu, "beam")
    b.init(**{"solver.dt": BEAM_DT, **(beam or {})})
    b.set(**{"tip.fy": force})
    n = int(round(T / H))
    ts, us = [0.0], [b.get("tip.uy")[0]]
    t0 = time.perf_counter()
    for i in range(n):
        b.s.doStep(i * H, H)
        ts.append((i + 1) * H)
        us.append(b.get("tip.uy")[0])
    wall = time.perf_counter() - t0
    b.free()
    return Result(np.array(ts), {"tip.uy": np.array(us)}, wall)


def total_energy(r: Result) -> np.ndarray:
    """Beam kinetic + strain energy (FMU outputs) + payload energy (its own output), J per m."""
    return r["kinetic_energy"] + r["strain_energy"] + r["energy"]
