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

An oscillation is declared when ``lobes`` successive half-cycles of the band-passed Γr, each
shorter than ``max_half_period`` s, peak beyond ``threshold`` N·m (an alternating torque: a quick
push or a firm grasp, a step of the torque, gives one or two lobes and is not an oscillation).
The monitor then raises a **damping floor** for the
admittance: at once to ``boost`` times the damping in use, and by ``boost`` again every
``step_time`` s while the index stays high, up to ``D_cap``; the floor is kept while the contact
lasts and relaxes back (time constant ``relax``) once the person has let go and the index has
been below half the threshold for ``hold`` s.  The
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
    f_lo: float = 0.6
    f_hi: float = 6.0
    tau_rms: float = 0.15
    threshold: float = 4.0
    lobes: int = 3
    max_half_period: float = 0.8
    boost: float = 2.0
    step_time: float = 0.15
    D_cap_factor: float = 10.0
    hold: float = 1.0
    relax: float = 4.0

    def __post_init__(self) -> None:
        ok = (0 < self.f_lo < self.f_hi and self.tau_rms > 0 and self.threshold > 0 and self.boost > 1
              and isinstance(self.lobes, int) and self.lobes >= 2 and self.max_half_period > 0
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
        self._sign = 0.0
        self._peak = 0.0
        self._t_cross = 0.0
        self._big = 0  # consecutive completed half-cycles beyond the threshold, each short enough

    def step(self, gamma_r: float, D_in_use: float, contact: bool = False) -> float:
        """Feed this cycle's Γr (N·m) and whether a person is in contact (detection); returns the
        damping floor (N·m·s/rad; 0 when inactive).  The floor is kept while the contact lasts
        (the grip that oscillated is still there) and relaxes only once it has ended."""
        c = self.config
        self._t += self.cycle
        x = float(gamma_r)
        band = self._bp.step(x)
        self._ms += self._alpha * (band * band - self._ms)
        self.index = math.sqrt(self._ms)
        # half-cycles of the band-passed torque: an oscillation alternates, a quick push (a step
        # of the torque) gives one or two lobes only
        sg = 1.0 if band > 0 else -1.0 if band < 0 else self._sign
        if sg != self._sign:
            short = self._t - self._t_cross <= c.max_half_period
            self._big = self._big + 1 if (self._peak > c.threshold and short) else 0
            self._sign, self._peak, self._t_cross = sg, 0.0, self._t
        self._peak = max(self._peak, abs(band))
        if self._t - self._t_cross > c.max_half_period:
            self._big = 0
        alternating = self._big >= c.lobes - 1 and self._peak > c.threshold
        self.oscillating = alternating or self._big >= 1
        if not c.enabled:
            return 0.0
        if alternating:
            self._quiet = 0.0
            if not self.active or self._t - self._last_raise >= c.step_time:
                new = min(max(self.floor, D_in_use) * c.boost, self.D_cap)
                if new > self.floor + 1e-9:
                    self.events.append({"time": self._t, "index": self.index, "D_floor": new,
                                        "reason": (f"oscillation: {self._big + 1} alternating half-cycles of Γr's "
                                                   f"{c.f_lo:g}-{c.f_hi:g} Hz content beyond {c.threshold:g} N·m "
                                                   f"(index {self.index:.1f} N·m): damping floor "
                                                   f"{new:.0f} N·m·s/rad")})
                    self.floor = new
                self._last_raise = self._t
                self.active = True
        else:
            if not self.oscillating:
                self._quiet += self.cycle
            if self._quiet >= c.hold and not contact:
                self.floor *= self._relax
                if self.floor < self.D_nominal * 1.01:
                    self.floor = 0.0
                    self.active = False
        return self.floor
