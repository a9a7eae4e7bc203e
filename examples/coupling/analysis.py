"""Post-processing of coupled runs (numpy only): modal frequencies of a free-vibration record
(matrix pencil), observed convergence orders, energy drift."""
import math

import numpy as np


def modal_frequencies(t: np.ndarray, y: np.ndarray, modes: int = 4) -> list[tuple[float, float]]:
    """Frequencies (Hz) and amplitudes of the `modes` damped sinusoids (plus a constant) that best
    describe a uniformly sampled record (matrix pencil method), sorted by frequency."""
    dt = t[1] - t[0]
    if not np.allclose(np.diff(t), dt, rtol=1e-6):
        raise ValueError("modal_frequencies needs a uniformly sampled record")
    y = np.asarray(y, float)
    if not np.all(np.isfinite(y)):  # LAPACK's SVD may not return on NaN
        raise ValueError("modal_frequencies: non-finite samples")
    n = len(y)
    L = n // 3
    Y = np.array([y[i:i + L + 1] for i in range(n - L)])
    _, _, vh = np.linalg.svd(Y, full_matrices=False)
    M = 2 * modes + 1
    v = vh[:M].T
    z = np.linalg.eigvals(np.linalg.pinv(v[:-1]) @ v[1:])
    # keep poles that change by less than e^5 over the record (free vibration, slow drift); the
    # others are noise and would overflow the Vandermonde basis
    z = z[np.abs(np.log(np.abs(z) + 1e-300)) < 5.0 / n]
    # amplitudes by least squares on the Vandermonde basis
    V = np.power.outer(z, np.arange(n)).T
    amp = np.abs(np.linalg.lstsq(V, y.astype(complex), rcond=None)[0])
    out = {}
    for zi, a in zip(z, amp):
        f = abs(np.angle(zi)) / (2 * math.pi * dt)
        if f > 1e-6:
            key = round(f, 6)
            out[key] = out.get(key, 0.0) + a
    return sorted(out.items())


def lowest_frequency(t: np.ndarray, y: np.ndarray, modes: int = 4, share: float = 0.05) -> float:
    """Lowest frequency (Hz) whose amplitude is at least `share` of the largest in the record."""
    fa = modal_frequencies(t, y, modes)
    top = max(a for _, a in fa)
    return min(f for f, a in fa if a >= share * top)


def orders(steps: list[float], values: list[np.ndarray]) -> tuple[list[float], list[float]]:
    """Differences between successive halvings (max norm over the common samples) and the observed
    orders log2(d_k / d_k+1), for results at steps H, H/2, H/4, ..."""
    d = [float(np.abs(a - b).max()) for a, b in zip(values, values[1:])]
    return d, [math.log2(d[i] / d[i + 1]) for i in range(len(d) - 1)]


def energy_drift(e: np.ndarray) -> float:
    """Largest relative deviation of an energy record from its first value."""
    return float(np.abs(e - e[0]).max() / abs(e[0]))
