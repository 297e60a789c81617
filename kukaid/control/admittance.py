"""Admittance control, eqs. (15)-(16): the reference follows  Γr = I σ̈ + D σ̇.

Second-order Taylor discretisation with step Δt (the paper's)::

    σ(k+1)  = σ(k) + (Δt - Δt²/2 · D/I) σ̇(k) + Δt²/(2 I) Γr(k)
    σ̇(k+1) = (1 - Δt D/I) σ̇(k) + Δt/I Γr(k)

σ is the reference angle (rad) sent to the robot's position control, σ̇ its velocity (rad/s).
The continuous system is stable for I > 0 and D > 0; the discrete velocity update additionally
needs |1 - Δt D/I| < 1, i.e. Δt D/I < 2 (checked, also for a damping that changes every step).
A constant torque Γ drives the reference to the steady velocity Γ/D.
"""
from __future__ import annotations

import math

from kukaid.errors import KukaidError


def check_admittance(I: float, D: float, dt: float) -> None:
    """Raise :class:`KukaidError` unless I > 0 kg·m², D > 0 N·m·s/rad, dt > 0 s and dt D/I < 2."""
    for name, v, unit in (("I", I, "kg·m²"), ("D", D, "N·m·s/rad"), ("dt", dt, "s")):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
            raise KukaidError(f"admittance: {name} = {v} {unit} must be a finite number > 0 "
                              f"(the admittance I σ̈ + D σ̇ = Γr is unstable otherwise)")
    if dt * D / I >= 2.0:
        raise KukaidError(f"admittance: dt·D/I = {dt * D / I:.3g} must be < 2 for the discretised admittance to be "
                          f"stable (I = {I} kg·m², D = {D} N·m·s/rad, dt = {dt} s); raise I or lower D")


class Admittance:
    """Discrete admittance (eqs. 15-16) with inertia ``I`` (kg·m²) and damping ``D`` (N·m·s/rad).

    ``step(gamma_r, D=None)`` advances one cycle of ``dt`` s with the torque ``gamma_r`` (N·m) and
    returns the new ``(sigma, sigma_dot)``; ``D`` may change every step (adaptive damping), it is
    then checked against the same stability condition.
    """

    def __init__(self, I: float = 20.0, D: float = 50.0, dt: float = 0.012, sigma0: float = 0.0) -> None:
        check_admittance(I, D, dt)
        self.I, self.D, self.dt = float(I), float(D), float(dt)
        self.reset(sigma0)

    def reset(self, sigma0: float, sigma_dot0: float = 0.0) -> None:
        self.sigma = float(sigma0)
        self.sigma_dot = float(sigma_dot0)

    def step(self, gamma_r: float, D: float | None = None) -> tuple[float, float]:
        h, I = self.dt, self.I
        d = self.D if D is None else float(D)
        if D is not None and not 0.0 < d * h / I < 2.0:  # (not for NaN either) the checks' message
            check_admittance(I, d, h)
        g = float(gamma_r)
        s = self.sigma + (h - 0.5 * h * h * d / I) * self.sigma_dot + 0.5 * h * h / I * g
        sd = (1.0 - h * d / I) * self.sigma_dot + h / I * g
        self.sigma, self.sigma_dot = s, sd
        return s, sd

    def continuous(self, gamma: float, t: float, sigma0: float = 0.0) -> tuple[float, float]:
        """Exact response of I σ̈ + D σ̇ = gamma (constant) from rest at ``sigma0``: (σ(t), σ̇(t))."""
        a = self.D / self.I
        v_inf = gamma / self.D
        sd = v_inf * (1.0 - math.exp(-a * t))
        s = sigma0 + v_inf * (t - (1.0 - math.exp(-a * t)) / a)
        return s, sd
