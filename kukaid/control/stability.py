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

With ``raise_rule="decay"`` (an option of the adaptive law, :class:`CouplingConfig`
``monitor_rule``) the floor is not doubled: once per half-cycle, from the envelope of the last two
half-cycles (their peaks A1, A2, t_h apart, while the damping was D), the mode's decay rate
σ = ln(A1 / A2) / t_h is measured and the floor set to D + 2 I (σ* − σ), the damping that gives
it the target decay σ* = max(ζ ω, ln(A2 / ``threshold``) / ``settle``) (ω = π / t_h: damping ratio
``zeta``, and down to the threshold within ``settle`` s); a mode already decaying that fast gets
no raise.  Near the coupled mode the loop is I s² + (D − D_loss) s + K_eff ≈ 0 whatever the
grip's stiffness, the delays and the arm's own damping are, so its envelope decays at
(D − D_loss) / 2I: the raise needs neither K nor the delay.

Every raise is an event (time, index, new floor, reason) that the loop records.

:class:`CouplingFloor` is the adaptive law's own floor: it estimates the grip's stiffness from
the first rebound of the coupled mode and keeps the damping above the delayed loop's stability
limit for it (:func:`critical_damping`), one half-cycle before the monitor would act.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

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
    raise_rule: str = "double"
    zeta: float = 0.2
    settle: float = 1.0

    def __post_init__(self) -> None:
        ok = (0 < self.f_lo < self.f_hi and self.tau_rms > 0 and self.threshold > 0 and self.boost > 1
              and self.raise_rule in ("double", "decay") and self.zeta >= 0 and self.settle > 0
              and isinstance(self.lobes, int) and self.lobes >= 2 and self.max_half_period > 0
              and self.step_time > 0 and self.D_cap_factor >= 1 and self.hold >= 0 and self.relax > 0)
        if not ok:
            raise KukaidError(f"stability monitor: settings out of range: {self}")


class OscillationMonitor:
    """Oscillation index of Γr and the damping floor it sets; :meth:`step` once per control cycle.

    ``cycle`` s: the control cycle; ``D_nominal``: the damping without oscillation; ``D_limit``:
    the largest damping the discretised admittance accepts; ``I``: the admittance's inertia
    (kg·m², needed by the decay rule).
    """

    def __init__(self, config: StabilityConfig, cycle: float, D_nominal: float, D_limit: float,
                 I: float | None = None) -> None:
        self.config = c = config
        if c.raise_rule == "decay" and not (I is not None and I > 0):
            raise KukaidError("stability monitor: the decay rule needs the admittance's inertia I > 0")
        self.I = float(I) if I is not None else math.nan
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
        self._halves: list[tuple[float, float, float]] = []  # (peak, duration, mean D) of the last two
        self._D_sum = 0.0
        self._n = 0
        self._evaluated = False  # the decay rule has acted on the half-cycle under way

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
        self._D_sum += D_in_use
        self._n += 1
        if sg != self._sign:
            dur = self._t - self._t_cross
            short = dur <= c.max_half_period
            self._big = self._big + 1 if (self._peak > c.threshold and short) else 0
            self._halves = (self._halves + [(self._peak, dur, self._D_sum / self._n)])[-2:]
            self._sign, self._peak, self._t_cross = sg, 0.0, self._t
            self._D_sum, self._n, self._evaluated = 0.0, 0, False
        self._peak = max(self._peak, abs(band))
        if self._t - self._t_cross > c.max_half_period:
            self._big = 0
        alternating = self._big >= c.lobes - 1 and self._peak > c.threshold
        self.oscillating = alternating or self._big >= 1
        if not c.enabled:
            return 0.0
        if alternating and c.raise_rule == "decay":
            self._quiet = 0.0
            self.active = True
            if not self._evaluated:  # once per half-cycle, from the two before it
                self._evaluated = True
                new, why = self._decay_floor()
                if new > max(self.floor, D_in_use) + 1e-9:  # a raise above the damping in use
                    self.floor = new
                    self.events.append({"time": self._t, "index": self.index, "D_floor": new, "reason": why})
                self._last_raise = self._t
        elif alternating:
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

    def _decay_floor(self) -> tuple[float, str]:
        """The damping that gives the ringing mode its target decay rate, from the envelope of the
        last two half-cycles (see the module's docstring), and the reason to log."""
        c = self.config
        (a1, t1, _), (a2, t2, d2) = self._halves
        th = 0.5 * (t1 + t2)
        w = math.pi / th
        sigma = math.log(max(a1, 1e-9) / max(a2, 1e-9)) / th
        target = max(c.zeta * w, math.log(max(a2 / c.threshold, 1.0)) / c.settle)
        need = min(d2 + 2.0 * self.I * (target - sigma), self.D_cap)
        why = (f"oscillation: {self._big + 1} alternating half-cycles of Γr's {c.f_lo:g}-{c.f_hi:g} Hz content beyond "
               f"{c.threshold:g} N·m at {w / (2 * math.pi):.2f} Hz, envelope {'growing' if sigma < 0 else 'decaying'} "
               f"at {abs(sigma):.2f}/s with D {d2:.0f}: damping floor {need:.0f} N·m·s/rad for a decay of "
               f"{target:.2f}/s")
        return need, why


