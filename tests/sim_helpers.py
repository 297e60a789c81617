"""Tiny commanded trajectories for the simulator tests (duck-typed: .t, .q, .kind, .params)."""
from __future__ import annotations

import types

import numpy as np

IPO = 0.012


class Builder:
    """Append smooth segments to a commanded position schedule at the IPO rate."""

    def __init__(self, q0: float = 0.0) -> None:
        self.t = [0.0]
        self.q = [q0]

    def hold(self, T: float) -> "Builder":
        n = int(round(T / IPO))
        for _ in range(n):
            self.t.append(self.t[-1] + IPO)
            self.q.append(self.q[-1])
        return self

    def move(self, v: float, plateau: float, ramp: float = 0.3) -> "Builder":
        """Accelerate to v (rad/s, signed) with a raised-cosine velocity ramp, cruise, stop."""
        def vel(tau: float) -> float:
            if tau < ramp:
                return v * 0.5 * (1 - np.cos(np.pi * tau / ramp))
            if tau < ramp + plateau:
                return v
            if tau < 2 * ramp + plateau:
                x = tau - ramp - plateau
                return v * 0.5 * (1 + np.cos(np.pi * x / ramp))
            return 0.0

        total = 2 * ramp + plateau
        n = int(round(total / IPO))
        fine = 20
        q = self.q[-1]
        for i in range(n):
            for j in range(fine):
                tau = (i + (j + 0.5) / fine) * IPO
                q += vel(tau) * IPO / fine
            self.t.append(self.t[-1] + IPO)
            self.q.append(q)
        return self

    def build(self, kind: str = "friction") -> types.SimpleNamespace:
        return types.SimpleNamespace(t=np.array(self.t), q=np.array(self.q), kind=kind, params={"test": True})
