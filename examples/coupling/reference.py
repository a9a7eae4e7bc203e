"""Independent references for the coupled cantilever + payload (numpy only).

* Timoshenko beam theory (plane strain: E' = E / (1 - nu^2), G = E / (2 (1 + nu)), shear
  correction 5/6) for the static deflection under a point load.
* A Timoshenko beam finite-element model (exact two-node Timoshenko stiffness, consistent
  translational mass, consistent rotary inertia) of the same cantilever with the payload's spring
  and mass attached where the load region is, for the coupled frequencies; and the 2-DOF model
  (the beam's first mode as a modal oscillator, effective mass k_tip / omega_1^2, on the payload's
  spring and mass).

All per metre of depth (2D). The load region is the last column of particles, at a = L - dp / 2.
"""
import json
import math
from dataclasses import dataclass

import numpy as np

KAPPA = 5.0 / 6.0


@dataclass
class Beam:
    """Plane-strain cantilever of length L, height h, per metre of depth; load at x = a."""

    length: float
    height: float
    density: float
    young: float
    poisson: float
    a: float

    @classmethod
    def from_scene(cls, path: str, load: str = "tip") -> "Beam":
        s = json.load(open(path))
        mat = s["bodies"][0]["material"]
        box = s["bodies"][0]["boxes"][0]
        dp = s["particle_spacing"]
        reg = next(r for r in s["loads"] if r["name"] == load)["region"]
        # the load region's particles are at cell centres: its mean x
        a = 0.5 * (reg["min"][0] + reg["max"][0])
        return cls(box["max"][0] - box["min"][0], box["max"][1] - box["min"][1], mat["density"],
                   mat["young"], mat["poisson"], a if load == "tip" else box["max"][0] - 0.5 * dp)

    @property
    def e_plane(self) -> float:
        return self.young / (1.0 - self.poisson**2)

    @property
    def shear(self) -> float:
        return self.young / (2.0 * (1.0 + self.poisson))

    @property
    def inertia(self) -> float:
        return self.height**3 / 12.0

    def tip_deflection(self, force: float) -> float:
        """Timoshenko deflection at x = a under a point load `force` at x = a (m)."""
        a = self.a
        return force * a**3 / (3 * self.e_plane * self.inertia) + force * a / (KAPPA * self.shear * self.height)

    def fe(self, elements: int = 120, payload_mass: float = 0.0, spring: float = 0.0):
        """Stiffness and mass matrices of the Timoshenko FE model, clamped at x = 0; with a payload
        (mass, spring to the node at x = a) as the last DOF when payload_mass > 0. Returns
        (K, M, index of the w DOF at x = a)."""
        xs = list(np.linspace(0.0, self.a, elements + 1))
        if self.length - self.a > 1e-12:
            xs.append(self.length)
        nn = len(xs)
        nd = 2 * nn + (1 if payload_mass > 0 else 0)
        K = np.zeros((nd, nd))
        M = np.zeros((nd, nd))
        ei, rho_a, rho_i = self.e_plane * self.inertia, self.density * self.height, self.density * self.inertia
        for e in range(nn - 1):
            l = xs[e + 1] - xs[e]
            phi = 12 * ei / (KAPPA * self.shear * self.height * l * l)
            k = ei / ((1 + phi) * l**3) * np.array([
                [12, 6 * l, -12, 6 * l],
                [6 * l, (4 + phi) * l * l, -6 * l, (2 - phi) * l * l],
                [-12, -6 * l, 12, -6 * l],
                [6 * l, (2 - phi) * l * l, -6 * l, (4 + phi) * l * l]])
            m = rho_a * l / 420 * np.array([
                [156, 22 * l, 54, -13 * l],
                [22 * l, 4 * l * l, 13 * l, -3 * l * l],
                [54, 13 * l, 156, -22 * l],
                [-13 * l, -3 * l * l, -22 * l, 4 * l * l]])
            m[np.ix_([1, 3], [1, 3])] += rho_i * l / 6 * np.array([[2, 1], [1, 2]])
            idx = [2 * e, 2 * e + 1, 2 * e + 2, 2 * e + 3]
            K[np.ix_(idx, idx)] += k
            M[np.ix_(idx, idx)] += m
        ia = 2 * elements
        if payload_mass > 0:
            p = nd - 1
            K[np.ix_([ia, p], [ia, p])] += spring * np.array([[1, -1], [-1, 1]])
            M[p, p] += payload_mass
        keep = list(range(2, nd))  # clamp: w = theta = 0 at x = 0
        return K[np.ix_(keep, keep)], M[np.ix_(keep, keep)], ia - 2

    def frequencies(self, payload_mass: float = 0.0, spring: float = 0.0, count: int = 3) -> np.ndarray:
        """Lowest natural frequencies (Hz) of the beam (with the payload if payload_mass > 0)."""
        K, M, _ = self.fe(payload_mass=payload_mass, spring=spring)
        L = np.linalg.cholesky(M)
        Li = np.linalg.inv(L)
        w2 = np.linalg.eigvalsh(Li @ K @ Li.T)
        return np.sqrt(np.abs(w2[:count])) / (2 * math.pi)

    def fe_tip_deflection(self, force: float) -> float:
        K, _, ia = self.fe()
        f = np.zeros(K.shape[0])
        f[ia] = force
        return float(np.linalg.solve(K, f)[ia])


def two_dof_frequencies(k_beam: float, f_beam: float, mass: float, spring: float) -> np.ndarray:
    """Frequencies (Hz) of the beam's first mode as a modal oscillator (stiffness k_beam at the load
    point, frequency f_beam, so effective mass k_beam / omega^2) carrying the payload (mass, spring)."""
    m1 = k_beam / (2 * math.pi * f_beam) ** 2
    K = np.array([[k_beam + spring, -spring], [-spring, spring]])
    M = np.diag([m1, mass])
    w2 = np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real)
    return np.sqrt(w2) / (2 * math.pi)


if __name__ == "__main__":
    b = Beam.from_scene("scenes/cantilever_payload.json")
    print(b)
    print("tip deflection under 1 kN/m: Timoshenko", b.tip_deflection(1000.0), "FE", b.fe_tip_deflection(1000.0))
    print("beam frequencies (Hz)", b.frequencies())
    print("beam + payload m 10 k 4e4 (Hz)", b.frequencies(10.0, 4.0e4))
    kb = 1000.0 / b.tip_deflection(1000.0)
    print("2-DOF", two_dof_frequencies(kb, b.frequencies()[0], 10.0, 4.0e4))