def critical_damping(K: float, I: float, T: float) -> float:
    """The damping below which the admittance I σ̈ + D σ̇ = Γ, reached by a spring K through the
    loop delay T, oscillates with growing amplitude (N·m·s/rad).

    The coupled loop's characteristic equation is I s² + D s + K e^{-sT} = 0; on the stability
    boundary s = jω: K cos ωT = I ω² and D = K sin(ωT) / ω (for small ωT, D ≈ K T: a stiffer arm
    or a longer delay needs proportionally more damping).  ω is found by bisection on (0, π/2T).
    """
    if K <= 0 or T <= 0:
        return 0.0
    lo, hi = 0.0, 0.5 * math.pi / T
    for _ in range(40):
        w = 0.5 * (lo + hi)
        if K * math.cos(w * T) > I * w * w:
            lo = w
        else:
            hi = w
    w = 0.5 * (lo + hi)
    return K * math.sin(w * T) / w


def probe_time(D: float, I: float, T: float) -> float:
    """One period (s) of the slowest coupled mode that the damping D cannot hold: the grip
    stiffness K_D with critical_damping(K_D, I, T) = D rings at ω with K_D cos ωT = I ω²; any
    stiffer grip rings faster, so a rebound shows within this time of a contact's start.

    On the boundary K = I ω² / cos ωT and D = K sin(ωT) / ω, so ω is the root of I ω tan(ωT) = D
    on (0, π/2T) (increasing in ω: one bisection, no search over K)."""
    a, b = 0.0, 0.5 * math.pi / T
    for _ in range(60):
        w = 0.5 * (a + b)
        a, b = (w, b) if I * w * math.tan(w * T) < D else (a, w)
    return 2.0 * math.pi / max(0.5 * (a + b), 1e-6)


@dataclass(frozen=True)
class CouplingConfig:
    """Settings of :class:`CouplingFloor` (Hz, s, N·m); ``monitor_lobes`` and ``monitor_rule`` set
    the stability monitor that backs it up in the adaptive loop (``monitor_rule``: "double" or
    "decay", :class:`StabilityConfig` ``raise_rule``; the monitor's damping ratio is ``zeta``)."""

    enabled: bool = True
    f_lo: float = 0.6
    f_hi: float = 6.0
    threshold: float = 4.0
    max_half_period: float = 0.8
    zeta: float = 0.2
    relax: float = 4.0
    hold: float = 1.0
    escalate: float = 1.3
    monitor_lobes: int = 4
    monitor_rule: str = "double"
    probe: bool = True

    def __post_init__(self) -> None:
        ok = (0 < self.f_lo < self.f_hi and self.threshold > 0 and self.max_half_period > 0 and self.zeta >= 0
              and self.escalate >= 1 and self.monitor_lobes >= 2 and self.monitor_rule in ("double", "decay")
              and self.relax > 0 and self.hold >= 0)
        if not ok:
            raise KukaidError(f"coupling floor: settings out of range: {self}")


