"""A simulated human arm guiding the link: the default operator of the admittance experiments.

The person grasps the link, intends a point-to-point move (minimum jerk, Flash & Hogan 1985) and
acts on the link through the arm's impedance around that intended motion::

    tau_h = g(t) [ K(t) (x_d - q) + B (xd_d - qd) - I_h qdd ] + tremor + signal-dependent noise

evaluated once per KRC sample (12 ms) by :meth:`kukaid.sim.VirtualKRC4.set_external_torque`
(``fn(t, q, qd)``, positive torque towards positive q), with ``g`` the grip (0 -> 1 at the grasp,
1 -> 0 at the release).  On the six-axis simulator (every 4 ms sample) the hand's inertia term is
the simulator's: it carries ``g I_h`` with the link (see :class:`HumanArm`, ``plant_inertia``).  Axis-level values are the hand's endpoint values times r² (r the lever
from the axis to the hand, 0.45-0.75 m on a KR 6's forearm).  Ranges and their sources:

* endpoint stiffness of the relaxed arm holding a posture 100-600 N/m (Mussa-Ivaldi, Hogan &
  Bizzi 1985, J. Neurosci. 5:2732; Tsuji et al. 1995, Biol. Cybern. 72:475), rising about
  linearly with the force the arm exerts and several-fold with co-contraction, to 2000-3000 N/m
  (Gomi & Osu 1998, J. Neurosci. 18:8965; Perreault, Kirsch & Crago 2001, Exp. Brain Res.
  141:312).  At the axis: soft grips K0 60-150 N·m/rad, ordinary 150-300, firm 300-500, rising
  with effort to K_max (up to 1200 N·m/rad for firm grips, the upper end of the cited endpoint
  stiffness at r ≈ 0.7 m);
* damping ratio of the hand 0.2-0.5 of critical for its own mass (Tsuji et al. 1995: viscosity
  5-50 N·s/m with mass 1-3 kg and the stiffness above); hand and forearm mass moving with the
  link 1-3 kg (Tsuji et al. 1995; Dolan, Friedman & Nagurka 1993, IEEE SMC 23:698);
* reflex part of the stiffness (about a third) acts with the long-latency stretch reflex delay of
  30-60 ms; voluntary reactions (a change of plan, letting go) take 150-250 ms (Hogan 1984;
  Kandel, Principles of Neural Science, ch. 35);
* physiological tremor 8-12 Hz, a few tenths of a N·m at the hand (Elble & Koller 1990, Tremor);
* signal-dependent motor noise, standard deviation 2-5 % of the exerted torque (Harris &
  Wolpert 1998, Nature 394:780; Jones, Hamilton & Wolpert 2002, J. Neurophysiol. 88:1533);
* some people change their mind mid-move: a second minimum-jerk segment superimposed on the
  first after a reaction time (Flash & Henis 1991, J. Cogn. Neurosci. 3:220);
* hand forces up to 60-120 N (a comfortable guiding force; ISO/TS 15066's 140 N transient limit
  at the hand is above it).

The person lets go only when the link is on target (within max(0.01 rad, 5 % of the move)) and
slow (|qd| < 0.02 rad/s) for a dwell time, or after a timeout; the decision comes a reaction time
after the state that prompted it.

:func:`make_human` draws one person from a seed (the same seed is the same person and the same
noise for every controller: paired comparisons).  The arm is stateful (delays, filters, noise):
use a fresh one (or :meth:`HumanArm.reset`) for every run.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from kukaid.errors import KukaidError

GRIPS = ("soft", "ordinary", "firm")
#: axis stiffness ranges (N·m/rad): base K0 and K_max reached with co-contraction, per grip
_K_RANGES = {"soft": ((60.0, 150.0), (1.5, 2.5)), "ordinary": ((150.0, 300.0), (2.0, 3.0)),
             "firm": ((300.0, 500.0), (2.4, 3.0))}


def _min_jerk(x: float) -> tuple[float, float]:
    """Minimum-jerk profile and its derivative (per unit of x) for x in [0, 1]."""
    if x <= 0.0:
        return 0.0, 0.0
    if x >= 1.0:
        return 1.0, 0.0
    return x ** 3 * (10.0 - 15.0 * x + 6.0 * x * x), 30.0 * x * x * (1.0 - x) ** 2


def _ramp(x: float) -> float:
    x = min(max(x, 0.0), 1.0)
    return 0.5 - 0.5 * math.cos(math.pi * x)


@dataclass(frozen=True)
class HumanParams:
    """One person (SI at the axis: rad, s, N·m, N·m/rad, N·m·s/rad, kg·m²)."""

    grip: str = "ordinary"
    q_start: float = 0.0            # where the link is when grasped, rad (the intended move starts there)
    distance: float = 0.3           # intended move, rad
    t_grasp: float = 2.0            # grasp begins, s
    grasp_time: float = 0.25        # grip builds up over this, s
    move_delay: float = 0.2         # intended motion starts this long after the grasp begins, s
    move_time: float = 2.5          # duration of the minimum-jerk move, s
    K0: float = 200.0               # base (relaxed) stiffness at the axis, N·m/rad
    K_max: float = 500.0            # stiffness with full co-contraction, N·m/rad
    tau_cocontract: float = 15.0    # effort (N·m) that doubles the stiffness
    zeta: float = 0.3               # damping ratio (of K0 with the hand's inertia)
    I_hand: float = 0.6             # hand and forearm inertia about the axis, kg·m²
    reflex_share: float = 0.35      # part of stiffness and damping acting through the reflex delay
    reflex_delay: float = 0.045     # s
    reaction_time: float = 0.2      # voluntary reaction (change of plan, letting go), s
    tremor_amp: float = 0.25        # N·m
    tremor_freq: float = 10.0       # Hz
    noise_cv: float = 0.03          # signal-dependent noise, SD / |torque|
    max_torque: float = 50.0        # largest torque the person applies, N·m
    change_at: float | None = None  # fraction of the move when the person changes the target (None: never)
    change_by: float = 0.0          # new target = old + change_by * distance
    change_time: float = 1.5        # duration of the corrective minimum-jerk segment, s
    on_target_tol: float = 0.015    # rad
    slow_speed: float = 0.02        # rad/s
    dwell: float = 0.3              # on target and slow for this long before deciding to let go, s
    timeout: float = 4.0            # lets go this long after the planned end in any case, s
    release_time: float = 0.2       # grip fades over this, s
    seed: int = 0

    @property
    def goal(self) -> float:
        """Final intended position, rad."""
        return self.q_start + self.distance * (1.0 + (self.change_by if self.change_at is not None else 0.0))

    @property
    def t_plan_end(self) -> float:
        """When the intended motion ends, s."""
        t1 = self.t_grasp + self.move_delay + self.move_time
        if self.change_at is None:
            return t1
        return max(t1, self._t_change() + self.change_time)

    def _t_change(self) -> float:
        return self.t_grasp + self.move_delay + float(self.change_at) * self.move_time + self.reaction_time


class HumanArm:
    """The arm of :class:`HumanParams` as an external-torque function ``fn(t, q, qd) -> N·m``.

    Attributes after a run: ``t_release`` (s, when the grip began to fade; NaN while holding),
    ``released_on_target`` (bool), ``K_peak`` (largest stiffness reached, N·m/rad); ``K`` (the
    stiffness at the latest evaluation, N·m/rad, 0 while not holding: what a benchmark's oracle may
    read, never a controller).

    The hand's own inertia ``I_hand`` moves with the link.  By default (``plant_inertia`` False,
    the one-axis simulator) the arm adds its reaction ``-I_hand qdd`` to the torque, with ``qdd``
    differenced between two evaluations: an explicit, one-evaluation-late coupling that is stable
    only while the link (behind its servo) is heavier than the hand (the paper's A3, Izz 2.28
    kg·m², against at most 1.7 kg·m² here).  A simulator that carries the hand's inertia in its
    own dynamics (the six-axis :class:`~kukaid.sim.robot_plant.VirtualRobotKRC4`, whose A3 is about
    0.7 kg·m²) sets ``plant_inertia`` True and adds :meth:`hand_inertia` to the axis's inertia
    (exact, implicit); the torque is then the muscles' alone, ``g (K e + B ė)`` + noise.
    """

    #: True: the simulator integrates :meth:`hand_inertia` with the link (no differenced ``qdd`` term)
    plant_inertia: bool = False

    def __init__(self, params: HumanParams) -> None:
        if params.grip not in GRIPS:
            raise KukaidError(f"operator: unknown grip {params.grip!r}; choose one of {', '.join(GRIPS)}")
        self.p = params
        self.reset()

    # the external-torque callable of the simulator
    def __call__(self, t: float, q: float, qd: float) -> float:
        return self.step(float(t), float(q), float(qd))

    def reset(self) -> None:
        p = self.p
        self._rng = np.random.default_rng(np.random.SeedSequence([int(p.seed), 0x4a7]))
        self._hist: list[tuple[float, float, float]] = []  # (t, q, qd), newest last
        self._t_prev: float | None = None
        self._qd_prev = 0.0
        self._qdd = 0.0
        self._g = 0.0
        self._effort = 0.0
        self._sdn = 0.0
        self._phase = float(self._rng.uniform(0.0, 2 * math.pi))
        self._freq = p.tremor_freq
        self._settled_since: float | None = None
        self._decided: float | None = None
        self.t_release = math.nan
        self.released_on_target = False
        self.K_peak = 0.0
        self.K = 0.0

    def intended(self, t: float) -> tuple[float, float]:
        """Intended position (rad) and velocity (rad/s) at ``t``."""
        p = self.p
        t0 = p.t_grasp + p.move_delay
        s, ds = _min_jerk((t - t0) / p.move_time)
        x, v = p.q_start + p.distance * s, p.distance * ds / p.move_time
        if p.change_at is not None:
            s2, ds2 = _min_jerk((t - p._t_change()) / p.change_time)
            x += p.change_by * p.distance * s2
            v += p.change_by * p.distance * ds2 / p.change_time
        return x, v

    def _delayed(self, t: float) -> tuple[float, float]:
        """(q, qd) as seen ``reflex_delay`` s ago (the oldest kept sample before that)."""
        target = t - self.p.reflex_delay
        q, qd = self._hist[0][1], self._hist[0][2]
        for th, qh, qdh in self._hist:
            if th <= target + 1e-9:
                q, qd = qh, qdh
            else:
                break
        return q, qd

    def _grip(self, t: float, q: float, qd: float) -> float:
        """Grip 0..1; decides the release (on target and slow for ``dwell``, or the timeout)."""
        p = self.p
        if t < p.t_grasp:
            return 0.0
        g = _ramp((t - p.t_grasp) / p.grasp_time)
        if self._decided is None and t >= p.t_plan_end:
            # what the person sees now prompts a decision one reaction time later
            on = abs(q - p.goal) <= p.on_target_tol and abs(qd) <= p.slow_speed
            if on:
                if self._settled_since is None:
                    self._settled_since = t
                if t - self._settled_since >= p.dwell:
                    self._decided = t + p.reaction_time
                    self.released_on_target = True
            else:
                self._settled_since = None
            if self._decided is None and t >= p.t_plan_end + p.timeout:
                self._decided = t
        if self._decided is not None and t >= self._decided:
            if math.isnan(self.t_release):
                self.t_release = self._decided
            g *= _ramp(1.0 - (t - self._decided) / p.release_time)
        return g

    def hand_inertia(self) -> float:
        """Inertia the hand adds to the link at the latest evaluation, kg·m²: grip times ``I_hand``."""
        return self._g * self.p.I_hand

    def step(self, t: float, q: float, qd: float) -> float:
        """Torque of the hand on the link at ``t`` s for link position ``q`` rad, velocity ``qd``."""
        p = self.p
        dt = 0.012 if self._t_prev is None else max(t - self._t_prev, 1e-6)
        if self._t_prev is not None:
            self._qdd = (qd - self._qd_prev) / dt
        self._t_prev, self._qd_prev = t, qd
        self._hist.append((t, q, qd))
        while len(self._hist) > 2 and self._hist[1][0] <= t - p.reflex_delay - 1e-9:
            self._hist.pop(0)
        # random streams advance every step, grasped or not (the same person, the same noise)
        w_sdn, w_tr = self._rng.standard_normal(2)
        g = self._grip(t, q, qd)
        self._g = max(g, 0.0)
        if g <= 0.0:
            self._effort = 0.0
            self.K = 0.0
            return 0.0
        x, v = self.intended(t)
        qr, qdr = self._delayed(t)
        a = self.p.reflex_share
        # co-contraction: stiffness rises with the effort (low-passed |torque|, ~0.1 s activation)
        K = min(p.K_max, p.K0 * (1.0 + self._effort / p.tau_cocontract))
        self.K_peak = max(self.K_peak, K)
        self.K = K
        B = 2.0 * p.zeta * math.sqrt(K * p.I_hand)
        e_pos = (1 - a) * (x - q) + a * (x - qr)
        e_vel = (1 - a) * (v - qd) + a * (v - qdr)
        tau = K * e_pos + B * e_vel
        if not self.plant_inertia:
            tau -= p.I_hand * self._qdd
        tau = min(max(tau, -p.max_torque), p.max_torque)
        alpha = min(dt / 0.1, 1.0)
        self._effort += alpha * (abs(tau) - self._effort)
        # signal-dependent noise: SD noise_cv |tau|, correlated over ~50 ms
        rho = math.exp(-dt / 0.05)
        self._sdn = rho * self._sdn + math.sqrt(1 - rho * rho) * w_sdn
        # tremor: 8-12 Hz with a wandering phase
        self._phase += 2 * math.pi * self._freq * dt + 0.3 * w_tr
        noise = p.noise_cv * abs(tau) * self._sdn + p.tremor_amp * math.sin(self._phase)
        return g * (tau + noise)

    def params(self) -> dict:
        """The person, JSON-able."""
        return asdict(self.p)


def make_human(seed: int = 0, q0: float = 0.0, t_start: float = 2.0, grip: str | None = None,
               distance: float | None = None) -> HumanArm:
    """Draw one person from ``seed`` (grip class too unless ``grip`` is given).

    ``q0`` rad: where the link is when grasped; ``t_start`` s: the grasp.  Travel 0.2-0.5 rad
    either way, move time 1.8-3.5 s, a change of target mid-move for about a third of people.
    """
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x4a8]))
    g_draw = GRIPS[int(rng.integers(0, 3))]
    grip = g_draw if grip is None else grip
    if grip not in GRIPS:
        raise KukaidError(f"operator: unknown grip {grip!r}; choose one of {', '.join(GRIPS)}")
    (k_lo, k_hi), (r_lo, r_hi) = _K_RANGES[grip]
    K0 = float(rng.uniform(k_lo, k_hi))
    K_max = min(1200.0, K0 * float(rng.uniform(r_lo, r_hi)))
    d = float(rng.uniform(0.2, 0.5)) * (1.0 if rng.random() < 0.5 else -1.0)
    if distance is not None:
        d = float(distance)
    change = rng.random() < 0.33
    lever = float(rng.uniform(0.45, 0.75))
    m_hand = float(rng.uniform(1.0, 3.0))
    f_max = float(rng.uniform(60.0, 120.0))
    p = HumanParams(
        grip=grip, q_start=float(q0), distance=d, t_grasp=float(t_start),
        grasp_time=float(rng.uniform(0.15, 0.3)), move_delay=float(rng.uniform(0.1, 0.3)),
        move_time=float(rng.uniform(1.8, 3.5)), K0=K0, K_max=K_max,
        tau_cocontract=float(rng.uniform(8.0, 20.0)), zeta=float(rng.uniform(0.2, 0.5)),
        I_hand=m_hand * lever ** 2, reflex_share=float(rng.uniform(0.25, 0.45)),
        reflex_delay=float(rng.uniform(0.03, 0.06)), reaction_time=float(rng.uniform(0.15, 0.25)),
        tremor_amp=float(rng.uniform(0.1, 0.4)), tremor_freq=float(rng.uniform(8.0, 12.0)),
        noise_cv=float(rng.uniform(0.02, 0.05)), max_torque=f_max * lever,
        change_at=float(rng.uniform(0.3, 0.6)) if change else None,
        change_by=float(rng.choice([-1.0, 1.0]) * rng.uniform(0.2, 0.5)) if change else 0.0,
        change_time=float(rng.uniform(1.0, 2.0)),
        on_target_tol=max(0.01, 0.05 * abs(d)), slow_speed=0.02, dwell=float(rng.uniform(0.2, 0.4)),
        timeout=float(rng.uniform(3.0, 5.0)), release_time=float(rng.uniform(0.15, 0.3)), seed=int(seed))
    return HumanArm(p)
