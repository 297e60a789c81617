"""Sensorless external-torque detection, eqs. (12)-(14): the torque residual Γr = Γp - Γm.

Γm is the measured motor torque ($TORQUE_AXIS_ACT), Γp the identified model's prediction::

    |qd| >= qd_thr (dynamic mode, eq. 6):      Γp = Izz qdd + Mx cos q (+ My sin q + offset + effects) + F(qd)
    |qd| <  qd_thr (quasi-static mode, eq. 11): Γp = Mx cos q (+ ...) + Fp(q) + Γu

with F the Stribeck friction (eq. 1) and Fp the Maxwell-slip pre-sliding torque (eqs. 9-10).
For a perfect model Γr equals the external torque on the link (a person's push), with the
paper's sign: pushing the joint towards positive q gives Γr > 0.

Online, causal version (what a controller can do):

* torque, position and the velocity and acceleration obtained by differencing positions all pass
  through the same causal 3rd-order Butterworth low-pass (5 Hz), so they stay aligned in time;
* Γu, the unmodelled quasi-static torque, is taken anew at the start of every rest (the paper's
  eq. 13; a rest begins when the axis stops with nobody in contact: no detection and |Γr| below
  the threshold for the last ``QUIET_BEFORE_REST`` s, so not a hand braking the axis; and it
  moved: a dynamic episode that stayed within the model's pre-sliding range, the largest W_i/k_i
  of its elements, is a push's breakaway deflecting a standing axis, and ends in no stop): the
  mean raw residual over its first ``u_window`` s, then, while the axis settles (``switch_quiet``
  s), a close follower (time constant ``u_window``), then, only while nobody is in contact
  (quasi-static, no detection, the innovation below half the start threshold at rest, so a push
  building up is not learnt), a slow observer (time constant ``u_tau``), and beyond half the start
  threshold a drift no faster than ``DRIFT_RATE`` (a servo's integral action winding up against
  stiction ramps the torque at rest by about 1 N·m/s; a push builds up faster), or
  ``HELD_DRIFT_RATE`` the way a hand held at rest would read as it lets go (the servo winds faster
  under it).  In contact Γu is
  frozen, so a push that is still there when the axis stops is never absorbed;
* at rest, out of contact, the RMS of Γr is tracked: the start threshold at rest is at least
  ``floor_k`` times it (at most ``floor_cap`` x ``threshold``), so a model whose friction at rest
  does not match the axis needs a firmer push instead of moving the axis by itself
  (``rest_threshold_max`` says how far it had to rise, ``rest_rms_max`` the RMS that raised it).  The mean square is the mean over the
  rest seen so far, the starting level (Γr's RMS at ``threshold / floor_k``) counted as
  ``FLOOR_PRIOR`` s of it, forgetting over ``floor_tau`` once that much has been seen: an average
  forgetting over ``floor_tau`` from the start held the starting level for seconds, and a plant's
  own sway at rest crossed the threshold before the floor had learnt it;
* friction is continuous across the mode switch: up to ``qd_thr`` the Maxwell-slip torque, from
  ``3 qd_thr`` on the Stribeck curve, linearly blended in between (on the differenced speed,
  ``BLEND``); and every change of mode
  (Γu added or removed) is bumpless: the jump of Γp at the switch is carried as an offset that
  fades with the time constant ``switch_tau``;
* the Maxwell-slip elements follow the raw position in both modes, so at a stop they stand
  saturated in the direction the axis last moved (the paper's eq. 12, which re-initialises them
  at the switch, without the sign of a low-passed speed that rings past zero after a hard stop);
* detection: Γr is "detected" when |Γr| >= the start threshold and stays so until |Γr| <
  ``release`` (hysteresis), so a residual hovering at the threshold does not chatter; within
  ``switch_quiet`` s of the axis stopping (a change to quasi-static mode, or the differenced
  speed falling below ``qd_thr``) the start threshold is ``switch_share`` x ``threshold``, or the
  threshold plus :attr:`blend_gap` when that is more (also while the axis creeps slower than the
  blend's upper end, out of contact): a stop leaves spikes in Γr (the paper's
  backlash spikes, the friction settling, the servo's overshoot, and the model's own friction
  going from its sliding curve to its elements' saturation before the servo's torque follows)
  that must not move the axis (a start is not guarded: a push at rest starts the axis);
  while moving, the start threshold is at least ``MOVING_MARGIN`` times the RMS of Γr moving out
  of contact (:attr:`moving_threshold`: a slow coast after a release is where a model's friction is
  least sure);
* a hand, or the model, at rest: at rest a torque that stands still is a hand left on the axis or
  the model's friction off by that much, and one cannot tell which.  So at rest the residual is
  read two ways until the axis moves again: Γr, relative to what Γu has taken in, and Γr plus the
  part of it that may be a hand (:attr:`_hand`); a push is what both readings see, the smaller of
  the two, so a hand letting go (one reading towards 0, the other away) moves nothing.  That part
  is what the moving model read as the axis stopped (averaged over ``DYN_MEMORY`` s: a hand left
  on below the threshold, or the model's error while moving); what a stop's settling adds beyond
  the threshold (a settling as large as a push may be a hand pressing harder as the axis
  stopped); and a residual standing at rest when the start threshold falls under |Γr| (the
  doubled threshold of a stop ends, the threshold at rest comes down) rather than |Γr| rising
  through it (:attr:`standing_max` reports the largest).  Γu goes on following a slow drift
  relative to it, and leaves it out when the axis moves (the next stop may keep that Γu).
  A drift Γu followed at rest may have been a hand leaning in slowly, so Γr is also read against
  every Γu held since the rest's first window (forgotten when the axis moves; :attr:`drift_max`
  reports the widest span): the push is the reading nearest zero over all of them, and a hand
  that leaned in and lets go moves nothing.  The other way round, a drift Γu followed the way the
  hand part's release would read (the servo winding against stiction under a held hand) adds to the
  hand part beyond the threshold (in full where it came faster than the servo's own creep,
  ``DRIFT_RATE``: the hand's doing), for the release adds the hand's own torque to it.  And what Γr read
  on one side of zero (at least half the threshold) and then lost there with Γu standing, Γr - Γu
  falling back (the servo's integral action handing a hand's torque to stiction: the motor torque goes
  back to where it was with the hand still on) is a possible hand too, at most what Γr read: the hand's
  release unloads the stiction through the motor and reads as a push the other way.  The cost:
  until the axis has moved, a push against that part, or against a drift Γu followed, needs that much
  more force.

Effects a diagnosis added to the parameter file are included when they depend on position only
(``gravity_sine``, ``torque_offset``, ``position_ripple``); others are listed in
:attr:`TorqueResidual.ignored_effects`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from kukaid.control.filters import CausalButterworth
from kukaid.errors import KukaidError
from kukaid.models.torque import JointTorqueModel

DYNAMIC = "dynamic"
QUASI_STATIC = "quasi-static"
#: speeds (multiples of qd_thr) between which the friction model goes from Maxwell-slip to Stribeck
BLEND = (1.0, 3.0)
#: default holding threshold (end of a detection) as a share of the start threshold
RELEASE_SHARE = 0.3
#: a stop begins a new rest (Γu anew) only after this long (s) with |Γr| below the threshold: a
#: hand that braked the coasting axis (applied, not detected) is still on it when it stops
QUIET_BEFORE_REST = 0.3
#: while moving, a start needs this many times the RMS of the residual moving out of contact
MOVING_MARGIN = 2.0
#: memory (s) of the residual read while moving, taken as the hand's torque when the axis stops
DYN_MEMORY = 0.1
#: at rest, out of contact, the fastest drift (N·m/s) Γu follows beyond half the start threshold: a
#: servo's integral action winding against stiction ramps the torque at rest by about 1 N·m/s with
#: nobody there; a person's push builds up faster (the simulated people: 7.6 N·m/s at the slowest)
DRIFT_RATE = 1.0
#: the same while a part held as a possible hand (at least half the threshold) may still hold the axis,
#: for a drift the way its release would read: the servo winds at 3-6 N·m/s then (the hand deflects the
#: stiction's bristles further), and the drift, read as the hand fading, left the release beyond it
HELD_DRIFT_RATE = 3.0
#: s of rest the threshold floor's starting level counts as (the floor then learns a plant's level at
#: rest as a mean over the rest seen so far, not as an average forgetting over floor_tau from the start)
FLOOR_PRIOR = 2.0
#: at rest, before anything was read and lost: (the side of zero, Γr - Γu's extreme there, the lowest and
#: highest Γr) and the loss each way (negative, positive), N·m
NOTHING_LOST = ((0.0, 0.0, 0.0, 0.0), (0.0, 0.0))
#: at rest, before Γu followed any drift the way the hand part's release reads: (all of it, the part
#: faster than ``DRIFT_RATE``), N·m
NOT_WOUND = (0.0, 0.0)
#: effects of a parameter file that the online residual evaluates
SUPPORTED_EFFECTS = ("gravity_sine", "torque_offset", "position_ripple")


@dataclass(slots=True)
class ResidualSample:
    """One step of the estimator (SI): residual ``gamma_r`` N·m, prediction ``gamma_p`` N·m,
    filtered torque ``tau_f`` N·m, filtered ``q`` rad, ``qd`` rad/s, ``qdd`` rad/s², ``mode``
    ("dynamic" or "quasi-static"), ``detected`` (bool), ``gamma_u`` N·m (quasi-static offset)."""

    gamma_r: float
    gamma_p: float
    tau_f: float
    q: float
    qd: float
    qdd: float
    mode: str
    detected: bool
    gamma_u: float


def _beyond(x: float, cap: float) -> float:
    """The part of ``x`` beyond ±``cap``."""
    return x - min(max(x, -cap), cap)


def _check(name: str, v: float, lo: float, hi: float = math.inf, open_lo: bool = True) -> float:
    v = float(v)
    ok = math.isfinite(v) and (v > lo if open_lo else v >= lo) and v <= hi
    if not ok:
        rng = f"({lo}, {hi}]" if open_lo else f"[{lo}, {hi}]"
        raise KukaidError(f"torque residual: {name} = {v} is outside the allowed range {rng}")
    return v


class TorqueResidual:
    """Online estimator of the external torque from measured position and torque.

    Parameters
    ----------
    model : the identified axis model (:func:`kukaid.params.axis.model_from_params`).
    sample_time : measurement interval, s (12 ms on a KR C4).
    threshold : detection threshold on |Γr|, N·m (paper: 3 quasi-static, 5 mode switching).
    release : |Γr| below which a detection ends, N·m (default 0.3 * threshold:
        a smaller holding threshold, so a person in contact is followed down to small torques).
    cutoff, order : causal Butterworth low-pass, Hz and order (paper: 5 Hz, 3).
    u_window : length of the initial Γu averaging (at rest, after a reset), s.
    u_tau : time constant of the Γu observer out of contact, s.
    switch_tau : time constant with which the jump of Γp at a mode switch fades, s.
    switch_quiet, switch_share : within ``switch_quiet`` s of the axis stopping a detection needs
        ``switch_share`` x ``threshold`` (and Γu follows a stop's settling closely).
    floor_tau, floor_k, floor_cap : at rest the start threshold is at least ``floor_k`` x the RMS of
        Γr at rest out of contact (forgetting ``floor_tau`` s), at most ``floor_cap`` x ``threshold``.
    zeta0 : Maxwell-slip element positions relative to the start position, rad (parameter file's
        ``maxwell_slip.zeta0``); default zero (Γu absorbs the unknown initial state).
    qd_thr : mode-switching velocity threshold, rad/s (default the model's).
    """

    def __init__(self, model: JointTorqueModel, sample_time: float = 0.012, threshold: float = 5.0,
                 release: float | None = None, cutoff: float = 5.0, order: int = 3, u_window: float = 0.12,
                 zeta0: Any = None, qd_thr: float | None = None, u_tau: float = 1.0,
                 switch_tau: float = 0.15, switch_quiet: float = 1.0, floor_tau: float = 5.0, floor_k: float = 4.0,
                 floor_cap: float = 3.0, switch_share: float = 2.0) -> None:
        self.model = model
        self._rigid, self._friction = model.rigid, model.friction  # the model's terms as functions
        self.sample_time = _check("sample_time", sample_time, 0.0, 1.0)
        self.threshold = _check("threshold", threshold, 0.0)
        self.release = RELEASE_SHARE * self.threshold if release is None else _check("release", release, 0.0, open_lo=False)
        if self.release > self.threshold:
            raise KukaidError(f"torque residual: release = {self.release} N·m must not exceed threshold = "
                              f"{self.threshold} N·m")
        self.u_window = _check("u_window", u_window, 0.0, 60.0, open_lo=False)
        self.u_tau = _check("u_tau", u_tau, 0.0, 600.0)
        self.switch_tau = _check("switch_tau", switch_tau, 0.0, 10.0)
        self.switch_quiet = _check("switch_quiet", switch_quiet, 0.0, 10.0, open_lo=False)
        self.floor_tau = _check("floor_tau", floor_tau, 0.0, 600.0)
        self.floor_k = _check("floor_k", floor_k, 0.0, 100.0, open_lo=False)
        self.floor_cap = _check("floor_cap", floor_cap, 1.0, 100.0, open_lo=False)
        self.switch_share = _check("switch_share", switch_share, 0.0, 100.0)
        self.qd_thr = _check("qd_thr", model.qd_thr if qd_thr is None else qd_thr, 0.0, open_lo=False)
        # what the model's own friction changes by as the axis stops, N·m: from the sliding curve where the blend
        # begins to the elements' saturation (the paper's A3: 2.6 down; a breakaway 1.5 x Coulomb whose elements
        # hold 0.85 x it at rest: 12 down, the stop alone read as a push against the motion; elements that hold
        # 1.24 x the breakaway: 7 up, a creep read as a push along it; each a stick-slip cycle with nobody there)
        ms = model.maxwell_slip
        self.blend_gap = (abs(abs(float(model.friction.at(BLEND[1] * self.qd_thr))) - float(np.sum(ms.W)))
                          if ms is not None else 0.0)
        # the start threshold at a stop or a creep after a stick-slip cycle with nobody there, N·m (the loop's
        # :class:`~kukaid.control.stability.StickSlipWatch` sets it; 0: none seen)
        self.cycle_margin = 0.0
        self.cutoff, self.order = float(cutoff), int(order)
        fs = 1.0 / self.sample_time
        # q, qd, qdd, tau, predicted torque
        self._filters = [CausalButterworth(cutoff, fs, order) for _ in range(5)]
        self._k = np.asarray(ms.k, dtype=float) if ms is not None else np.zeros(0)
        self._W = np.asarray(ms.W, dtype=float) if ms is not None else np.zeros(0)
        z0 = np.zeros(self._k.size) if zeta0 is None else np.asarray(zeta0, dtype=float).ravel()
        if z0.size != self._k.size:
            raise KukaidError(f"torque residual: zeta0 has {z0.size} values, the Maxwell-slip model {self._k.size} elements")
        self._zeta0 = z0
        self._k_lim = [(float(k), float(w) / float(k)) for k, w in zip(self._k, self._W)]
        # the travel within which a "move" is the pre-sliding deflection of a push (every element not yet
        # broken away), not a move that ends in a new rest
        self._presliding_range = max((lim for _, lim in self._k_lim), default=0.0)
        # effects a diagnosis stored in the rigid body (inertial.My, offset; marked stored_as) are
        # already in the model
        eff = {k: v for k, v in model.stored_effects.items() if "stored_as" not in v}
        self.ignored_effects = sorted(k for k in eff if k not in SUPPORTED_EFFECTS)
        self._My_extra = float(eff["gravity_sine"].get("My", 0.0)) if "gravity_sine" in eff else 0.0
        self._off_extra = float(eff["torque_offset"].get("offset", 0.0)) if "torque_offset" in eff else 0.0
        r = eff.get("position_ripple")
        self._ripple = None
        if r:  # a sin(n q) + b cos(n q) as diagnose writes it, or A sin(n q + phi) as the simulator
            A, phi = float(r.get("A", 0.0)), float(r.get("phi", 0.0))
            a = float(r["a"]) if "a" in r else A * math.cos(phi)
            b = float(r["b"]) if "b" in r else A * math.sin(phi)
            self._ripple = (float(r["n"]), a, b)
        self._started = False

    # -- model pieces ---------------------------------------------------------------------------
    def static_torque(self, q: float) -> float:
        """Position-only part of Γp: gravity, offset and supported effects, N·m."""
        rb = self._rigid
        g = rb.Mx * math.cos(q) + (rb.My + self._My_extra) * math.sin(q) + rb.offset + self._off_extra
        if self._ripple is not None:
            n, a, b = self._ripple
            g += a * math.sin(n * q) + b * math.cos(n * q)
        return g

    def _maxwell_slip(self, z: float) -> float:
        """Eqs. (9)-(10) for the common displacement ``z`` rad (element positions updated)."""
        total = 0.0
        zeta = self._zeta
        for i, (k, lim) in enumerate(self._k_lim):  # a few elements: plain floats are fastest
            d = z - zeta[i]
            if d >= lim:
                zeta[i] = z - lim
            elif d <= -lim:
                zeta[i] = z + lim
            total += k * (z - zeta[i])
        return total

    # -- state ----------------------------------------------------------------------------------
    def reset(self, q0: float | None = None) -> None:
        """Start over (filters, mode, Γu); the first :meth:`update` initialises from its sample."""
        self._started = False
        self._q0 = q0

    def _start(self, q: float, tau: float) -> None:
        self._q_prev = q
        self._qd_prev = 0.0
        self._zeta = [q + float(v) for v in self._zeta0]
        fp0 = self._maxwell_slip(q)  # elements beyond their saturation slip back to it
        for f, x0 in zip(self._filters, (q, 0.0, 0.0, tau, self.static_torque(q) + fp0)):
            f.reset(x0)
        self._mode = QUASI_STATIC
        self._u_n = 0
        self._u_need = max(1, int(round(self.u_window / self.sample_time)))
        self._gamma_u = 0.0  # Γu at the rest's anchor, N·m
        self._u_anchor = 0.0  # Γu at the end of the rest's first window, N·m
        # mean square of Γr at rest out of contact, N²m², from the level where the start threshold
        # is ``threshold``
        self._rest_ms = (self.threshold / self.floor_k) ** 2 if self.floor_k > 0 else 0.0
        self._rest_t = FLOOR_PRIOR  # s of rest in that mean square (the starting level counts as FLOOR_PRIOR)
        self._dyn_ms, self._dyn_n = 0.0, 0  # mean square of Γr moving out of contact, N²m²
        self.rest_threshold_max = self.threshold
        self.rest_rms_max = 0.0  # the largest RMS of Γr at rest out of contact the start threshold followed, N·m
        self.standing_max = 0.0  # the largest torque held as a possible hand when the threshold fell under one, N·m
        self.drift_max = 0.0  # the widest span of Γu held in one rest, N·m (a push against it needed that much more)
        self._bump = 0.0  # Γp jump of the last mode switch, fading
        self._since_switch = math.inf  # s since the axis last started or stopped
        self._since_stop = math.inf  # s since the axis last stopped
        self._quiet = math.inf  # s since |Γr| was last at the threshold (or detected)
        self._rest_age = math.inf  # s of close following since the present rest began
        self._hand = 0.0  # at rest: the part of the residual that may be a hand still on the axis, N·m
        self._u_span = (0.0, 0.0)  # at rest: the lowest and highest Γu held since the rest's first window, N·m
        self._q_move0 = q  # where the present dynamic episode began, rad
        self._travel = 0.0  # the farthest the axis has been from there, rad
        self._wound = NOT_WOUND  # at rest: the drift Γu followed the way the hand part's release reads, N·m
        # at rest: what Γr read on one side of zero and then lost with Γu standing (the servo handing a hand's
        # torque to stiction), N·m
        self._seen, self._hidden = NOTHING_LOST
        self._rest_kept = (0.0, 0.0, (0.0, 0.0), 0.0, self._seen, self._hidden)  # Γu, the hand part, the span,
        # the wound and what was lost as the episode began
        self._dyn_r = 0.0  # Γr while moving, averaged over DYN_MEMORY s, N·m
        self._start_prev = math.inf  # the start threshold at the previous sample, N·m
        self._moving = False
        self._detected = False
        self._started = True

    @property
    def mode(self) -> str:
        return self._mode if self._started else QUASI_STATIC

    @property
    def detected(self) -> bool:
        return self._detected if self._started else False

    @property
    def release_now(self) -> float:
        """|Γr| below which a detection ends, N·m: ``release``, or 1.5 x the RMS of Γr while the axis
        moved with nobody in contact (the initiation move, coasting after a release) when that is
        larger, at most 0.8 x ``threshold``: a model off by a few N·m while moving (friction that
        changes with position, a gravity error) would otherwise hold a released detection on and
        keep moving the axis by its own error."""
        return min(max(self.release, 1.5 * math.sqrt(self._dyn_ms)), max(self.release, 0.8 * self.threshold))

    @property
    def moving_threshold(self) -> float:
        """The start threshold while the axis moves, N·m: ``threshold``, or ``MOVING_MARGIN`` times the RMS
        of Γr while it moved with nobody in contact when that is larger (at most ``floor_cap`` x
        ``threshold``): a coast after a release, slower than the friction's Stribeck velocity, is where
        a model is least sure of its friction, and its own error there must not start the axis again."""
        return min(max(self.threshold, MOVING_MARGIN * math.sqrt(self._dyn_ms)), self.floor_cap * self.threshold)

    @property
    def rest_threshold(self) -> float:
        """The start threshold at rest, N·m: ``threshold``, or ``floor_k`` times the RMS of Γr at rest
        out of contact when that is larger (a model that misses part of the friction at rest then
        needs a firmer push, instead of moving the axis by itself), at most ``floor_cap`` x
        ``threshold``."""
        return min(max(self.threshold, self.floor_k * math.sqrt(self._rest_ms)), self.floor_cap * self.threshold)

    def nobody_was_there(self) -> None:
        """The loop's word that nobody has touched the axis so far (its own initiation move and the rest
        after it): what the present rest read and lost (a stop's settling) was no hand."""
        self._seen, self._hidden = NOTHING_LOST

    def end_detection(self) -> None:
        """End the present detection now (the loop's judgement: see :func:`kukaid.control.loop.run_admittance`);
        a new one needs the start threshold again."""
        self._detected = False

    # -- Γu, the quasi-static model's offset at rest ---------------------------------------------
    def _new_rest(self) -> None:
        """A rest begins (the axis stopped, nobody in contact): Γu anew (the paper: eq. 13)."""
        self._u_n = 0
        self._rest_age = 0.0

    def _learn_rest(self, raw: float, h: float) -> None:
        """Out of contact at rest: Γu is the mean of the raw residual over the first ``u_window`` s of
        a rest (eq. 13), then follows it: closely (time constant ``u_window``) while the axis settles
        (``switch_quiet`` s from the stop, when a push needs ``switch_share`` x the threshold), then with
        the time constant ``u_tau``, no faster than ``DRIFT_RATE`` N·m/s once the difference is beyond
        half the start threshold at rest (a push building up is not learnt, a servo winding up is).  No
        gain on the model's pre-sliding torque: fitted at rest it takes up a push (the push deflects the
        axis, the pre-sliding torque follows)."""
        e = raw - self._gamma_u
        if self._u_n < self._u_need:
            self._u_n += 1
            self._gamma_u += e / self._u_n
            self._u_anchor = self._gamma_u
        elif self._rest_age < self.switch_quiet:  # the stop settling (not a push's deflection)
            self._rest_age += h
            before = self._gamma_u - self._u_anchor
            self._follow(min(h / max(self.u_window, h), 1.0) * e)
            # beyond the threshold a settling is as large as a push, and may be a hand pressing harder as
            # the axis stopped: what goes beyond it is kept out of the reading without the hand
            after = self._gamma_u - self._u_anchor
            self._hand -= _beyond(after, self.threshold) - _beyond(before, self.threshold)
        else:  # beyond half the start threshold only a slow drift is followed (a servo's integrator winding
            # up against stiction ramps the torque at rest by 1-6 N·m/s; a push builds up faster)
            step, fast = min(h / self.u_tau, 1.0) * e, 0.0
            if abs(e) >= 0.5 * self.rest_threshold:
                held = step * self._hand > 0.0 and abs(self._hand) >= 0.5 * self.threshold
                rate = HELD_DRIFT_RATE if held else DRIFT_RATE
                step = min(max(step, -rate * h), rate * h)
                if held:  # faster than the servo's own creep: the hand deflecting the stiction further
                    fast = _beyond(step, DRIFT_RATE * h)
            self._follow(step, fast)

    def _follow(self, step: float, fast: float = 0.0) -> None:
        """Γu follows a drift at rest by ``step``; a step the way the hand part's release would read (the
        servo winding against stiction under a held hand: on a LuGre plant 5-11 N·m while a person held
        the stopped axis) counts to :attr:`_wound`, which the reading with the hand adds beyond the
        threshold: the release then adds the hand's own torque to what the winding made Γu follow.
        ``fast``, the part of the step faster than the servo's own creep (``DRIFT_RATE``) under a held
        hand, is the hand's doing and counts in full (lugre person 22: a 9.8 N·m hold wound 8.9 N·m at
        3 N·m/s; its 3.9 beyond the threshold left the release reading as a push)."""
        if step * self._hand > 0.0:
            self._wound = (self._wound[0] + step, self._wound[1] + fast)
        self._gamma_u += step

    def _lose(self, r: float, u: float) -> None:
        """At rest, out of contact: what Γr (``r``) read on one side of zero and then lost there while Γu (``u``)
        stood (Γr - Γu falling back, not Γu following) may be a hand whose torque the servo handed to stiction
        (on a LuGre plant a 15 N·m hold read 9 N·m, then nothing, with Γu still): its release then reads as a
        push the other way, so that much is a possible hand too, each way at most what Γr read."""
        w = r - u
        side, w_ext, r_lo, r_hi = self._seen
        r_lo, r_hi = min(r_lo, r), max(r_hi, r)
        neg, pos = self._hidden
        small = 0.5 * self.threshold  # a residual's own noise at rest: nothing lost
        if r > 0.0:
            w_ext = max(w_ext, w) if side > 0 else w
            if r_hi >= small:
                pos = max(pos, min(w_ext - w, r_hi))
        elif r < 0.0:
            w_ext = min(w_ext, w) if side < 0 else w
            if -r_lo >= small:
                neg = max(neg, min(w - w_ext, -r_lo))
        self._seen = (math.copysign(1.0, r) if r else side, w_ext, r_lo, r_hi)
        self._hidden = (neg, pos)

    def update(self, q: float, tau: float, dt: float | None = None) -> ResidualSample:
        """Feed one measurement (position rad, motor torque N·m); return the new residual.

        ``dt`` is the time since the previous measurement, s (default ``sample_time``).
        """
        q, tau = float(q), float(tau)
        if not (math.isfinite(q) and math.isfinite(tau)):
            raise KukaidError(f"torque residual: measurement must be finite (q = {q}, tau = {tau})")
        if not self._started:
            self._start(q, tau)
        h = self.sample_time if dt is None else float(dt)
        if not (h > 0 and math.isfinite(h)):
            raise KukaidError(f"torque residual: time step must be > 0 s, got {h}")
        qd_raw = (q - self._q_prev) / h
        qdd_raw = (qd_raw - self._qd_prev) / h
        self._q_prev, self._qd_prev = q, qd_raw
        fq, fqd, fqdd, ftau, fpred = self._filters
        # The prediction is evaluated sample by sample on the raw (differenced) signals, switching
        # friction model on the raw speed, and then low-passed by the same filter as the torque:
        # the filter is linear, so predicted and measured torque pass through identical dynamics
        # (a nonlinear model of low-passed signals is not the low-passed model: friction reversals
        # and the Maxwell-slip hysteresis would leave spikes).  The mode is chosen on the filtered
        # speed, as in the paper.
        fp_raw = self._maxwell_slip(q)
        v = abs(qd_raw)
        thr = self.qd_thr
        lo, hi = BLEND[0] * thr, BLEND[1] * thr
        if v <= lo:
            fric_raw = fp_raw
        else:
            fs = self._friction.at(qd_raw)
            fric_raw = fs if v >= hi else fp_raw + (fs - fp_raw) * (v - lo) / (hi - lo)
        pred_raw = self._rigid.Izz * qdd_raw + self.static_torque(q) + fric_raw
        q_f, qd_f, qdd_f, tau_f = fq.step(q), fqd.step(qd_raw), fqdd.step(qdd_raw), ftau.step(tau)
        pred_f = fpred.step(pred_raw)

        # Γu without the hand (the model's own offset at rest) makes the switches bumpless
        old_mode, old_u = self._mode, (self._gamma_u + self._hand if self._mode == QUASI_STATIC else 0.0)
        if abs(qd_f) >= self.qd_thr:
            self._mode = DYNAMIC
        elif self._mode == DYNAMIC:
            # eq. (12) holds without re-initialising the elements: they follow the raw position
            # in both modes, so at a stop they stand saturated in the direction the axis actually
            # last moved (and partly unloaded by a servo overshoot back), not in the sign of the
            # low-passed speed, which rings past zero after a hard stop and once set them the
            # wrong way (a 36 N·m jump of Γp, a self-sustained cycle on a LuGre plant)
            self._mode = QUASI_STATIC
        quasi = self._mode == QUASI_STATIC
        if not quasi and old_mode == QUASI_STATIC:  # moving: Γu is kept without the hand
            self._rest_kept = (self._gamma_u, self._hand, self._u_span, self._wound, self._seen, self._hidden)
            self._gamma_u, self._hand = self._gamma_u + self._hand, 0.0
            self._q_move0, self._travel = q, 0.0
        if not quasi:
            self._travel = max(self._travel, abs(q - self._q_move0))
        # a dynamic episode that stayed within the pre-sliding range was a push's deflection of a standing
        # axis (its breakaway crossing qd_thr for a few samples), not a move: it ends in no stop, and the
        # rest goes on as it was (its Γu, the part that may be a hand, the span)
        moved = self._travel > self._presliding_range
        if quasi and old_mode == DYNAMIC and not moved:
            self._gamma_u, self._hand, self._u_span, self._wound, self._seen, self._hidden = self._rest_kept
        if not quasi or self._u_n < self._u_need:
            self._u_span = (self._gamma_u, self._gamma_u)
            self._wound = NOT_WOUND
            self._seen, self._hidden = NOTHING_LOST
        if quasi and old_mode == DYNAMIC and not self._detected and moved:
            if self._quiet >= QUIET_BEFORE_REST:
                self._new_rest()  # stopped with nobody in contact (no detection, nor a braking hand)
            else:  # the old Γu, read from here relative to what the moving model last saw
                self._gamma_u -= self._dyn_r
            # what the moving model read as the axis stopped (a hand left on below the threshold, or the
            # model's own error) is, at rest, either: Γu takes it in, and the two readings below keep it
            self._hand, self._wound = self._dyn_r, NOT_WOUND
        raw = tau_f - pred_f  # what Γu must add for Γr = 0
        learning = quasi and not self._detected
        if learning:
            self._learn_rest(raw, h)
        lo, hi = min(self._u_span[0], self._gamma_u), max(self._u_span[1], self._gamma_u)
        self._u_span = (lo, hi)
        self.drift_max = max(self.drift_max, hi - lo)
        new_u = self._gamma_u if quasi else 0.0
        if self._mode != old_mode:  # bumpless: the prediction does not jump at a switch
            self._bump += old_u - new_u - self._hand
        moving = v > thr  # the axis starting or stopping (on the differenced speed)
        if self._mode != old_mode or moving != self._moving:
            self._since_switch = 0.0
        else:
            self._since_switch += h
        # a stop: to quasi-static mode, or the raw speed falling below qd_thr while still dynamic (a
        # push's own deflection of a standing axis is not one)
        stopped = old_mode == DYNAMIC and moved and (quasi or (self._moving and not moving))
        self._since_stop = 0.0 if stopped else self._since_stop + h
        self._moving = moving
        self._bump *= math.exp(-h / self.switch_tau)
        gamma_p = pred_f + new_u + self._bump
        gamma_r = r1 = gamma_p - tau_f
        if not quasi:  # moving: the dynamic model reads the hand again
            self._dyn_r += min(h / DYN_MEMORY, 1.0) * (r1 - self._dyn_r)
        else:  # a push only if every reading sees it (Γr with and without the hand, against every Γu held
            # in this rest: a drift Γu followed may have been a hand leaning in), the one nearest zero
            wound, fast = self._wound
            held = self._hand + fast + _beyond(wound - fast, self.threshold)
            if learning and self._u_n >= self._u_need:
                self._lose(r1, new_u)
            lo = min(0.0, held, -self._hidden[0]) + self._u_span[0] - self._gamma_u
            hi = max(0.0, held, self._hidden[1]) + self._u_span[1] - self._gamma_u
            gamma_r = r1 + lo if r1 + lo > 0.0 else r1 + hi if r1 + hi < 0.0 else 0.0
        a = abs(gamma_r)
        if not quasi and not self._detected and self._since_switch >= self.switch_quiet / 4:
            self._dyn_n += 1  # moving out of contact (the initiation move, coasting): the model's own error
            self._dyn_ms += max(h / self.floor_tau, 1.0 / self._dyn_n) * (gamma_r * gamma_r - self._dyn_ms)
        self._quiet = 0.0 if (self._detected or abs(r1) >= self.threshold) else self._quiet + h
        if self._detected:
            self._detected = a >= self.release_now
            self._start_prev = math.inf
        else:
            start = self.moving_threshold
            if quasi:
                if (learning and self._u_n >= self._u_need and self._since_switch >= self.switch_quiet
                        and abs(r1) < self.rest_threshold):  # what is not taken for a push (gated at half
                    # of it, as Γu, the floor stayed low on LuGre plants: 179/192 no-person runs held)
                    self._rest_t += h
                    self._rest_ms += min(max(h / self.floor_tau, h / self._rest_t), 1.0) * (r1 * r1 - self._rest_ms)
                start = self.rest_threshold
                self.rest_threshold_max = max(self.rest_threshold_max, start)
                self.rest_rms_max = max(self.rest_rms_max, math.sqrt(self._rest_ms))
            if self._since_stop < self.switch_quiet:  # a stop: friction settles, the servo overshoots
                start = max(start, self.switch_share * self.threshold)
            if self._since_stop < self.switch_quiet or (not quasi and v < BLEND[1] * thr):
                # a stop or a creep: the model's friction between its sliding curve and its elements' saturation
                start = max(start, self.threshold + self.blend_gap, self.cycle_margin)
            if quasi and start <= a < self._start_prev:
                # the start threshold fell under a residual standing at rest (a stop's 2 x ended, the
                # floor came down): not a push, rather a model off at this rest, or a hand that stayed
                # on after braking the axis; Γu takes it in, and a push must show in both readings
                self._hand += r1
                self._gamma_u -= r1
                self.standing_max = max(self.standing_max, abs(self._hand))
                gamma_r = a = 0.0
            self._start_prev = start
            self._detected = a >= start
        return ResidualSample(gamma_r, gamma_p, tau_f, q_f, qd_f, qdd_f, self._mode, self._detected, new_u)


def torque_residual(time: np.ndarray, q: np.ndarray, tau: np.ndarray, model: JointTorqueModel,
                    **options: Any) -> dict[str, np.ndarray]:
    """Run :class:`TorqueResidual` over recorded samples (causally, as online).

    Parameters
    ----------
    time : (N,) s.   q : (N,) rad.   tau : (N,) N·m (measured motor torque).
    model : identified axis model.   options : keyword arguments of :class:`TorqueResidual`.

    Returns
    -------
    dict of (N,) arrays: ``gamma_r``, ``gamma_p``, ``tau_f``, ``q``, ``qd``, ``qdd`` (filtered),
    ``dynamic`` (bool), ``detected`` (bool), ``gamma_u``.
    """
    time = np.asarray(time, dtype=float).ravel()
    q = np.asarray(q, dtype=float).ravel()
    tau = np.asarray(tau, dtype=float).ravel()
    if not time.size == q.size == tau.size:
        raise KukaidError(f"torque residual: time, q and tau must have one length (got {time.size}, {q.size}, {tau.size})")
    if time.size >= 2 and "sample_time" not in options:
        options["sample_time"] = float(np.median(np.diff(time)))
    est = TorqueResidual(model, **options)
    keys = ("gamma_r", "gamma_p", "tau_f", "q", "qd", "qdd", "gamma_u")
    out = {k: np.empty(time.size) for k in keys}
    dyn = np.zeros(time.size, dtype=bool)
    det = np.zeros(time.size, dtype=bool)
    for i in range(time.size):
        dt = float(time[i] - time[i - 1]) if i else None
        s = est.update(q[i], tau[i], dt if dt and dt > 0 else None)
        for k in keys:
            out[k][i] = getattr(s, k)
        dyn[i] = s.mode == DYNAMIC
        det[i] = s.detected
    out["dynamic"] = dyn
    out["detected"] = det
    return out