class CouplingFloor:
    """The adaptive law's damping floor from the stiffness of the person's grip, estimated online
    from the interaction's own ringing; :meth:`step` once per control cycle.

    Physics.  Around the intended motion the arm is a spring K (plus damping and the hand's
    inertia); holding the link couples it to the admittance I σ̈ + D σ̇ = Γr, which reaches the
    arm only after the loop's delay T (the estimator's low-pass, the control cycle, the robot's
    interpolation and position loop).  The coupled mode rings at ω ≈ sqrt(K / I) and is unstable
    once D < D_crit(K, T) (:func:`critical_damping`, ≈ K T): a firm grip (K up to ~1200 N·m/rad)
    with I = 20 kg·m² and T ≈ 0.1 s needs D ≈ 120 N·m·s/rad whatever an RBF network wants, a soft
    one (K ≈ 100) only ≈ 10.  Neither K nor T are known in advance:

    * K: as soon as Γr's band-passed content ([``f_lo``, ``f_hi``] Hz, above a person's guiding
      motion) makes two successive half-cycles beyond ``threshold`` N·m, each shorter than
      ``max_half_period`` s (a push and its rebound: the mode ringing; the stability monitor waits
      for three and then doubles the damping), their mean half-period t_h gives ω = π / t_h and
      K_est = I ω² (the largest seen during the contact is kept: stiffness only rises with
      co-contraction while the grip lasts);
    * T: the filter's delay at ω (its phase / ω, exact from its coefficients), plus one control
      cycle (Γr of cycle k moves the reference of cycle k+1), plus the robot's lag behind its
      reference, measured online from the sent reference and the measured position while the
      axis moves (so a slower robot behind KUKAVARPROXY gets a larger floor).

    The floor is D_crit(K_est, T) + 2 ``zeta`` sqrt(K_est I) (a margin of damping ratio
    ``zeta`` on top of the stability limit), kept while the contact lasts and relaxed (``relax``
    s) once the person has let go for ``hold`` s.  If the mode still rings a period after the
    floor is in use, the loop is slower than estimated: T is taken ``escalate`` times longer.
    With ``probe``, a new contact first keeps the damping D0 (ramping down to nothing) for
    :func:`probe_time`: one period of the slowest mode D0 cannot hold, the time within which any
    grip too stiff for D0 shows its rebound, so the network does not lower the damping under a
    firm grip before its stiffness can be seen.  A soft grip never rings, so after that the
    network keeps lowering the damping for it.
    """

    def __init__(self, config: CouplingConfig, cycle: float, I: float, D_cap: float,
                 filter_delay: Callable[[float], float] | None = None, D0: float = 50.0) -> None:
        self.D0 = float(D0)
        self.config = c = config
        fs = 1.0 / cycle
        hi = min(c.f_hi, 0.45 * fs)
        self._bp = CausalButterworth((c.f_lo, hi), fs, 2, btype="bandpass")
        self.cycle, self.I, self.D_cap = float(cycle), float(I), float(D_cap)
        self._filter_delay = filter_delay or (lambda w: 0.0)
        self._relax = math.exp(-cycle / c.relax)
        self.reset()

    def reset(self) -> None:
        self.floor = 0.0
        self.K_est = 0.0
        self.T_est = math.nan
        self.events: list[dict] = []
        self._t = 0.0
        self._sign = 0.0
        self._peak = 0.0
        self._t_cross = 0.0
        self._halves: list[float] = []
        self._lag_num = 0.0
        self._lag_den = 0.0
        self._q_prev: float | None = None
        self._quiet = 0.0
        self._T_gain = 1.0
        self._t_first = -math.inf
        self._contact = 0.0
        self.probe_time = 0.0

    @property
    def robot_lag(self) -> float:
        """The robot's measured lag behind the sent reference, s (0 until it has moved)."""
        return min(max(self._lag_num / self._lag_den, 0.0), 0.3) if self._lag_den > 0 else 0.0

    def observe_robot(self, q_sent: float, q: float) -> None:
        """Feed the reference sent last cycle and the position measured since (rad), for the lag."""
        if self._q_prev is not None:
            v = (q - self._q_prev) / self.cycle
            if abs(v) > 0.02:  # moving: (reference - position) ≈ lag · velocity
                a = min(self.cycle / 2.0, 1.0)
                self._lag_num += a * ((q_sent - q) * v - self._lag_num)
                self._lag_den += a * (v * v - self._lag_den)
        self._q_prev = q

    def step(self, gamma_r: float, contact: bool, D_in_use: float = 0.0) -> float:
        """Feed this cycle's Γr (N·m), whether a person is in contact and the damping used in the
        last cycle (N·m·s/rad); returns the floor (N·m·s/rad, 0 when inactive)."""
        c = self.config
        self._t += self.cycle
        band = self._bp.step(gamma_r)
        sg = 1.0 if band > 0 else -1.0 if band < 0 else self._sign
        if sg != self._sign:
            dur = self._t - self._t_cross
            if self._peak > c.threshold and dur <= c.max_half_period:
                self._halves = (self._halves + [dur])[-2:]
            else:
                self._halves = []
            self._sign, self._peak, self._t_cross = sg, 0.0, self._t
            if contact and len(self._halves) == 2 and c.enabled:
                self._raise(math.pi / (0.5 * sum(self._halves)), D_in_use)
        self._peak = max(self._peak, abs(band))
        if contact:
            self._contact += self.cycle
            self._quiet = 0.0
        else:
            self._quiet += self.cycle
            if self._quiet >= c.hold:
                self._contact = 0.0
                self.floor *= self._relax
                if self.floor < 1.0:
                    self.floor, self.K_est, self._T_gain = 0.0, 0.0, 1.0
        if not c.enabled:
            return 0.0
        if c.probe and contact:
            if self._contact <= self.cycle:  # a new contact: how long a rebound would take to show
                T = self._filter_delay(3.0) + self.cycle + self.robot_lag
                self.probe_time = probe_time(self.D0, self.I, T)
            if self._contact < self.probe_time:
                return max(self.floor, self.D0 * (1.0 - self._contact / self.probe_time))
        return self.floor

    def _raise(self, w: float, D_in_use: float) -> None:
        """A pair of half-cycles at ω rad/s: raise the floor to what the stiffness they show needs;
        if the mode still rings a period after the floor was set and in use, the loop is slower
        than estimated: assume ``escalate`` times its delay."""
        c = self.config
        persists = (self.floor > 0 and D_in_use >= 0.99 * self.floor
                    and self._t - self._t_first >= 2.0 * math.pi / w)
        if persists:
            self._T_gain *= c.escalate
        T = (self._filter_delay(w) + self.cycle + self.robot_lag) * self._T_gain
        K = self.I * w * w
        K /= max(math.cos(min(w * T, 1.4)), 0.17)  # the delayed loop rings below sqrt(K/I): K cos ωT = I ω²
        if K <= self.K_est and not persists:
            return
        self.K_est, self.T_est = max(K, self.K_est), T
        new = min(critical_damping(self.K_est, self.I, T) + 2.0 * c.zeta * math.sqrt(self.K_est * self.I),
                  self.D_cap)
        if new > self.floor + 1e-9:
            if self.floor == 0.0:
                self._t_first = self._t
            self.floor = new
            why = (f"still ringing at {self.floor:.0f}: loop delay taken as {1000 * T:.0f} ms" if persists else
                   f"loop delay {1000 * T:.0f} ms")
            self.events.append({"time": self._t, "index": self.K_est, "D_floor": new,
                                "reason": (f"coupled mode at {w / (2 * math.pi):.2f} Hz: grip stiffness about "
                                           f"{self.K_est:.0f} N·m/rad, {why}: damping floor {new:.0f} N·m·s/rad")})


