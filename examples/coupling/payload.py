"""Payload load model as a pythonfmu co-simulation FMU: a mass m hanging from the beam's tip on a
spring k and a damper c, moving along one axis (the beam's y).

Coupling variables (2D: per metre of depth, like the beam FMU):
  inputs   u, v        tip displacement (m) and velocity (m/s) of the beam's load region
                       (connect from `tip.uy`, `tip.vy`)
  outputs  force       force of the spring-damper on the beam, k (x - u) + c (xdot - v) (N);
                       connect to `tip.fy`. It depends directly on the inputs (direct feedthrough)
           force_rate  d(force)/dt (N/s), for masters that extrapolate the force
           x, xdot     payload displacement (m) and velocity (m/s) from where it hangs unloaded
           energy      m xdot^2 / 2 + k (x - u)^2 / 2 + m g x (J): kinetic, spring and gravity
           dissipated  energy dissipated by the damper since t = 0 (J)

Between communication points the inputs are held (extrapolate = 0) or u moves linearly with
slope v (extrapolate = 1); the motion over a step is integrated with RK4 sub-steps of at most
1/100 of the payload's own period. Build: pythonfmu build -f payload.py -d ../../target/coupling
"""
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Status


class Payload(Fmi2Slave):
    author = "mps-solid"
    description = "Mass on a spring-damper hanging from a beam tip (1 axis)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.m = 10.0
        self.k = 4.0e4
        self.c = 0.0
        self.g = 0.0
        self.x0 = 0.0
        self.xdot0 = 0.0
        self.extrapolate = 0
        self.u = 0.0
        self.v = 0.0
        self.x = 0.0
        self.xdot = 0.0
        self.dissipated = 0.0
        par, tun = Fmi2Causality.parameter, Fmi2Variability.tunable
        fixed = Fmi2Variability.fixed
        for name, doc in [
            ("m", "payload mass (kg; per metre of depth in 2D)"),
            ("k", "spring stiffness (N/m)"),
            ("c", "damper coefficient (N s/m)"),
            ("g", "gravity acceleration acting on the payload along -y (m/s2)"),
        ]:
            self.register_variable(Real(name, causality=par, variability=tun, description=doc))
        for name, doc in [
            ("x0", "initial payload displacement (m)"),
            ("xdot0", "initial payload velocity (m/s)"),
        ]:
            self.register_variable(Real(name, causality=par, variability=fixed, description=doc))
        self.register_variable(
            Integer(
                "extrapolate",
                causality=par,
                variability=fixed,
                description="0: u held over a step; 1: u + v (t - t_n) over a step",
            )
        )
        inp, cont = Fmi2Causality.input, Fmi2Variability.continuous
        self.register_variable(Real("u", causality=inp, variability=cont, description="tip displacement (m)"))
        self.register_variable(Real("v", causality=inp, variability=cont, description="tip velocity (m/s)"))
        out = Fmi2Causality.output
        self.register_variable(
            Real("force", causality=out, variability=cont, getter=self.force, description="force on the beam (N)")
        )
        self.register_variable(
            Real("force_rate", causality=out, variability=cont, getter=self.force_rate,
                 description="d(force)/dt with the tip moving at v (N/s)")
        )
        self.register_variable(Real("x", causality=out, variability=cont, description="payload displacement (m)"))
        self.register_variable(Real("xdot", causality=out, variability=cont, description="payload velocity (m/s)"))
        self.register_variable(
            Real("energy", causality=out, variability=cont, getter=self.energy, description="payload energy (J)")
        )
        self.register_variable(
            Real("dissipated", causality=out, variability=cont, description="energy dissipated by the damper (J)")
        )

    def exit_initialization_mode(self):
        self.x = self.x0
        self.xdot = self.xdot0
        self.dissipated = 0.0

    def force(self) -> float:
        """Force of the spring-damper on the beam (N), from the current state and inputs."""
        return self.k * (self.x - self.u) + self.c * (self.xdot - self.v)

    def force_rate(self) -> float:
        """Time derivative of `force` (N/s) for a tip moving at v with no acceleration."""
        acc = (-self.k * (self.x - self.u) - self.c * (self.xdot - self.v)) / self.m - self.g
        return self.k * (self.xdot - self.v) + self.c * acc

    def energy(self) -> float:
        """Kinetic, spring and gravity energy of the payload (J)."""
        s = self.x - self.u
        return 0.5 * self.m * self.xdot**2 + 0.5 * self.k * s * s + self.m * self.g * self.x

    def _rhs(self, tau: float, y):
        x, xd, _ = y
        u = self.u + (self.v * tau if self.extrapolate else 0.0)
        fd = self.c * (xd - self.v)
        a = (-self.k * (x - u) - fd) / self.m - self.g
        return (xd, a, fd * (xd - self.v))

    def do_step(self, current_time: float, step_size: float) -> bool:
        if not all(math.isfinite(q) for q in (self.u, self.v, self.m, self.k, self.c, self.g)) or self.m <= 0:
            self.log("payload: non-finite input or parameter, or m <= 0", Fmi2Status.error)
            return False
        period = 2 * math.pi * math.sqrt(self.m / self.k) if self.k > 0 else step_size
        n = max(1, math.ceil(step_size / (period / 100)))
        h = step_size / n
        y = (self.x, self.xdot, self.dissipated)
        tau = 0.0
        for _ in range(n):
            k1 = self._rhs(tau, y)
            k2 = self._rhs(tau + h / 2, [a + h / 2 * b for a, b in zip(y, k1)])
            k3 = self._rhs(tau + h / 2, [a + h / 2 * b for a, b in zip(y, k2)])
            k4 = self._rhs(tau + h, [a + h * b for a, b in zip(y, k3)])
            y = tuple(a + h / 6 * (p + 2 * q + 2 * r + s) for a, p, q, r, s in zip(y, k1, k2, k3, k4))
            tau += h
        self.x, self.xdot, self.dissipated = y
        return True
