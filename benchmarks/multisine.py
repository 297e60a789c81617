"""A random multi-sine joint motion for the benchmarks' independent log generators (not kukaid.sim)."""
from __future__ import annotations

import numpy as np


def multisine(rng: np.random.Generator, t: np.ndarray, q0: tuple[float, float], f: tuple[float, float],
              a: tuple[float, float], n: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """q, qd, qdd of a start position drawn from ``q0`` plus ``n`` sines (frequency Hz from ``f``,
    amplitude rad from ``a``, random phase), drawn from ``rng`` in that order."""
    q = np.full(t.size, rng.uniform(*q0))
    qd = np.zeros(t.size)
    qdd = np.zeros(t.size)
    for _ in range(n):
        fk, ak, ph = rng.uniform(*f), rng.uniform(*a), rng.uniform(0, 2 * np.pi)
        w = 2 * np.pi * fk
        q += ak * np.sin(w * t + ph)
        qd += ak * w * np.cos(w * t + ph)
        qdd -= ak * w * w * np.sin(w * t + ph)
    return q, qd, qdd