class StickSlipWatch:
    """A stick-slip cycle with nobody there: the loop's own stop read as a push back.

    On a plant whose friction at a stop is not what the parameter file says (a breakaway well above
    the file's, friction that grows as the axis sticks), the torque as the axis stops reads as a push
    against the way it moved; detected, it drives the axis back, and the next stop does the same: a
    cycle of a few tenths of a degree every 0.3-0.6 s that goes on with nobody there (gms-sensor
    seed 4 with a breakaway 1.6 x its Coulomb friction, the file's 1.1 x: 1344 detected cycles in
    30 s).  A person may push back just after a stop too, but not ``starts`` times in a row, each
    within ``gap`` s of the last.

    :meth:`step`, once per control cycle of the admittance, counts detections that start against
    the way the reference last moved, within ``stand_window`` s of it standing.  ``starts`` in a row
    are a cycle: the first time, the start threshold at a stop is raised to the largest |Γr| those
    detections read (``margin``, at most ``cap``: the estimator's
    :attr:`~kukaid.control.torque_residual.TorqueResidual.cycle_margin`); a cycle after that stops
    the run (:attr:`stop` says why)."""

    def __init__(self, cycle: float, cap: float, starts: int = 3, stand_window: float = 0.3,
                 gap: float = 1.5) -> None:
        self.cycle, self.cap = float(cycle), float(cap)
        self.starts, self.stand_window, self.gap = int(starts), float(stand_window), float(gap)
        self.margin = 0.0
        self.stop: str | None = None
        self._t = 0.0
        self._dir = 0.0  # the way the reference last moved
        self._standing = math.inf  # s the reference has stood (inf: never moved)
        self._last = -math.inf  # when the last detection started, s
        self._n = 0  # reversals at a stand in a row
        self._peak = 0.0  # the largest |Γr| since the first of them, N·m
        self._was = False

    def step(self, sigma_dot: float, detected: bool, gamma_r: float) -> float:
        """This cycle's reference speed (before the step), detection and Γr; returns the margin, N·m."""
        self._t += self.cycle
        if detected and not self._was:
            reversal = (sigma_dot == 0.0 and self._standing <= self.stand_window
                        and gamma_r * self._dir < 0.0)
            self._n = self._n + 1 if reversal and self._t - self._last <= self.gap else int(reversal)
            if self._n == 1:
                self._peak = 0.0
            self._last = self._t
        self._was = detected
        if self._n:
            self._peak = max(self._peak, abs(gamma_r))
        if sigma_dot != 0.0:
            self._dir, self._standing = math.copysign(1.0, sigma_dot), 0.0
        else:
            self._standing += self.cycle
        if self._n >= self.starts:
            self._n = 0
            if self.margin > 0.0:
                self.stop = (f"a stick-slip cycle with nobody there: {self.starts} detections in a row started "
                             f"against the reference's last motion within {self.stand_window:g} s of it standing "
                             f"(up to {self._peak:.3g} N·m), again after the start threshold at a stop was raised to "
                             f"{self.margin:.3g} N·m: the parameter file's friction at a stop is not this axis's "
                             "(refit it on a recent log: kukaid fit ... --presliding LOG)")
            else:
                self.margin = min(self._peak, self.cap)
        return self.margin
