"""Online stability monitoring of the admittance with a person in the loop.

A stiff grip (co-contraction) closes a loop person -> Γr -> admittance -> robot -> person whose
delays (the 5 Hz estimator filter, the control cycle, the robot's interpolation, the reflexes)
make it oscillate at 1-4 Hz when the admittance's damping is low for the person's stiffness.
Following Dimeas & Aspragathos (2016, "Online stability in human-robot cooperation with
admittance control", IEEE Trans. Haptics 9:267), an **oscillation index** is computed from the
frequency content of the interaction torque Γr: the RMS of its content in the band
[``f_lo``, ``f_hi``] Hz (a causal Butterworth band-pass, scipy-designed, then an exponential
mean square with time constant ``tau_rms``), above what a person's intended guiding torque
(below about 1 Hz) and physiological tremor (8-12 Hz, a few tenths of a N·m, mostly removed by
the estimator's 5 Hz low-pass) contain.

When the index exceeds ``threshold`` N·m the monitor raises a **damping floor** for the
admittance: at once to ``boost`` times the damping in use, and by ``boost`` again every
``step_time`` s while the index stays high, up to ``D_cap``; the floor relaxes back
(time constant ``relax``) once the index has been below half the threshold for ``hold`` s.  The
admittance's inertia I stays constant and D stays > 0, so the variable admittance stays passive
(the energy-tank condition of Ferraguti et al. 2019 is met by construction: the dissipated power
D σ̇² is never negative); the instability addressed here is the delayed coupling with a stiff
arm, which passivity of the admittance alone does not prevent.

Every raise is an event (time, index, new floor, reason) that the loop records.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from kukaid.control.filters import CausalButterworth
from kukaid.errors import KukaidError


@dataclass(frozen=True)
class StabilityConfig:
    """Settings of :class:`OscillationMonitor` (Hz, s, N·m, N·m·s/rad)."""

    enabled: bool = True
    f_lo: float = 1.2
    f_hi: float = 6.0
    tau_rms: float = 0.25
    threshold: float = 4.0
    boost: float = 1.8
    step_time: float = 0.25
    D_cap_factor: float = 10.0
    hold: float = 1.0
    relax: float = 4.0

    def __post_init__(self) -> None:
        ok = (0 < self.f_lo < self.f_hi and self.tau_rms > 0 and self.threshold > 0 and self.boost > 1
              and self.step_time > 0 and self.D_cap_factor >= 1 and self.hold >= 0 and self.relax > 0)
        if not ok:
            raise KukaidError(f"stability monitor: settings out of range: {self}")


class OscillationMonitor:
    """Oscillation index of Γr and the damping floor it sets; :meth:`step` once per control cycle.

    ``cycle`` s: the control cycle; ``D_nominal``: the damping without oscillation; ``D_limit``:
    the largest damping the discretised admittance accepts.
    """

    def __init__(self, config: StabilityConfig, cycle: float, D_nominal: float, D_limit: float) -> None:
        self.config = c = config
        fs = 1.0 / cycle
        hi = min(c.f_hi, 0.45 * fs)
        self._bp = CausalButterworth((c.f_lo, hi), fs, 2, btype="bandpass")
        self.cycle = float(cycle)
        self.D_nominal = float(D_nominal)
        self.D_cap = min(c.D_cap_factor * D_nominal, D_limit)
        self._alpha = min(cycle / c.tau_rms, 1.0)
        self._relax = math.exp(-cycle / c.relax)
        self.reset()

    def reset(self) -> None:
        self._ms = 0.0
        self.index = 0.0
        self.floor = 0.0
        self._t = 0.0
        self._last_raise = -math.inf
        self._quiet = 0.0
        self.active = False
        self.oscillating = False
        self.events: list[dict] = []

    def step(self, gamma_r: float, D_in_use: float) -> float:
        """Feed this cycle's Γr (N·m); returns the damping floor (N·m·s/rad; 0 when inactive)."""
        c = self.config
        self._t += self.cycle
        x = float(gamma_r)
        band = self._bp.step(x)
        self._ms += self._alpha * (band * band - self._ms)
        self.index = math.sqrt(self._ms)
        self.oscillating = self.index > 0.5 * c.threshold
        if not c.enabled:
            return 0.0
        if self.index > c.threshold:
            self._quiet = 0.0
            if not self.active or self._t - self._last_raise >= c.step_time:
                new = min(max(self.floor, D_in_use) * c.boost, self.D_cap)
                if new > self.floor + 1e-9:
                    self.events.append({"time": self._t, "index": self.index, "D_floor": new,
                                        "reason": (f"oscillation index {self.index:.2f} N·m > {c.threshold:g} N·m "
                                                   f"({c.f_lo:g}-{c.f_hi:g} Hz content of Γr): damping floor "
                                                   f"{new:.0f} N·m·s/rad")})
                    self.floor = new
                self._last_raise = self._t
                self.active = True
        else:
            if self.index < 0.5 * c.threshold:
                self._quiet += self.cycle
            if self._quiet >= c.hold:
                self.floor *= self._relax
                if self.floor < self.D_nominal * 1.01:
                    self.floor = 0.0
                    self.active = False
        return self.floor
