"""Time-series load model as a pythonfmu co-simulation FMU: a force F(t) on a beam region.

kind = 1: linear sine sweep  F = amplitude sin(2 pi (f_start t + (f_end - f_start) t^2 / (2 duration)))
          for t <= duration, then 0;
kind = 2: irregular wave force from a Pierson-Moskowitz spectrum with significant amplitude hs
          (4 standard deviations) and peak period tp, as `components` cosines at equally spaced
          frequencies between 0.5/tp and 3/tp with random phases (seed): a repeatable record.

Output `force` (N; per metre of depth in 2D) is the value at the current time, so a master that
holds it over a step applies F(t_n) on [t_n, t_n + H]. Connect it to the beam's `mid.fy`.
Build: pythonfmu build -f wave.py -d ../../target/coupling
"""
import math
import random

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real


class Wave(Fmi2Slave):
    author = "mps-solid"
    description = "Time-series load: sine sweep or irregular wave force"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.kind = 2
        self.amplitude = 100.0
        self.f_start = 1.0
        self.f_end = 20.0
        self.duration = 2.0
        self.hs = 200.0
        self.tp = 0.25
        self.seed = 1
        self.components = 64
        self.time = 0.0
        par, fixed = Fmi2Causality.parameter, Fmi2Variability.fixed
        self.register_variable(Integer("kind", causality=par, variability=fixed,
                                       description="1 sine sweep, 2 irregular wave (spectrum)"))
        for name, doc in [
            ("amplitude", "sweep amplitude (N)"),
            ("f_start", "sweep start frequency (Hz)"),
            ("f_end", "sweep end frequency (Hz)"),
            ("duration", "sweep duration (s)"),
            ("hs", "significant force amplitude 4 sigma of the wave force (N)"),
            ("tp", "peak period of the spectrum (s)"),
        ]:
            self.register_variable(Real(name, causality=par, variability=fixed, description=doc))
        self.register_variable(Integer("seed", causality=par, variability=fixed, description="phases seed"))
        self.register_variable(Integer("components", causality=par, variability=fixed,
                                       description="number of cosines of the irregular record"))
        self.register_variable(Real("force", causality=Fmi2Causality.output, variability=Fmi2Variability.continuous,
                                    getter=self.force, description="load at the current time (N)"))
        self._waves = []

    def exit_initialization_mode(self):
        self.time = 0.0
        if self.kind == 2:
            rng = random.Random(self.seed)
            fp = 1.0 / self.tp
            n = max(1, int(self.components))
            df = 2.5 * fp / n
            self._waves = []
            for i in range(n):
                f = 0.5 * fp + (i + 0.5) * df
                s = 5.0 / 16.0 * self.hs**2 * fp**4 / f**5 * math.exp(-1.25 * (fp / f) ** 4)
                self._waves.append((math.sqrt(2 * s * df), 2 * math.pi * f, rng.uniform(0, 2 * math.pi)))

    def force(self) -> float:
        t = self.time
        if self.kind == 1:
            if t > self.duration:
                return 0.0
            rate = (self.f_end - self.f_start) / self.duration
            return self.amplitude * math.sin(2 * math.pi * (self.f_start * t + 0.5 * rate * t * t))
        return sum(a * math.cos(w * t + p) for a, w, p in self._waves)

    def do_step(self, current_time: float, step_size: float) -> bool:
        self.time = current_time + step_size
        return True
