"""Joint identification of all axes of a robot from logs of the whole arm moving (a URDF model).

Steps (:func:`fit_robot`):

1. *Motion*: each log's positions are low-pass filtered (zero-phase Butterworth, scipy.signal)
   and differentiated twice (central differences); the measured torques go through the same
   filter ("parallel filtering", so both sides of ``tau = Y pi`` see the same gain and phase).
   Edges are trimmed and the samples decimated to about ten per cut-off period. Unless given, and
   with several logs, the cut-off is chosen among :data:`CUTOFF_GRID` by held-out error against
   the raw torques (:func:`choose_cutoff`).
2. *Regressor*: Pinocchio's joint-torque regressor (ten inertial parameters per link) plus
   per-joint friction (Coulomb-viscous or Stribeck with a fixed Stribeck velocity) and offset.
3. *Base parameters* (numerical QR, :meth:`RobotModel.base_parameters`): weighted least squares
   on the base columns gives ``beta`` with its standard deviations; the per-joint weights are the
   inverse residual standard deviations of a first ordinary fit. Filtered residuals are correlated
   in time, so these sigma are optimistic: ``metrics.residual_correlation_factor`` is the factor
   to multiply them by (as in the single-axis fit).
4. *Physically consistent estimate*: every link's pseudo-inertia ``J = U U^T`` in log-Cholesky
   coordinates (Rucker & Wensing 2022), so every mass is positive and every inertia satisfies the
   triangle inequalities by construction; Coulomb and viscous friction >= 0. IPOPT (CasADi)
   minimises ``chi2 / M + prior_weight * sum_links D(J || J_nominal)``: ``chi2 / M`` is the mean
   squared weighted residual (about 1 at a good fit), ``D`` the entropic (log-det) divergence of
   the link from its URDF value, which is zero at the nominal link and grows as it moves away,
   equally in every direction of the consistent set. The prior only decides what the data leave
   open; its weight is ``prior_weight``.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Sequence

import numpy as np

from kukaid.errors import FitError, ParamFileError
from kukaid.identify.filtering import check_even_samples, evenly_sampled
from kukaid.identify.solve_interrupt import interruptible_solve
from kukaid.identify.uncertainty import correlation_factor
from kukaid.logs import AxisLog, check_each_recording_once, log_fingerprint
from kukaid.params.robot import SCHEMA as ROBOT_SCHEMA
from kukaid.params.robot import check_fitted_urdf, validate_robot_params
from kukaid.models import robot_effects
from kukaid.models.urdf import BUNDLED
from kukaid.models.robot import (FRICTION_MODELS, LINK_PARAMS, DriveModel, RobotModel, consistency,
                                 friction_names, friction_regressor, pseudo_inertia, smooth_sign)

PRIOR_WEIGHT = 1e-3
#: default low-pass cut-off, Hz. Parallel filtering (the same filter on positions and torques) is
#: exact only for the terms linear in the signals; Coriolis, gravity and Coulomb friction are not,
#: so wherever the filter cuts into the motion's band it biases the fit. The cut-off sits well above
#: the band of identification trajectories (a few Hz) and below the torque noise: 10 Hz (at most
#: fs/10); on the real LWR4+ the blocked cross-validation within the fit recording ranks it first
#: (``benchmarks/robot_lwr4_selection.py``), on the simulated KR 6 R700 sixx 5 and 10 Hz are alike.
CUTOFF = 10.0
#: candidate cut-offs, Hz, when none is given and there are several recordings: chosen by held-out
#: error against the raw torques (:func:`choose_cutoff`), each at most fs/10 (ten samples per cut-off
#: period: the central differences' gain is then within 7 % at the cut-off; one recording keeps the
#: default, :func:`_cutoff_terms`). An octave each side of the default: below 5 Hz the filter cuts into an identification
#: trajectory's band (a few Hz) and parallel filtering's bias on the nonlinear terms grows; above
#: 20 Hz the torque noise and the drives' and the structure's resonances come through
CUTOFF_GRID = (5.0, 10.0, 20.0)
#: at most this many samples per candidate cut-off in its choice (every k-th fitted sample of a long
#: log): ranking three cut-offs needs far fewer than the fit (:func:`_choice_settings`)
CHOICE_SAMPLES = 10_000
#: held-out mean relative error above which the recordings cannot rank the cut-offs (a 2 s recording
#: beside a long one gave 488 / 1413 / 577 %): the default is kept
NO_RANKING = 1.0
#: default harmonics of the position ripple per joint (see ``RobotFitSettings.ripple``): the LWR4+'s
#: blocked cross-validation within the fit recording falls from 19.9 % (none) to 19.3, 14.5, 12.0 %
#: (2, 3, 4) and then flattens (11.7 % at 6, 11.6 % at 8): the smallest where it flattens. The most
#: harmonics tried: with ``choose`` each joint gets 0, 2 or 4 by its own held-out error
RIPPLE = 4
#: candidate transition velocities of the Coulomb term ``Fc tanh(qd / v)``, rad/s (0: the sign),
#: chosen per joint by held-out error: a real joint's friction does not step at zero velocity (the
#: LWR4+'s A5 rises over several hundredths of a rad/s). 0.1 rad/s was a candidate too: blocks of
#: lwr4_3 chose it for A5, which then lost on lwr4_1 and lwr4_2 (27 -> 35 %): as wide as a slow
#: joint's whole motion, it is no longer a friction transition
SMOOTH_GRID = (0.0, 0.01, 0.03)
#: a joint slower than this (rad/s, its filtered velocity) is standing or sticking: its friction is static,
#: any torque up to the breakaway force, no function of the velocity. Such samples are not fitted, and a
#: stop (going on the same way after it, or lasting longer than the reversal window) is treated as a
#: reversal, its window counted from its edges (:func:`away_from_reversals`). The smallest transition
#: velocity of :data:`SMOOTH_GRID`: below it no candidate Coulomb term is determined by the speed. The
#: virtual KR C4's servo-driven joints stick between and at reversals (runs under 0.01 rad/s of up to
#: 0.8 s; 1 to 9 % of the equations away from reversals under 0.003 rad/s on tests/test_robot_e2e.py's
#: recording): fitted, they had a transition velocity of 0.01 to 0.03 rad/s chosen for them, which then
#: biased the inertias (well-determined base parameters 10 with the sign, 2 with 0.01 rad/s, 3 chosen),
#: and ripple harmonics the robot does not have. The LWR4+ passes through zero speed in at most 0.12 s
#: at its reversals and never stops: its fits are unchanged
STANDSTILL = 0.01
#: the Coulomb term's dead-band: this many standard deviations of the joint's velocity noise (the filtered
#: noise is correlated: at 3 its excursions still flip the sign a few times a second at rest)
NOISE_DEADBAND = 5.0
#: contiguous blocks of a single recording for the held-out choices (with several recordings,
#: each recording is left out in turn)
FOLDS = 5
#: a more complex choice (more ripple harmonics, a larger transition velocity) must lower the joint's
#: held-out error by more than this factor over the simplest within it: blocks of one recording
#: share its motion, so small gains there do not carry to other recordings (on the heavy-robot
#: check a margin of 1 % let ripple terms the robot does not have in and cost A6 2.6 points)
SIMPLER_WITHIN = 1.05
#: default bounds of each link's mass, multiples of its URDF mass: a CAD model is rarely off by more
#: than a factor 2 (cables, hoses, a motor not drawn); wider, the consistent set lets a link that the
#: data see only in combinations take several times its mass (a heavy robot: 5x and 11x)
MASS_BOUNDS = (0.4, 2.5)
#: default bounds of the moving links' total mass, multiples of the URDF's total
TOTAL_MASS_BOUNDS = (0.67, 1.5)
#: log sources whose torques the drives compute from their motor currents (a KR C4's
#: $TORQUE_AXIS_ACT): they carry the rotors' inertia, which a link-side torque sensor (the LWR4+'s)
#: does not see; the default fit has rotor inertias for these only
MOTOR_TORQUE_SOURCES = ("kuka-trace", "kukavarproxy", "virtual-krc4", "virtual-krc4-robot")


@dataclass(frozen=True)
class RobotFitSettings:
    """Settings of :func:`fit_robot` (all stored in the parameter file).

    cutoff : low-pass cut-off of positions and torques, Hz (None: with ``choose`` and several logs one
        of :data:`CUTOFF_GRID` by held-out error against the raw torques, :func:`choose_cutoff`; else
        :data:`CUTOFF`; each at most fs/10; the file holds the value used).
    order : Butterworth order.
    decimate : keep every n-th sample after filtering (None: about 10 samples per cut-off period).
    friction : "coulomb-viscous" or "stribeck".
    vs : Stribeck velocity, rad/s (Stribeck only; fixed, so the model stays linear).
    offset : fit a constant torque per joint.
    prior_weight : weight of the divergence from the URDF's nominal links (0: none).
    consistent : physically consistent estimate (else the least-squares base parameters only).
    torque_side : "joint" (the log's torques are joint torques) or "motor" (motor-side torques,
        converted with the URDF's gear ratios and the wrist coupling).
    rotor : fit rotor inertias (one per motor) as extra parameters; None: when every log's torques come
        from the motor currents (:data:`MOTOR_TORQUE_SOURCES`). Blocks of one recording cannot choose
        them: within one trajectory the links' inertias take their part and extrapolate it to the
        next (the heavy-robot check, six fits: block errors with and without them within 4 % of each
        other; on the other recordings 9.6 % mean with them against 10.8 % without).
    spring : a torque linear in the joint's own angle, ``k_j q_j`` (N·m/rad): what cables, hoses,
        a balancing spring or a torque sensor's cross-talk add, and what a gravity model that is
        slightly off leaves (with the offset: its first-order term about the working range).
    ripple : harmonics per revolution of a torque periodic in the joint's own angle,
        ``sum_k a_k cos(k q_j) + b_k sin(k q_j)``, k = 1..ripple (N·m; 0: none): what a torque
        sensor's or a gear's position-dependent error adds (the LWR4+'s A6 shows ``cos 4 q``).
    weighting : per-joint weights of the equations: "noise" (1 / the residual standard deviation
        of a first least-squares fit) or "torque" (1 / the joint's RMS torque: every joint's
        relative error counts alike) or "none".
    v_smooth : Coulomb friction as ``Fc tanh(qd / v_smooth)``, rad/s (0: ``Fc sign(qd)``), one number
        or one per joint; None: chosen per joint by held-out error among :data:`SMOOTH_GRID` (the
        file holds the values chosen).
    deadband : the Coulomb term is 0 at speeds below it, rad/s (one number or one per joint; see
        :func:`kukaid.models.robot.smooth_sign`); None: :data:`NOISE_DEADBAND` times the joint's
        velocity noise, estimated from the positions, so a joint at rest is not given ``±Fc`` by
        the sign of its noise (the file holds the values used).
    reversal_window : a joint's equations closer than this many cut-off periods to a reversal of
        its velocity or to a stop (slower than :data:`STANDSTILL`) are not fitted (0: all are).
    mass_bounds : (low, high) every link's mass within these multiples of its URDF mass (None: no
        bound). The consistent set alone lets a link take several times its mass where the data
        see only combinations (a 339 kg link fitted at 1.7 to 3.8 t on a heavy robot).
    total_mass_bounds : (low, high) the moving links' total mass within these multiples of the
        URDF's total (None: no bound).
    choose : choose per joint, by held-out error on the user's own recordings (each recording left
        out in turn, or :data:`FOLDS` blocks of one): the Coulomb transition velocity (when
        ``v_smooth`` is None; else the given one), the ripple harmonics (0, ``ripple // 2`` or
        ``ripple``) and whether the spring term is in (when ``spring``); those left out are held
        at 0. False: ``ripple`` and ``spring`` as given, ``v_smooth`` None = the dead-band only.
    viscous_beyond : "hold" (the viscous term's velocity held within the velocities the fit saw,
        per joint and direction: the fit knows the friction curve only there; on the LWR4+ the
        friction flattens at higher speeds, where a straight line over-predicts it by up to 2x) or
        "linear" (extrapolated).
    """

    cutoff: float | None = None
    order: int = 4
    decimate: int | None = None
    friction: str = "coulomb-viscous"
    vs: float = 0.05
    offset: bool = True
    prior_weight: float = PRIOR_WEIGHT
    consistent: bool = True
    torque_side: str = "joint"
    rotor: bool | None = None
    reversal_window: float = 2.0
    v_smooth: float | tuple[float, ...] | None = None
    deadband: float | tuple[float, ...] | None = None
    weighting: str = "noise"
    spring: bool = True
    ripple: int = RIPPLE
    mass_bounds: tuple[float, float] | None = MASS_BOUNDS
    total_mass_bounds: tuple[float, float] | None = TOTAL_MASS_BOUNDS
    viscous_beyond: str = "hold"
    choose: bool = True

    def __post_init__(self) -> None:
        if self.viscous_beyond not in ("hold", "linear"):
            raise FitError(f"viscous_beyond '{self.viscous_beyond}': expected hold or linear")
        for name in ("v_smooth", "deadband"):
            val = getattr(self, name)
            if val is None:
                continue
            try:
                vv = np.atleast_1d(np.asarray(val, float))
            except (TypeError, ValueError):
                vv = np.array([np.nan])
            if vv.ndim != 1 or not np.all(np.isfinite(vv)) or np.any(vv < 0):
                raise FitError(f"{name} must be a number >= 0 or one per joint, got {val!r}")
            object.__setattr__(self, name, float(vv[0]) if np.ndim(val) == 0 else tuple(vv.tolist()))
        for name in ("mass_bounds", "total_mass_bounds"):
            v = getattr(self, name)
            if v is None:
                continue
            try:
                lo, hi = (float(x) for x in v)
            except (TypeError, ValueError):
                raise FitError(f"{name} must be two numbers (low, high) or None, got {v!r}") from None
            if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < 1 < hi):
                raise FitError(f"{name} must be (low, high) with 0 < low < 1 < high, got {v!r}")
            object.__setattr__(self, name, (lo, hi))
        if self.friction not in FRICTION_MODELS:
            raise FitError(f"friction model '{self.friction}': expected one of {', '.join(FRICTION_MODELS)}")
        for name, v in (("cutoff", self.cutoff), ("vs", self.vs)):
            if v is not None and not (math.isfinite(v) and v > 0):
                raise FitError(f"{name} must be a finite number > 0, got {v}")
        if not (math.isfinite(self.prior_weight) and self.prior_weight >= 0):
            raise FitError(f"prior weight must be a finite number >= 0, got {self.prior_weight}")
        if self.weighting not in ("noise", "torque", "none"):
            raise FitError(f"weighting '{self.weighting}': expected noise, torque or none")
        if not (isinstance(self.ripple, int) and 0 <= self.ripple <= 12):
            raise FitError(f"ripple harmonics must be an integer 0 to 12, got {self.ripple}")
        if self.torque_side not in ("joint", "motor"):
            raise FitError(f"torque side '{self.torque_side}': expected joint or motor")


@dataclass(frozen=True)
class Motion:
    """Filtered signals of one or more logs: positions (N, n) rad, velocities rad/s,
    accelerations rad/s², joint torques N·m."""

    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    tau: np.ndarray
    keep: np.ndarray | None = None      # (N, n) bool: the joint's equation is fitted at that sample
    log_rows: tuple[int, ...] | None = None    # rows of each log, in order
    qd_noise: np.ndarray | None = None  # (n,) standard deviation of the velocity's noise, rad/s
    tau_raw: np.ndarray | None = None   # (N, n) the joint torques unfiltered (the cut-off's common target)


def away_from_reversals(qd: np.ndarray, time: np.ndarray, window: float, standstill: float = 0.0) -> np.ndarray:
    """(N, n) mask: True where joint j's velocity has not changed sign within ``window`` s, is not
    under ``standstill`` rad/s and has not stopped within ``window`` s.

    Near a reversal the low-pass filter smears the Coulomb step of the measured torque over about
    one cut-off period while ``sign(qd)`` steps at once; in and near a stop the joint stands or sticks
    and its friction is static, any torque up to the breakaway force, no function of the velocity
    (see :data:`STANDSTILL`); those equations are left out."""
    keep = np.ones(qd.shape, bool)
    if window <= 0:
        return keep
    for j in range(qd.shape[1]):
        s = np.signbit(qd[:, j])
        idx = np.flatnonzero(s[1:] != s[:-1])
        slow = np.abs(qd[:, j]) < standstill
        keep[:, j] = ~slow
        # a stop: slower than ``standstill`` and either going on the same way (a joint that sticks and
        # slips) or for longer than the window (standing); its samples are events, so the window
        # counts from its edges. A passage through zero shorter than the window is a reversal's: the
        # window about its zero crossing covers it
        d = np.diff(np.concatenate([[0], slow.astype(np.int8), [0]]))
        for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)):
            if (0 < a and b < s.size and s[a - 1] == s[b]) or time[b - 1] - time[a] > window:
                idx = np.union1d(idx, np.arange(a, b))
        if idx.size == 0:
            continue
        tc = time[idx]
        pos = np.searchsorted(tc, time)
        near = np.full(time.size, np.inf)
        for off in (-1, 0):
            k = np.clip(pos + off, 0, tc.size - 1)
            near = np.minimum(near, np.abs(time - tc[k]))
        keep[:, j] &= near > window
    return keep


def _joint_columns(log: AxisLog, n: int) -> list[int]:
    where = log.attrs.get("source_file", "axis log")
    missing = [a for a in range(1, n + 1) if a not in log.axes]
    if missing:
        raise FitError(f"{where}: the robot has {n} axes but the log lacks "
                       f"{', '.join(f'A{a}' for a in missing)} (axes: {list(log.axes)})")
    extra = [a for a in log.axes if not 1 <= a <= n]
    if extra:  # a log of another robot: its other axes would be silently dropped
        raise FitError(f"{where}: the log holds {len(log.axes)} axes but the robot has {n} (A1..A{n}); "
                       f"{', '.join(f'A{a}' for a in extra)} would be ignored: use the robot the log was "
                       "recorded on")
    return [log.index(a) for a in range(1, n + 1)]


#: a joint torque beyond this many times the URDF's effort limit is a unit mistake, not a robot
EFFORT_FACTOR = 10.0


def check_torque_scale(log: AxisLog, robot: RobotModel) -> None:
    """Refuse a log whose torques are far beyond the robot's effort limits (FitError naming the
    joint): N·mm or another unit in a column the CSV names N·m fits without complaint and gives a
    model 1000 times too strong (validated at 99.9 % relative error). Joints without a limit in the
    URDF are not checked.  A log of another robot (other axes) is said first: its torques against
    this URDF's limits would read as a unit mistake."""
    where = log.attrs.get("source_file", "axis log")
    _joint_columns(log, robot.n)
    effort = np.asarray(robot.effort, float)
    for j in range(min(robot.n, effort.size)):
        a = j + 1
        if a not in log.axes or not (np.isfinite(effort[j]) and effort[j] > 0):
            continue
        peak = float(np.max(np.abs(log.channel("tau", a)))) if log.n_samples else 0.0
        if peak > EFFORT_FACTOR * effort[j]:
            raise FitError(f"{where}: the torque of A{a} reaches {peak:.4g} N·m, {peak / effort[j]:.0f} x the effort "
                           f"limit of its joint in {Path(robot.path).name} ({effort[j]:g} N·m): wrong unit (N·mm, "
                           "or a torque in another unit under a column named N·m)?")


#: every joint that carries weight measuring under this fraction of the torque the URDF's gravity
#: alone needs at the logged positions is a unit mistake (kN·m), not a robot
GRAVITY_FACTOR = 0.05


def check_torque_size(log: AxisLog, robot: RobotModel, drive: DriveModel, torque_side: str = "joint",
                      samples: int = 200) -> None:
    """Refuse a log whose torques are far below what the URDF's gravity needs where the log holds
    the arm (FitError naming the joint that carries most): torques in kN·m under a column named N·m
    fitted every link's mass to 0.00 x the URDF's without a word (the mass bounds, 560 % held-out
    error, released). Joints that carry under 5 % of the most loaded joint's gravity are not judged
    (a counterbalanced or vertical axis); ``samples`` positions, evenly spread, are enough."""
    cols = _joint_columns(log, robot.n)
    rows = np.unique(np.linspace(0, log.n_samples - 1, min(samples, log.n_samples)).astype(int))
    q = log.q[rows][:, cols]
    g = robot.rnea(q, np.zeros_like(q), np.zeros_like(q))
    tau = log.tau[rows][:, cols]
    tau = drive.joint_torque(tau) if torque_side == "motor" else tau
    g_rms, t_rms = np.sqrt(np.mean(g ** 2, axis=0)), np.sqrt(np.mean(tau ** 2, axis=0))
    if not g_rms.max() > 0:
        return
    carry = g_rms >= 0.05 * g_rms.max()
    if np.max(t_rms[carry] / g_rms[carry]) < GRAVITY_FACTOR:
        j = int(np.argmax(g_rms))
        raise FitError(f"{log.attrs.get('source_file', 'axis log')}: the torques are far below what the gravity of "
                       f"{Path(robot.path).name}'s links needs at the logged positions (A{j + 1}: RMS {t_rms[j]:.3g} "
                       f"N·m against {g_rms[j]:.3g} N·m; every joint that carries weight under {GRAVITY_FACTOR:g} x): "
                       "wrong unit (kN·m, or a torque in another unit under a column named N·m), or another robot's "
                       "URDF?")


def _cutoff(settings: RobotFitSettings, fs: float) -> float:
    fc = settings.cutoff if settings.cutoff is not None else CUTOFF
    return min(fc, 0.1 * fs) if settings.cutoff is None else fc


def motion(log: AxisLog, n: int, settings: RobotFitSettings, drive: DriveModel | None = None,
           filter_tau: bool = True, rows: slice = slice(None), reversal_window: float | None = None,
           raw: bool = False) -> Motion:
    """Filtered positions, their derivatives and the (filtered) joint torques of axes A1..An.

    ``rows``: the samples to return (after filtering and differentiating the whole log);
    ``reversal_window`` (s): also mark the samples away from the joint's velocity reversals and stops
    (:func:`away_from_reversals`) in ``keep``. The log is processed one joint at a time, so the
    memory beyond the returned rows is a few single-column arrays whatever the log's length.
    ``raw``: also the unfiltered joint torques at those rows (``tau_raw``)."""
    from scipy.signal import butter, sosfiltfilt

    cols = _joint_columns(log, n)
    where = log.attrs.get("source_file", "axis log")
    check_even_samples(log.time, where, log.attrs)
    fs = 1.0 / log.sample_time
    fc = _cutoff(settings, fs)
    if fc >= 0.45 * fs:  # as the one-axis fit: a Butterworth this close to Nyquist hardly filters
        raise FitError(f"{where}: filter cut-off {fc:g} Hz must be in (0, {0.45 * fs:.4g}) Hz (0.9 x Nyquist at "
                       f"{fs:.4g} Hz)")
    sos = butter(settings.order, fc, fs=fs, output="sos")
    need = 3 * (2 * sos.shape[0] + 1)
    if log.n_samples <= need:
        raise FitError(f"{where}: {log.n_samples} samples are too few to filter (need more than {need})")
    stamps = log.time  # the reversal windows, in seconds, as the stamps say
    log = evenly_sampled(log, cols)[0]
    t = log.time
    idx = np.arange(log.n_samples)[rows]
    out = {k: np.empty((idx.size, n)) for k in ("q", "qd", "qdd", "tau") + (("tau_raw",) if raw else ())}
    keep = np.ones((idx.size, n), bool) if reversal_window is not None else None
    G = drive.G if settings.torque_side == "motor" and drive is not None else None
    gain = _velocity_noise_gain(sos, float(np.median(np.diff(t))), log.n_samples)
    qd_noise = np.zeros(n)
    for j, c in enumerate(cols):
        qd_noise[j] = gain * position_noise(log.q[:, c])
        qj = sosfiltfilt(sos, log.q[:, c])
        qdj = np.gradient(qj, t)
        out["q"][:, j] = qj[rows]
        out["qd"][:, j] = qdj[rows]
        out["qdd"][:, j] = np.gradient(qdj, t)[rows]
        if keep is not None:
            keep[:, j] = away_from_reversals(qdj[:, None], stamps, reversal_window, STANDSTILL)[rows, 0]
        del qj, qdj
        if G is None:
            tj = log.tau[:, c]
        else:  # joint torque = G^T motor torques
            tj = sum(log.tau[:, ck] * G[k, j] for k, ck in enumerate(cols) if G[k, j] != 0.0)
            tj = tj if isinstance(tj, np.ndarray) else np.zeros(log.n_samples)
        out["tau"][:, j] = (sosfiltfilt(sos, tj) if filter_tau else tj)[rows]
        if raw:
            out["tau_raw"][:, j] = tj[rows]
    return Motion(out["q"], out["qd"], out["qdd"], out["tau"], keep, (idx.size,), qd_noise, out.get("tau_raw"))


def filtered_coulomb(log: AxisLog, n: int, settings: RobotFitSettings, rows: slice = slice(None),
                     v_smooth: Sequence[float] | None = None, velocity_cutoff: float | None = None) -> np.ndarray:
    """The Coulomb column of each joint as the filtered torque shows it: ``tanh(qd / v)`` (the sign
    where ``v`` is 0, with the settings' dead-band) on every sample of the log, through the fit's
    low-pass; (N, n), or (N, n, V) for ``v_smooth`` a list of V transition velocities (rad/s, each
    for every joint; default: the settings' per joint).

    Parallel filtering is exact for the terms linear in the signals; the Coulomb step is not: the
    measured torque's step at a reversal is smeared by the filter over about a cut-off period while
    the sign of the filtered velocity steps at once (see ``docs/robot.md``, the robot diagnosis).
    ``velocity_cutoff``: the low-pass of the positions the velocity is taken from, Hz (default the
    fit's cut-off; a wider band shows a stop as it happens). ``rows``: the samples to return."""
    from scipy.signal import butter, sosfiltfilt

    cols = _joint_columns(log, n)
    fs = 1.0 / log.sample_time
    sos = fit_lowpass(log, settings)
    vc = _cutoff(settings, fs) if velocity_cutoff is None else min(float(velocity_cutoff), 0.45 * fs)
    sv = butter(settings.order, vc, fs=fs, output="sos")
    log = evenly_sampled(log, cols)[0]
    t = log.time
    many = v_smooth is not None
    vs = np.asarray(v_smooth, float)[:, None] * np.ones(n) if many else \
        np.broadcast_to(np.asarray(settings.v_smooth or 0.0, float), (n,))[None, :]
    d = np.broadcast_to(np.asarray(settings.deadband or 0.0, float), (n,))
    idx = np.arange(log.n_samples)[rows]
    out = np.empty((idx.size, n, vs.shape[0]))
    for j, c in enumerate(cols):
        qdj = np.gradient(sosfiltfilt(sv, log.q[:, c]), t)
        for k in range(vs.shape[0]):
            out[:, j, k] = sosfiltfilt(sos, smooth_sign(qdj[:, None], vs[k, j:j + 1], d[j:j + 1])[:, 0])[rows]
    return out if many else out[:, :, 0]


def wide_velocity(log: AxisLog, n: int, settings: RobotFitSettings, velocity_cutoff: float) -> np.ndarray:
    """(M, n) rad/s: every joint's velocity on every sample of the log, differentiated from its
    positions through a low-pass at ``velocity_cutoff`` Hz (at most 0.45 of the sample rate), the
    velocity :func:`filtered_coulomb` switches on."""
    from scipy.signal import butter, sosfiltfilt

    cols = _joint_columns(log, n)
    fs = 1.0 / log.sample_time
    sv = butter(settings.order, min(float(velocity_cutoff), 0.45 * fs), fs=fs, output="sos")
    log = evenly_sampled(log, cols)[0]
    t = log.time
    return np.column_stack([np.gradient(sosfiltfilt(sv, log.q[:, c]), t) for c in cols])


def lowpassed_values(log: AxisLog, settings: RobotFitSettings, values: np.ndarray, rows: slice = slice(None),
                     sos: np.ndarray | None = None) -> np.ndarray:
    """``values`` (M, ...) on every sample of the log through the fit's low-pass (along the
    samples), at the rows ``rows``: a term nonlinear in the signals compared as the filtered torque
    shows it. ``sos``: the filter (:func:`fit_lowpass`), when the caller keeps it (designing it
    takes longer than filtering a 10 s log)."""
    from scipy.signal import sosfiltfilt

    return sosfiltfilt(fit_lowpass(log, settings) if sos is None else sos, values, axis=0)[rows]


class ZeroPhaseLowPass:
    """``scipy.signal.sosfiltfilt(sos, x, axis=0)`` (odd padding of the default length) with what
    depends on the filter alone worked out once: the steady-state initial conditions
    (``sosfilt_zi``) cost a third of each call's time on a 10 s log, and the robot diagnosis
    filters its candidates' columns thousands of times with one filter per log. The same
    operations in the same order: the same result to the bit."""

    def __init__(self, sos: np.ndarray) -> None:
        from scipy.signal import sosfilt_zi

        self.sos = np.asarray(sos, float)
        k = self.sos.shape[0]
        ntaps = 2 * k + 1 - min(int((self.sos[:, 2] == 0).sum()), int((self.sos[:, 5] == 0).sum()))
        self.edge = 3 * ntaps
        self.zi = sosfilt_zi(self.sos)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        from scipy.signal import sosfilt, sosfiltfilt

        x = np.asarray(x)
        e = self.edge
        if x.ndim == 0 or x.shape[0] <= e:      # scipy says what is wrong
            return sosfiltfilt(self.sos, x, axis=0)
        # odd extension at both ends (scipy.signal._arraytools.odd_ext along axis 0)
        ext = np.concatenate((2 * x[0:1] - x[e:0:-1], x, 2 * x[-1:] - x[-2:-(e + 2):-1]), axis=0)
        zi = self.zi.reshape([self.sos.shape[0], 2] + [1] * (x.ndim - 1))
        y, _ = sosfilt(self.sos, ext, axis=0, zi=zi * ext[0:1])
        y, _ = sosfilt(self.sos, y[::-1], axis=0, zi=zi * y[-1:])
        return y[::-1][e:-e]


def fit_lowpass(log: AxisLog, settings: RobotFitSettings) -> np.ndarray:
    """The fit's low-pass of the log's torques and positions (second-order sections)."""
    from scipy.signal import butter

    fs = 1.0 / log.sample_time
    return butter(settings.order, _cutoff(settings, fs), fs=fs, output="sos")


def position_noise(q: np.ndarray) -> float:
    """Standard deviation of the white noise on a position signal, from its fourth differences
    (robust: 1.4826 x their median absolute deviation / sqrt(70)); a smooth motion's fourth
    differences are orders of magnitude smaller, so what is left is the encoder's noise and
    quantisation."""
    d4 = np.diff(np.asarray(q, float), 4)
    if d4.size < 5:
        return 0.0
    return float(1.4826 * np.median(np.abs(d4 - np.median(d4))) / math.sqrt(70.0))


def _velocity_noise_gain(sos: np.ndarray, dt: float, n: int) -> float:
    """Standard deviation of the filtered, differentiated velocity per unit white position noise."""
    from scipy.signal import sosfiltfilt

    w = np.random.default_rng(0).standard_normal(min(max(n, 64), 4096))
    v = np.gradient(sosfiltfilt(sos, w), dt)
    k = v.size // 8
    return float(np.std(v[k: v.size - k]))


def sample_rows(log: AxisLog, settings: RobotFitSettings) -> slice:
    """The rows of ``log`` the fit uses: two cut-off periods trimmed at each end, then every
    ``decimate``-th sample (default: about 10 samples per cut-off period, and at most 10 x
    :data:`CUTOFF` = 100 equations per second: above a 10 Hz cut-off the equations stay more than 5
    per cut-off period, 2.5 x the filtered signals' Nyquist rate, and the fit costs what the 10 Hz
    default does; at 20 Hz and 250 Hz every second sample, not every one)."""
    fs = 1.0 / log.sample_time
    fc = _cutoff(settings, fs)
    edge = int(math.ceil(2.0 * fs / fc))                     # two cut-off periods at each end
    return slice(edge, max(log.n_samples - edge, edge), _step(settings, fs))


def _step(settings: RobotFitSettings, fs: float) -> int:
    """Every how many samples of a log at ``fs`` Hz the fit takes an equation (:func:`sample_rows`)."""
    return settings.decimate or max(1, int(round(fs / (10.0 * min(_cutoff(settings, fs), CUTOFF)))))


def _samples(logs: Sequence[AxisLog], n: int, settings: RobotFitSettings, drive: DriveModel,
             raw: bool = False) -> Motion:
    parts = []
    for log in logs:
        fc = _cutoff(settings, 1.0 / log.sample_time)
        rows = sample_rows(log, settings)
        parts.append(motion(log, n, settings, drive, rows=rows, reversal_window=settings.reversal_window * 1.0 / fc,
                            raw=raw))
    if len(parts) == 1:
        out = parts[0]
    else:
        out = Motion(*(np.concatenate([getattr(p, k) for p in parts]) for k in ("q", "qd", "qdd", "tau", "keep")),
                     tuple(p.q.shape[0] for p in parts), np.max([p.qd_noise for p in parts], axis=0),
                     np.concatenate([p.tau_raw for p in parts]) if raw else None)
    if out.q.shape[0] < 10:
        names = ", ".join(str(log.attrs.get("source_file", "axis log")) for log in logs)
        fcs = sorted({f"{_cutoff(settings, 1.0 / log.sample_time):g}" for log in logs})
        raise FitError(f"{names}: too few samples left ({out.q.shape[0]}) after trimming two periods of the filter "
                       f"cut-off {' / '.join(fcs)} Hz at each end and decimating: give "
                       + (f"a smaller --decimate (now {settings.decimate}), " if settings.decimate else "")
                       + "a longer log or a higher cut-off")
    return out


def _drive(robot: RobotModel, settings: RobotFitSettings, coupling: np.ndarray | None = None) -> DriveModel:
    if settings.torque_side == "joint" and not settings.rotor:
        return DriveModel.direct(robot.n)
    return DriveModel(robot.ratio.copy(), np.zeros((robot.n, robot.n)) if coupling is None else coupling,
                      np.zeros(robot.n))


def design(robot: RobotModel, m: Motion, settings: RobotFitSettings, drive: DriveModel) -> tuple[np.ndarray, np.ndarray]:
    """Rigid-body regressor (N, n, 10 n) and the extra columns (N, n, k): friction, offset, rotors."""
    return robot.regressor(m.q, m.qd, m.qdd), extras(robot, m, settings, drive)


def extras(robot: RobotModel, m: Motion, settings: RobotFitSettings, drive: DriveModel,
           v_smooth=None, qd_range: np.ndarray | None = None) -> np.ndarray:
    """The extra columns (N, n, k): friction, offset, spring, ripple, rotors (``v_smooth``: instead
    of the settings'; ``qd_range`` (n, 2): the viscous term's velocity held within it)."""
    v = settings.v_smooth if v_smooth is None else v_smooth
    F = friction_regressor(m.qd, settings.friction, settings.offset, settings.vs, v_smooth=0.0 if v is None else v,
                           qd_range=qd_range, deadband=settings.deadband or 0.0)
    n = robot.n
    if settings.spring:
        P = np.zeros((m.q.shape[0], n, n))
        P[:, np.arange(n), np.arange(n)] = m.q
        F = np.concatenate([F, P], axis=2)
    if settings.ripple:
        F = np.concatenate([F, ripple_regressor(m.q, settings.ripple)], axis=2)
    if settings.rotor:
        F = np.concatenate([F, drive.rotor_regressor(m.qdd)], axis=2)
    return F


def ripple_regressor(q: np.ndarray, harmonics: int) -> np.ndarray:
    """(N, n, 2 n K) columns of ``cos(k q_j)``, ``sin(k q_j)``, k = 1..K, each on joint j's own equation."""
    q = np.atleast_2d(np.asarray(q, float))
    N, n = q.shape
    k = np.arange(1, harmonics + 1)
    out = np.zeros((N, n, 2 * n * harmonics))
    for j in range(n):
        ph = np.outer(q[:, j], k)
        out[:, j, 2 * harmonics * j: 2 * harmonics * (j + 1)] = np.concatenate([np.cos(ph), np.sin(ph)], axis=1)
    return out


def _covered_harmonics_only(F: np.ndarray, q: np.ndarray, settings: RobotFitSettings,
                            span: np.ndarray | None = None) -> None:
    """Zero (in place) the ripple columns of harmonics whose period the joint's fitted range does not
    cover once: over a shorter arc ``cos(k q)`` and ``sin(k q)`` look like a polynomial of q, which
    the fit can use to bend the torque within the range and which then runs away outside it.
    ``span``: each joint's range over all fitted samples (default: over ``q``'s rows)."""
    K = settings.ripple
    n = q.shape[1]
    start = F.shape[2] - 2 * n * K - (n if settings.rotor else 0)     # the rotor columns come last
    span = np.ptp(q, axis=0) if span is None else span
    for j in range(n):
        for i, k in enumerate(list(range(1, K + 1)) * 2):
            if k * span[j] < 2 * np.pi:
                F[:, j, start + 2 * K * j + i] = 0.0


def ripple_names(n: int, harmonics: int) -> list[str]:
    return [f"A{j + 1}.{cs}{k}" for j in range(n) for cs in ("ripple_cos", "ripple_sin")
            for k in range(1, harmonics + 1)]


def extra_names(robot: RobotModel, settings: RobotFitSettings) -> list[str]:
    names = friction_names(robot.n, settings.friction, settings.offset)
    names += [f"A{j + 1}.k" for j in range(robot.n)] if settings.spring else []
    names += ripple_names(robot.n, settings.ripple)
    return names + ([f"M{k + 1}.rotor_inertia" for k in range(robot.n)] if settings.rotor else [])


# -- physically consistent estimate ------------------------------------------------------------------
def _upper_cholesky(J: np.ndarray) -> np.ndarray:
    """U upper-triangular with J = U U^T."""
    P = np.eye(4)[::-1]
    L = np.linalg.cholesky(P @ J @ P)
    return P @ L @ P


def _theta_of(pi10: np.ndarray) -> np.ndarray:
    """Log-Cholesky coordinates of a consistent link (nudged inside when on the boundary)."""
    J = pseudo_inertia(pi10)
    w, V = np.linalg.eigh(J)
    J = (V * np.maximum(w, 1e-6 * max(w.max(), 1e-9))) @ V.T
    U = _upper_cholesky(J)
    a = math.log(U[3, 3])
    U = U / U[3, 3]
    return np.array([a, math.log(U[0, 0]), math.log(U[1, 1]), math.log(U[2, 2]), U[0, 1], U[1, 2], U[0, 2],
                     U[0, 3], U[1, 3], U[2, 3]])


def _pi_of_theta(th):
    """CasADi: ten standard parameters of a link from its log-Cholesky coordinates."""
    import casadi as ca

    a, d1, d2, d3, s12, s23, s13, t1, t2, t3 = (th[i] for i in range(10))
    U = ca.vertcat(ca.horzcat(ca.exp(d1), s12, s13, t1), ca.horzcat(0, ca.exp(d2), s23, t2),
                   ca.horzcat(0, 0, ca.exp(d3), t3), ca.horzcat(0, 0, 0, 1)) * ca.exp(a)
    J = U @ U.T
    S = J[:3, :3]
    tr = S[0, 0] + S[1, 1] + S[2, 2]
    return ca.vertcat(J[3, 3], J[0, 3], J[1, 3], J[2, 3], tr - S[0, 0], -S[0, 1], tr - S[1, 1], -S[0, 2],
                      -S[1, 2], tr - S[2, 2]), J


#: consistent-fit solvers kept (:func:`_consistent_solver`)
SOLVERS_KEPT = 8
_SOLVERS: dict = {}


def _consistent_solver(robot: RobotModel, n_extra: int, shape: tuple, total_mass: float | None):
    """IPOPT of :func:`consistent_fit` for a robot, a number of extras, the shape of ``R`` and the
    nominal total mass (None: no constraint on it), with the prior's weight, ``R``, ``z``, ``c`` and the
    extras' ridge weights and reference its parameters (``[w, vec(R), z, c, rw, xr]``), and the function
    from its variables to the parameters: made once per thread and kept (the last :data:`SOLVERS_KEPT`).
    Building one took 0.14 s, a third of a fit's time; a fit solves it 11 times (the fit, and each fold
    with and without the mass bounds)."""
    import casadi as ca

    import threading

    key = (robot.pi_nominal.tobytes(), robot.n, int(n_extra), tuple(shape), total_mass, threading.get_ident())
    if key in _SOLVERS:
        return _SOLVERS[key]
    n = robot.n
    ts = ca.SX.sym("t", 10)
    pt, Jt = _pi_of_theta(ts)
    link = ca.Function("link", [ts], [pt, Jt])          # one link, reused: a small graph
    th = ca.MX.sym("theta", 10 * n)
    ex = ca.MX.sym("extra", n_extra)
    pis, prior = [], 0
    for k in range(n):
        p, J = link(th[10 * k: 10 * k + 10])
        pis.append(p)
        J0 = pseudo_inertia(robot.pi_nominal[10 * k: 10 * k + 10])
        w, V = np.linalg.eigh(J0)
        J0 = (V * np.maximum(w, 1e-9 * max(w.max(), 1e-9))) @ V.T
        J0inv = np.linalg.inv(J0)
        logdetJ = 2 * (4 * th[10 * k] + th[10 * k + 1] + th[10 * k + 2] + th[10 * k + 3])
        prior += ca.trace(ca.mtimes(ca.DM(J0inv), J)) - logdetJ + float(np.linalg.slogdet(J0)[1]) - 4
    p = ca.vertcat(*pis, ex)
    Rs, zs, cs = ca.MX.sym("R", *shape), ca.MX.sym("z", shape[0]), ca.MX.sym("c")
    r = ca.mtimes(Rs, p) - zs
    wp = ca.MX.sym("w")
    rw, xr = ca.MX.sym("rw", n_extra), ca.MX.sym("xr", n_extra)
    f = ca.dot(r, r) + cs + wp * prior + ca.dot(rw * (ex - xr), ex - xr)
    nlp = {"x": ca.vertcat(th, ex), "f": f, "p": ca.vertcat(wp, ca.vec(Rs), zs, cs, rw, xr)}
    if total_mass is not None:
        nlp["g"] = sum(ca.exp(2 * th[10 * k]) for k in range(n)) / total_mass
    solver = ca.nlpsol("robot_fit", "ipopt", nlp, {"ipopt.print_level": 0, "ipopt.sb": "yes", "print_time": 0, "show_eval_warnings": False,
                                                   "ipopt.max_iter": 3000, "ipopt.tol": 1e-9})
    _SOLVERS[key] = out = (solver, ca.Function("p", [th, ex], [p]))
    while len(_SOLVERS) > SOLVERS_KEPT:
        _SOLVERS.pop(next(iter(_SOLVERS)))
    return out


def consistent_fit(R: np.ndarray, z: np.ndarray, c: float, robot: RobotModel, n_extra: int,
                   nonneg: np.ndarray, prior_weight: float, pi0: np.ndarray, x0_extra: np.ndarray,
                   fixed: np.ndarray | None = None, mass_bounds: tuple[float, float] | None = None,
                   total_mass_bounds: tuple[float, float] | None = None,
                   start: np.ndarray | None = None, ridge: np.ndarray | None = None,
                   ref: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
    """Minimise ``|R p - z|^2 + c + prior_weight * sum D(J_k || J_k,nominal) + sum ridge (e - ref)^2``
    over physically consistent links (log-Cholesky) and the extra parameters ``e`` (``nonneg`` ones
    >= 0); each link's mass ``exp(2 a_k)`` within ``mass_bounds`` times its nominal mass (a bound on
    ``a_k``), their sum within ``total_mass_bounds`` times the nominal total (a constraint).
    ``ridge`` (default 0) holds extras the data do not see near ``ref`` (default ``x0_extra``).

    Returns the standard parameters (10 n,), the extra parameters and solver statistics."""
    n = robot.n
    pis0 = pi0 if start is None else start
    x0 = np.concatenate([np.concatenate([_theta_of(pis0[10 * k: 10 * k + 10]) for k in range(n)]), x0_extra])
    lbx = np.full(x0.size, -np.inf)
    lbx[10 * n:][nonneg] = 0.0
    ubx = np.full(x0.size, np.inf)
    if fixed is not None:  # extras the data cannot see: held at zero
        lbx[10 * n:][fixed] = ubx[10 * n:][fixed] = 0.0
    x0[10 * n:] = np.clip(x0[10 * n:], lbx[10 * n:], ubx[10 * n:])
    m0 = pi0[0::10]
    if mass_bounds is not None:   # a massless link (nominal 0) stays unbounded
        has = m0 > 0
        lbx[10 * np.flatnonzero(has)] = 0.5 * np.log(mass_bounds[0] * m0[has])
        ubx[10 * np.flatnonzero(has)] = 0.5 * np.log(mass_bounds[1] * m0[has])
        x0[:10 * n] = np.clip(x0[:10 * n], lbx[:10 * n], ubx[:10 * n])
    total = float(m0.sum()) if total_mass_bounds is not None and m0.sum() > 0 else None
    lbg, ubg = ([total_mass_bounds[0]], [total_mass_bounds[1]]) if total is not None else ([], [])
    solver, pfun = _consistent_solver(robot, n_extra, R.shape, total)
    ridge = np.zeros(n_extra) if ridge is None else np.asarray(ridge, float)
    ref = np.asarray(x0_extra if ref is None else ref, float)
    data = np.concatenate([np.ravel(R, order="F"), np.ravel(z), [float(c)], ridge, ref])
    # continuation: a strong prior first (near the nominal links, quick), then down to the weight
    # asked for, each solve starting at the last; the problem is convex in the pseudo-inertias, so
    # the end point is the same minimum, reached in fewer iterations
    iters = 0
    for w in ([x for x in (1e-1, 1e-2) if x > prior_weight] if start is None else []) + [prior_weight]:
        with interruptible_solve():  # Ctrl-C: KeyboardInterrupt, not a solve that "did not converge"
            sol = solver(x0=x0, lbx=lbx, ubx=ubx, p=np.concatenate([[w], data]), **({"lbg": lbg, "ubg": ubg} if lbg else {}))
        iters += int(solver.stats().get("iter_count") or 0)
        x0 = np.asarray(sol["x"]).ravel()
    stats = solver.stats()
    x = np.asarray(sol["x"]).ravel()
    pv = np.asarray(pfun(x[:10 * n], x[10 * n:])).ravel()
    info = {"solver": "ipopt", "status": stats.get("return_status"), "iterations": iters,
            "objective": float(sol["f"])}
    ok = ("Solve_Succeeded", "Solved_To_Acceptable_Level", "Maximum_Iterations_Exceeded")
    if stats.get("return_status") not in ok or not np.all(np.isfinite(pv)):
        raise FitError(f"physically consistent fit did not converge (IPOPT: {stats.get('return_status')})")
    return pv[:10 * n], pv[10 * n:], info


# -- the fit ---------------------------------------------------------------------------------------------
def _one_blas_thread():
    """Narrow products (under a hundred columns) and dot products gain nothing from BLAS threads, and on a busy
    machine OpenBLAS threads that wait for cores make them ~50 times slower: use one."""
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")


def _solve(G: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Least-squares solution of the normal equations ``G x = g`` (columns scaled first)."""
    dg = np.diag(G)
    d = np.where(dg > 0, 1.0 / np.sqrt(np.where(dg > 0, dg, 1.0)), 0.0)   # an empty column: its value 0
    x, *_ = np.linalg.lstsq(d[:, None] * G * d[None, :], d * g, rcond=1e-13)
    return d * x


#: samples per block of the regressor: (BLOCK, n, p) doubles stay a few MB whatever the log's length
BLOCK = 2048


def _blocks(m: Motion, block: int = BLOCK):
    for a in range(0, m.q.shape[0], block):
        rows = slice(a, min(a + block, m.q.shape[0]))
        yield rows, Motion(m.q[rows], m.qd[rows], m.qdd[rows], m.tau[rows],
                           None if m.keep is None else m.keep[rows])


def _block_columns(robot: RobotModel, mb: Motion, settings: RobotFitSettings, drive: DriveModel,
                   span: np.ndarray) -> np.ndarray:
    """(B, n, 10 n + k): the rigid-body and extra columns of one block of samples."""
    Y, F = design(robot, mb, settings, drive)
    if settings.ripple:
        _covered_harmonics_only(F, mb.q, settings, span)
    return np.concatenate([Y, F], axis=2)


def _active_columns(robot: RobotModel, settings: RobotFitSettings, drive: DriveModel) -> list[np.ndarray]:
    """Per joint, the columns (standard parameters, then extras) its equation can touch: the links
    from the joint out, its own friction, spring and ripple, the rotors coupled to it (structural:
    from the regressor at a few random states)."""
    n = robot.n
    rng = np.random.default_rng(0)
    x = [rng.uniform(-1.0, 1.0, (6, n)) for _ in range(3)]
    mb = Motion(x[0], x[1], x[2], np.zeros((6, n)))
    Y, F = robot.regressor(mb.q, mb.qd, mb.qdd), extras(robot, mb, settings, drive, v_smooth=1.0)
    nz = np.any(np.concatenate([Y, F], axis=2) != 0, axis=0)
    return [np.flatnonzero(nz[j]) for j in range(n)]


def folded_rotors(robot: RobotModel, drive: DriveModel, base, samples: int = 200,
                  rtol: float = 1e-8) -> list[tuple[int, np.ndarray]]:
    """The motors (0-based, each with its (b,) coefficients ``x``: per kg·m² of its rotor, the base
    parameters grow by ``x``) whose rotor-inertia column is a combination of the base parameters' columns
    at every state: the rotor of a joint whose link inertia about the
    joint's axis shows only in that joint's own equation, as A1's (``ratio² qdd1``, as link 1's
    ``Izz``) and, with A2's axis across A1's, A2's. The data cannot split such a rotor from the base
    parameters: fitted as a column of its own it left those base parameters without a sigma (NaN,
    a null direction) and their split arbitrary. Folded, it is held at 0 and the base parameters
    that hold that link inertia carry it (their value is the sum). Found as
    :meth:`RobotModel.base_parameters` finds the base parameters: at random states."""
    rng = np.random.default_rng(1)
    n = robot.n
    lo = np.where(np.isfinite(robot.lower) & (robot.lower > -1e10), robot.lower, -np.pi)
    hi = np.where(np.isfinite(robot.upper) & (robot.upper < 1e10), robot.upper, np.pi)
    q = rng.uniform(lo, hi, (samples, n))
    qdd = rng.standard_normal((samples, n))
    Y = robot.regressor(q, rng.standard_normal((samples, n)), qdd)[:, :, base.independent].reshape(-1, base.size)
    R = drive.rotor_regressor(qdd).reshape(-1, n)
    out = []
    for k in range(n):
        c = R[:, k]
        if not np.any(c):
            continue
        x, *_ = np.linalg.lstsq(Y, c, rcond=None)
        if np.linalg.norm(c - Y @ x) <= rtol * np.linalg.norm(c):
            out.append((k, np.where(np.abs(x) > 1e-9 * np.abs(x).max(), x, 0.0)))
    return out


@dataclass
class FoldEquations:
    """Per-joint normal equations per candidate transition velocity and per fold, compact: joint j
    over its active columns ``act[j]`` only.

    train[j] : (V, K, a_j, a_j) over the samples fitted (away from reversals); tg[j] : (V, K, a_j)
    rest[j], rg[j] : the same over the samples not fitted (train + rest: all samples, to evaluate)
    tc, rc : (K, n) sums of the squared torques, fitted and not fitted.
    used : (k,) the extra columns that are nonzero somewhere.
    tn, rn : (K, n) numbers of samples fitted and not fitted.
    xg[j] : (V, K, a_j), xc : (K, n) the columns against the raw (unfiltered) torques and the raw
    torques' sums of squares, over every sample (when the motion carries ``tau_raw``; else None):
    the common target the cut-offs are compared on (:func:`choose_cutoff`).
    """

    act: list
    train: list
    tg: list
    rest: list
    rg: list
    tc: np.ndarray
    rc: np.ndarray
    used: np.ndarray
    tn: np.ndarray
    rn: np.ndarray
    xg: list | None = None
    xc: np.ndarray | None = None

    def full(self, p: int, v: Sequence[int] | None = None, folds: Sequence[int] | None = None,
             evaluate: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """G (n, p, p), g (n, p), c (n,): joint j's equations at candidate ``v[j]`` (default 0),
        summed over ``folds`` (default all); ``evaluate``: all samples, not only those fitted."""
        n = len(self.act)
        v = [0] * n if v is None else list(v)
        f = slice(None) if folds is None else list(folds)
        G, g = np.zeros((n, p, p)), np.zeros((n, p))
        for j, a in enumerate(self.act):
            Gj, gj = self.train[j][v[j]][f].sum(0), self.tg[j][v[j]][f].sum(0)
            if evaluate:
                Gj, gj = Gj + self.rest[j][v[j]][f].sum(0), gj + self.rg[j][v[j]][f].sum(0)
            G[j][np.ix_(a, a)] = Gj
            g[j, a] = gj
        c = self.tc[f].sum(0) + (self.rc[f].sum(0) if evaluate else 0.0)
        return G, g, c


def fold_equations(robot: RobotModel, m: Motion, settings: RobotFitSettings, drive: DriveModel,
                   smooth: np.ndarray, folds: np.ndarray, n_folds: int, block: int = BLOCK) -> FoldEquations:
    """Normal equations accumulated block by block (never the (N, n, p) regressor), for each row of
    ``smooth`` (V, n) (Coulomb transition velocities per joint) and each fold (``folds``: (N,) fold
    of each sample). The rigid-body block of each joint's equations is computed once for all
    candidates; only the extra columns change with the transition velocity."""
    n = robot.n
    span = np.ptp(m.q, axis=0)
    act = _active_columns(robot, settings, drive)
    V, K = smooth.shape[0], n_folds
    ay = [a[a < robot.n_std] for a in act]
    af = [a[a >= robot.n_std] - robot.n_std for a in act]
    train = [np.zeros((V, K, a.size, a.size)) for a in act]
    rest = [np.zeros((V, K, a.size, a.size)) for a in act]
    tg = [np.zeros((V, K, a.size)) for a in act]
    rg = [np.zeros((V, K, a.size)) for a in act]
    tc, rc = np.zeros((K, n)), np.zeros((K, n))
    tn, rn = np.zeros((K, n)), np.zeros((K, n))
    raw = m.tau_raw is not None
    xg = [np.zeros((V, K, a.size)) for a in act] if raw else None
    xc = np.zeros((K, n)) if raw else None
    used = None
    # blocks that do not straddle a fold boundary
    edges = np.flatnonzero(np.diff(folds)) + 1
    starts = np.concatenate([[0], edges]).astype(int)
    stops = np.concatenate([edges, [folds.size]]).astype(int)
    with _one_blas_thread():
        for s0, s1 in zip(starts, stops):
            f = int(folds[s0])
            for a0 in range(s0, s1, block):
                rows = slice(a0, min(a0 + block, s1))
                mb = Motion(m.q[rows], m.qd[rows], m.qdd[rows], m.tau[rows], m.keep[rows])
                Y = robot.regressor(mb.q, mb.qd, mb.qdd)
                F0 = extras(robot, mb, settings, drive, v_smooth=smooth[0])
                if settings.ripple:
                    _covered_harmonics_only(F0, mb.q, settings, span)
                Fs = [F0] + [_with_coulomb(F0, mb.qd, settings, smooth[v]) for v in range(1, V)]
                for F in Fs:
                    u = np.any(F != 0, axis=(0, 1))
                    used = u if used is None else used | u
                kw = mb.keep.astype(float)
                tn[f] += kw.sum(axis=0)
                rn[f] += (1.0 - kw).sum(axis=0)
                for j in range(n):
                    t = mb.tau[:, j]
                    for wt, G, g, c in ((kw[:, j], train, tg, tc), (1.0 - kw[:, j], rest, rg, rc)):
                        if not np.any(wt):
                            continue
                        Yj = Y[:, j, ay[j]]
                        Yw = Yj * wt[:, None]
                        YY, Yt = Yw.T @ Yj, Yw.T @ t
                        c[f, j] += float((t * wt) @ t)
                        ny = ay[j].size
                        for v in range(V):
                            Fj = Fs[v][:, j, af[j]]
                            Gv = G[j][v, f]
                            Gv[:ny, :ny] += YY
                            YF = Yw.T @ Fj
                            Gv[:ny, ny:] += YF
                            Gv[ny:, :ny] += YF.T
                            Gv[ny:, ny:] += (Fj * wt[:, None]).T @ Fj
                            g[j][v, f, :ny] += Yt
                            g[j][v, f, ny:] += Fj.T @ (t * wt)
                    if raw:
                        r = m.tau_raw[rows, j]
                        xc[f, j] += float(r @ r)
                        Yr = Y[:, j, ay[j]].T @ r
                        for v in range(V):
                            xg[j][v, f, :ay[j].size] += Yr
                            xg[j][v, f, ay[j].size:] += Fs[v][:, j, af[j]].T @ r
    return FoldEquations(act, train, tg, rest, rg, tc, rc, used, tn, rn, xg, xc)


def _with_coulomb(F: np.ndarray, qd: np.ndarray, settings: RobotFitSettings, v_smooth) -> np.ndarray:
    """A copy of the extra columns ``F`` with the Coulomb (and Stribeck) columns at another transition
    velocity: the only columns that depend on it (the friction block comes first, ``nf`` per joint)."""
    n = qd.shape[1]
    out = F.copy()
    sgn = smooth_sign(qd, v_smooth, settings.deadband or 0.0)
    nf = 2 + (settings.friction == "stribeck") + bool(settings.offset)
    for j in range(n):
        out[:, j, j * nf] = sgn[:, j]
        if settings.friction == "stribeck":
            vs = np.broadcast_to(np.asarray(settings.vs, float), (n,))
            out[:, j, j * nf + 2] = sgn[:, j] * np.exp(-np.abs(qd[:, j] / vs[j]) ** 2.0)
    return out


def normal_equations(robot: RobotModel, m: Motion, settings: RobotFitSettings, drive: DriveModel,
                     block: int = BLOCK) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-joint normal equations of all columns over the samples ``m.keep`` marks:
    ``G[j] = sum_s C_sj^T C_sj``, ``g[j] = sum_s C_sj^T tau_sj`` (C: the standard-parameter and extra
    columns, the settings' ``v_smooth``), accumulated block by block; joint j's equation only
    touches its nonzero columns (the links from j out, its own friction), so each block costs a
    fraction of the full products.

    Returns G (n, p, p), g (n, p) and which extra columns are nonzero anywhere (k,)."""
    v = np.broadcast_to(np.asarray(settings.v_smooth or 0.0, float), (robot.n,))[None, :]
    fe = fold_equations(robot, m, settings, drive, v, np.zeros(m.q.shape[0], int), 1, block)
    G, g, _ = fe.full(robot.n_std + fe.used.size)
    return G, g, fe.used


def _solve_quick(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``A x = b`` for a symmetric positive semi-definite ``A`` (columns scaled, a tiny ridge, Cholesky);
    a zero column's value is 0. For the many small solves of the held-out choices."""
    from scipy.linalg import cho_factor, cho_solve

    dg = np.diag(A)
    live = dg > 0
    x = np.zeros(b.size)
    if not live.any():
        return x
    d = 1.0 / np.sqrt(dg[live])
    As = d[:, None] * A[np.ix_(live, live)] * d[None, :]
    try:
        x[live] = d * cho_solve(cho_factor(As + 1e-10 * np.eye(As.shape[0])), d * b[live])
    except np.linalg.LinAlgError:
        x[live] = d * np.linalg.lstsq(As, d * b[live], rcond=1e-12)[0]
    return x


def choose_terms(fe: "FoldEquations", ib: np.ndarray, p: int, w: np.ndarray, harmonic: np.ndarray,
                 K_grid: Sequence[int], rw_grid: Sequence[bool], spring_col: np.ndarray | None = None,
                 sp_grid: Sequence[bool] = (True,)) -> tuple[list, np.ndarray, np.ndarray | None]:
    """Held-out relative error of each joint (pooled over the folds; every sample of the held-out
    fold) of the weighted least-squares fit on the other folds, for each combination (all joints
    alike) of transition velocity (``fe``'s candidates), ripple harmonics up to K and reversal
    window (True: the equations near reversals left out of the fit). Returns the combinations,
    simplest first, the errors (C, n) against the filtered torque the fit is fitted to and, when
    ``fe`` carries the raw torques (``fe.xg``), the same predictions' errors against the raw
    torques (C, n; else None)."""
    V, Kf = fe.train[0].shape[:2]
    n = len(fe.act)
    spring_col = np.zeros(p, bool) if spring_col is None else spring_col
    combos = [(v, Kh, rw, sp) for sp in sp_grid for Kh in K_grid for rw in rw_grid for v in range(V)]
    err = np.zeros((len(combos), n))
    raw = fe.xg is not None
    err_raw = np.zeros((len(combos), n)) if raw else None
    den = fe.tc.sum(0) + fe.rc.sum(0)
    for v in range(V):
        At, Ar, bt, br = [], [], [], []
        for f in range(Kf):
            Gt, gt, _ = fe.full(p, [v] * n, [f])
            Ge, ge, _ = fe.full(p, [v] * n, [f], evaluate=True)
            At.append(np.einsum("j,jkl->kl", w, Gt)), bt.append(w @ gt)
            Ar.append(np.einsum("j,jkl->kl", w, Ge - Gt)), br.append(w @ (ge - gt))
        sAt, sAr, sbt, sbr = sum(At), sum(Ar), sum(bt), sum(br)
        for Kh, sp in ((Kh, sp) for Kh in K_grid for sp in sp_grid):
            cols = ib[(harmonic[ib] <= Kh) & (sp | ~spring_col[ib])]
            for rw in rw_grid:
                num, num_raw = np.zeros(n), np.zeros(n)
                for f in range(Kf):
                    A, b = sAt - At[f], sbt - bt[f]
                    if not rw:
                        A, b = A + sAr - Ar[f], b + sbr - br[f]
                    x = np.zeros(p)
                    x[cols] = _solve_quick(A[np.ix_(cols, cols)], b[cols])
                    for j, a in enumerate(fe.act):
                        xa = x[a]
                        E = fe.train[j][v, f] + fe.rest[j][v, f]
                        e = fe.tg[j][v, f] + fe.rg[j][v, f]
                        xEx = xa @ E @ xa
                        num[j] += max(fe.tc[f, j] + fe.rc[f, j] - 2 * e @ xa + xEx, 0.0)
                        if raw:
                            num_raw[j] += max(fe.xc[f, j] - 2 * fe.xg[j][v, f] @ xa + xEx, 0.0)
                c = combos.index((v, Kh, rw, sp))
                err[c] = np.sqrt(num / np.maximum(den, 1e-300))
                if raw:
                    err_raw[c] = np.sqrt(num_raw / np.maximum(fe.xc.sum(0), 1e-300))
    return combos, err, err_raw


def _chosen(fe: "FoldEquations", pick: Sequence[tuple], harmonic: np.ndarray, p: int,
            folds: Sequence[int] | None = None, evaluate: bool = False, spring_col: np.ndarray | None = None):
    """Per-joint normal equations at each joint's chosen combination (transition velocity, ripple
    harmonics, reversal window), over ``folds`` (default all); ``evaluate``: every sample.
    Returns G (n, p, p), g (n, p), c (n,) and which extras stay (p - n_std,)."""
    n = len(fe.act)
    n_std = p - fe.used.size
    f = slice(None) if folds is None else list(folds)
    G, g, c = np.zeros((n, p, p)), np.zeros((n, p)), np.zeros(n)
    used = np.ones(fe.used.size, bool)
    spring_col = np.zeros(p, bool) if spring_col is None else spring_col
    for j, (v, Kh, rw, sp) in enumerate(pick):
        a = fe.act[j]
        Gj, gj, cj = fe.train[j][v][f].sum(0), fe.tg[j][v][f].sum(0), fe.tc[f, j].sum()
        if not rw or evaluate:
            Gj, gj, cj = Gj + fe.rest[j][v][f].sum(0), gj + fe.rg[j][v][f].sum(0), cj + fe.rc[f, j].sum()
        drop = (harmonic[a] > Kh) | (spring_col[a] & (not sp))
        Gj[drop, :], Gj[:, drop], gj[drop] = 0.0, 0.0, 0.0
        G[j][np.ix_(a, a)], g[j, a], c[j] = Gj, gj, cj
        used[a[drop] - n_std] = False
    return G, g, c, used


#: ridge on the extra parameters (friction, offset, spring, ripple) towards the least-squares solution, relative to
#: each one's own curvature: a direction the data do not see stays where least squares put it. Without it, on a cut
#: of lwr4_3 where A1 moves one way only (its Coulomb and offset columns one column), the bound Fc >= 0 pushed IPOPT
#: along that direction to Fc 1.1e5 and offset -1.1e5 N·m; 1e-10 holds it there (Fc 0.35, offset 0.35) and moves
#: the fits of the tests' references by under 1e-7 of their values (1e-8: 5e-6)
EXTRA_RIDGE = 1e-10


def _consistent(Gw, gw, cw, M, robot, extra_n, nonneg, settings, x0_extra, fixed, bounded: bool, x0=None):
    """The physically consistent fit of weighted normal equations (``bounded``: the settings' mass
    bounds; ``x0``: a start, standard parameters then extras, solved at the final prior weight only;
    ``x0_extra``: the least-squares extras, where :data:`EXTRA_RIDGE` holds those the data do not see)."""
    # chi2 / M = p^T H p - 2 g^T p + c = |R p - z|^2 + c' with H = R^T R (eigenvectors of H)
    H, g, c = Gw / M, gw / M, cw / M
    ev, V = np.linalg.eigh(H)
    pos = ev > 1e-12 * ev.max()
    R = np.sqrt(ev[pos])[:, None] * V[:, pos].T
    z = (V[:, pos].T @ g) / np.sqrt(ev[pos])
    n_std = robot.n_std
    return consistent_fit(R, z, float(c - z @ z), robot, len(extra_n), nonneg, settings.prior_weight,
                          robot.pi_nominal, x0_extra if x0 is None else x0[n_std:], fixed=fixed,
                          mass_bounds=settings.mass_bounds if bounded else None,
                          total_mass_bounds=settings.total_mass_bounds if bounded else None,
                          start=None if x0 is None else x0[:n_std], ridge=EXTRA_RIDGE * np.diag(H)[n_std:],
                          ref=x0_extra)


def _masses_on_bound(robot: RobotModel, pi: np.ndarray, bounds) -> list[str]:
    if bounds is None:
        return []
    m0 = robot.pi_nominal[0::10]
    r = pi[0::10] / np.where(m0 > 0, m0, np.inf)
    return [name for name, x, has in zip(robot.link_names, r, m0 > 0)
            if has and (x < bounds[0] * 1.001 or x > bounds[1] * 0.999)]


def _mass_bound_check(fe, pick, harmonic, p, w, robot, solve, pi_c, extra, K, spring_col=None) -> dict:
    """Held-out relative error (per joint, pooled over the folds) of the consistent fit with the
    mass bounds and without them, each fitted on the other folds (started at the full fit)."""
    n = len(fe.act)
    num = {True: np.zeros(n), False: np.zeros(n)}
    den = np.zeros(n)
    x0 = np.concatenate([pi_c, extra])
    for f in range(K):
        Gt, gt, ct, used = _chosen(fe, pick, harmonic, p, [k for k in range(K) if k != f], spring_col=spring_col)
        Ge, ge, ce, _ = _chosen(fe, pick, harmonic, p, [f], evaluate=True, spring_col=spring_col)
        tr = [k for k in range(K) if k != f]
        Mt = max(float(sum(fe.tn[tr, j].sum() + (0.0 if rw else fe.rn[tr, j].sum())
                           for j, (_, _, rw, _) in enumerate(pick))), 1.0)
        Gw, gw, cw = np.einsum("j,jkl->kl", w, Gt), w @ gt, float(w @ ct)
        den += ce
        for bounded in (True, False):
            pi_f, ex_f, _ = solve(Gw, gw, cw, Mt, bounded, x0)
            x = np.concatenate([pi_f, ex_f])
            num[bounded] += np.maximum(ce - 2 * ge @ x + np.einsum("k,jkl,l->j", x, Ge, x), 0.0)
    err = {b: np.sqrt(num[b] / np.maximum(den, 1e-300)) for b in (True, False)}
    released = bool(np.mean(err[False]) < np.mean(err[True]) / SIMPLER_WITHIN)
    return {"heldout_relative_error_bounded": err[True].tolist(), "heldout_relative_error_free": err[False].tolist(),
            "released": released,
            "why": (f"held-out error {100 * np.mean(err[False]):.1f} % free against {100 * np.mean(err[True]):.1f} % "
                    f"bounded (mean over joints): " + ("the bounds are released" if released else "the bounds stay"))}


def _folds(m: Motion, logs: Sequence[AxisLog]) -> tuple[np.ndarray, int, str]:
    """Fold of each sample: each recording when there are several, else :data:`FOLDS` contiguous
    blocks of the one recording; the number of folds and how they were made."""
    rows = m.log_rows or (m.q.shape[0],)
    if len(rows) > 1:
        return np.repeat(np.arange(len(rows)), rows), len(rows), "each recording left out in turn"
    N = m.q.shape[0]
    return np.minimum(np.arange(N) * FOLDS // N, FOLDS - 1), FOLDS, f"{FOLDS} contiguous blocks of the recording"


def _weights(G: np.ndarray, g: np.ndarray, cc: np.ndarray, ib: np.ndarray, counts: np.ndarray,
             settings: RobotFitSettings) -> np.ndarray:
    """Per-joint standard deviations of the equations (see ``RobotFitSettings.weighting``)."""
    n = cc.size
    Gb, gbb = G[:, ib][:, :, ib], g[:, ib]
    beta0 = _solve(Gb.sum(0), gbb.sum(0))
    rss = cc - 2 * gbb @ beta0 + np.einsum("k,jkl,l->j", beta0, Gb, beta0)
    dof = np.maximum(counts - ib.size / n, 1.0)
    sig = np.sqrt(np.maximum(rss, 0.0) / dof)
    if settings.weighting == "torque":
        sig = np.sqrt(cc / np.maximum(counts, 1.0))
    elif settings.weighting == "none":
        sig = np.ones(n)
    return np.maximum(sig, 1e-6 * max(sig.max(), 1e-12))


def predictions(robot: RobotModel, m: Motion, settings: RobotFitSettings, drive: DriveModel,
                independent: np.ndarray, coefs: Sequence[np.ndarray], block: int = BLOCK) -> list[np.ndarray]:
    """(N, n) torques of each coefficient vector (base parameters, then the extras) on every sample
    of ``m``, block by block."""
    span = np.ptp(m.q, axis=0)
    out = [np.empty_like(m.tau) for _ in coefs]
    cols = None
    with _one_blas_thread():
        for rows, mb in _blocks(m, block):
            C = _block_columns(robot, mb, settings, drive, span)
            if cols is None:
                cols = np.concatenate([independent, np.arange(robot.n_std, C.shape[2])])
            Cb = C[:, :, cols]
            for o, x in zip(out, coefs):
                o[rows] = Cb @ x
    return out


def _log_names(logs: Sequence[AxisLog]) -> str:
    """The logs as a message names them: their files, comma-separated."""
    return ", ".join(str(lg.attrs.get("source_file", "log")) for lg in logs)


def _too_few_moving(logs: Sequence[AxisLog], counts: np.ndarray) -> str:
    """Why joints with fewer than 10 samples to fit (``counts``) cannot be fitted: each such
    joint's equations are fitted only where it moves faster than :data:`STANDSTILL` away from its
    reversals and stops; a joint that barely moves (positions in radians under a degree header:
    57 x too small) has none."""
    from kukaid.identify.adequacy import unit_warnings

    names = _log_names(logs)
    few = [j for j in range(counts.size) if counts[j] < 10]
    said = ", ".join(f"A{j + 1} {int(counts[j])}" for j in few)
    units = [w for lg in logs for j in few if (j + 1) in lg.axes for w in unit_warnings(lg, j + 1)]
    if len(logs) == 1:  # the log is named first
        units = [w.removeprefix(f"{names}: ") for w in units]
    why = units[0] if units else "record a motion in which every joint moves (kukaid excite fourier --robot)"
    return (f"{names}: too few samples to fit {', '.join(f'A{j + 1}' for j in few)}: a joint's equations are fitted "
            f"where it moves faster than {STANDSTILL:g} rad/s away from its reversals and stops, and there are "
            f"fewer than 10 such samples ({said}); {why}")


@dataclass
class _Terms:
    """One cut-off's samples, fold equations and per-joint held-out choices (:func:`_terms`)."""

    settings: RobotFitSettings      # the dead-band and each joint's chosen transition velocity set
    m: Motion
    fe: FoldEquations
    K: int                          # folds
    p: int                          # standard parameters + extras
    ib: np.ndarray                  # the base parameters' and extras' columns
    harmonic: np.ndarray            # (p,) ripple harmonic of each column (0: none)
    spring_col: np.ndarray          # (p,) bool: a spring column
    pick: list                      # per joint (transition velocity index, ripple, reversal window, spring)
    choices: dict
    err_raw: np.ndarray | None      # (n,) held-out error of each joint's pick against the raw torques


def _terms(logs: Sequence[AxisLog], robot: RobotModel, settings: RobotFitSettings, drive: DriveModel,
           base, raw: bool = False) -> _Terms:
    """The samples of ``logs`` at the settings' cut-off, their per-fold normal equations and each
    joint's transition velocity, ripple harmonics and spring chosen by held-out error (``raw``: the
    same held-out predictions also scored against the unfiltered torques, :func:`choose_cutoff`)."""
    n = robot.n
    m = _samples(logs, n, settings, drive, raw=raw)
    N = m.q.shape[0]
    kw = m.keep.astype(float)
    counts = kw.sum(axis=0)
    if np.any(counts < 10):
        raise FitError(_too_few_moving(logs, counts))
    # per-joint normal equations of all columns (standard parameters + extras), accumulated over
    # blocks of samples (never the (N, n, p) regressor), per candidate Coulomb transition velocity
    # and per fold when one is to be chosen: everything below works on these small matrices,
    # whatever the number of samples
    if settings.deadband is None:
        settings = replace(settings, deadband=tuple(float(x) for x in NOISE_DEADBAND * m.qd_noise))
    deadband = np.broadcast_to(np.asarray(settings.deadband, float), (n,))
    if settings.v_smooth is None and settings.choose:
        grid = np.broadcast_to(np.asarray(SMOOTH_GRID, float)[:, None], (len(SMOOTH_GRID), n))     # (V, n)
    elif settings.v_smooth is None:
        grid = np.zeros((1, n))
    else:
        grid = np.broadcast_to(np.asarray(settings.v_smooth, float), (n,))[None, :]
    K_grid = sorted({0, settings.ripple // 2, settings.ripple}) if settings.choose else [settings.ripple]
    # fitting the equations near reversals too (a window of 0) can be chosen the same way
    # (choose_terms), but blocks of one recording favour it and it loses on other recordings (the
    # LWR4+'s A6: 12.9 -> 21.8 % on lwr4_3): the window stays as set
    rw_grid = [True]
    sp_grid = [False, True] if settings.choose and settings.spring else [settings.spring]
    choose = len(grid) * len(K_grid) * len(rw_grid) * len(sp_grid) > 1 or raw
    folds, K, how = _folds(m, logs) if choose else (np.zeros(N, int), 1, None)
    fe = fold_equations(robot, m, settings, drive, grid, folds, K)
    n_extra = fe.used.size
    p = robot.n_std + n_extra
    folded = folded_rotors(robot, drive, base) if settings.rotor else []
    ib = np.concatenate([base.independent, robot.n_std + np.arange(n_extra)])
    harmonic = np.zeros(p, int)           # the ripple harmonic of each column (0: not a ripple column)
    if settings.ripple:
        for k, nm in enumerate(extra_names(robot, settings)):
            if ".ripple_" in nm:
                harmonic[robot.n_std + k] = int(nm.rsplit("_", 1)[1][3:])
    spring_col = np.zeros(p, bool)
    if settings.spring:
        for k, nm in enumerate(extra_names(robot, settings)):
            spring_col[robot.n_std + k] = nm.endswith(".k")
    pick = [(0, settings.ripple, True, settings.spring)] * n
    choices: dict = {}
    if folded:
        choices["rotor_folded"] = {
            "motors": [f"M{k + 1}" for k, _ in folded], "columns": [p - n + k for k, _ in folded],
            # the least-squares base parameters hold the folded rotors: (links' part) + sum_k into[k] * I_rotor_k
            "into": [x.tolist() for _, x in folded],
            "why": "each is one column with a link's inertia about its joint's axis: in the least squares it is held "
                   "at 0 and the base parameters holding that inertia carry it; the consistent estimate splits it "
                   "between them and the rotor (the prior decides)"}
    err_raw = None
    if choose:
        G0, g0, c0 = fe.full(p)
        combos, err, err_raw = choose_terms(fe, ib, p, 1.0 / _weights(G0, g0, c0, ib, counts, settings) ** 2, harmonic,
                                   K_grid, rw_grid, spring_col, sp_grid)
        # per joint the simplest combination (no spring, fewer harmonics, the smaller transition velocity)
        # within SIMPLER_WITHIN of its lowest held-out error
        best = [int(np.flatnonzero(err[:, j] <= SIMPLER_WITHIN * err[:, j].min())[0]) for j in range(n)]
        pick = [combos[i] for i in best]
        err_raw = None if err_raw is None else err_raw[best, np.arange(n)]
        choices["held_out"] = {
            "folds": how, "rule": f"per joint the simplest combination within {100 * (SIMPLER_WITHIN - 1):.0f} % of its "
                                  "lowest held-out relative error",
            "combinations": [{"v_smooth": [float(x) for x in grid[v]], "ripple": Kh,
                              "reversal_window": settings.reversal_window if rw else 0.0, "spring": sp}
                             for v, Kh, rw, sp in combos],
            "relative_error": err.T.tolist(),
            "chosen": best}
    settings = replace(settings, v_smooth=tuple(float(grid[v, j]) for j, (v, _, _, _) in enumerate(pick)))
    choices["v_smooth"] = {"chosen": list(settings.v_smooth), "candidates": [float(x) for x in SMOOTH_GRID]
                           if len(grid) > 1 else None, "velocity_noise": m.qd_noise.tolist(),
                           "deadband": deadband.tolist()}
    choices["ripple"] = {"chosen": [Kh for _, Kh, _, _ in pick], "candidates": K_grid}
    choices["spring"] = {"chosen": [bool(sp) for _, _, _, sp in pick], "candidates": sp_grid}
    choices["reversal_window"] = {"chosen": [settings.reversal_window if rw else 0.0 for _, _, rw, _ in pick]}
    return _Terms(settings, m, fe, K, p, ib, harmonic, spring_col, pick, choices, err_raw)


def cutoff_candidates(logs: Sequence[AxisLog]) -> list[float]:
    """The cut-offs :func:`choose_cutoff` tries on ``logs``, Hz: :data:`CUTOFF_GRID`, each at most a
    tenth of the slowest log's sample rate (the default's cap), without repeats."""
    fs = min(1.0 / lg.sample_time for lg in logs)
    return sorted({_cut(min(float(c), 0.1 * fs)) for c in CUTOFF_GRID})


def _cut(fc: float) -> float:
    """A cut-off to three significant digits: a log at 100.01 Hz caps a candidate at 10.0, not 10.001."""
    return float(f"{fc:.3g}")


def _fitted_rows(logs: Sequence[AxisLog], settings: RobotFitSettings) -> int:
    return sum(len(range(*sample_rows(lg, settings).indices(lg.n_samples))) for lg in logs)


def _choice_settings(logs: Sequence[AxisLog], settings: RobotFitSettings) -> tuple[RobotFitSettings, int]:
    """A candidate cut-off's settings for the choice: every k-th of its fitted samples, k such that
    at most :data:`CHOICE_SAMPLES` remain (k = 1 for a short log); and k."""
    k = max(1, math.ceil(_fitted_rows(logs, settings) / CHOICE_SAMPLES))
    if k == 1:
        return settings, 1
    return replace(settings, decimate=k * max(_step(settings, 1.0 / lg.sample_time) for lg in logs)), k


def choose_cutoff(err_raw: dict[float, np.ndarray], default: float) -> tuple[float, list[float], bool]:
    """The cut-off (Hz) of the lowest mean held-out error over the joints, ``err_raw`` {cut-off:
    (n,) relative errors against the raw torques}; ``default`` unless another's is lower by more than
    :data:`SIMPLER_WITHIN` (the rule of the other held-out choices), and when no candidate predicts the
    held-out recordings (every mean above :data:`NO_RANKING`: they cannot rank). Returns it, the means
    and whether the held-out errors ranked the candidates."""
    cands = sorted(err_raw)
    mean = [float(np.mean(err_raw[c])) for c in cands]
    best = cands[int(np.argmin(mean))]
    if default not in err_raw:     # the default could not be fitted (see _cutoff_terms)
        return best, mean, True
    ranked = min(mean) <= NO_RANKING
    return (best if ranked and min(mean) * SIMPLER_WITHIN < mean[cands.index(default)] else default), mean, ranked


def _cutoff_terms(logs: Sequence[AxisLog], robot: RobotModel, settings: RobotFitSettings, drive: DriveModel,
                  base) -> _Terms:
    """:func:`_terms` at the given cut-off, or, when none is given (and ``settings.choose``) and there
    are several recordings, at the one of :func:`cutoff_candidates` with the lowest held-out error
    against the common target, each recording left out in turn.

    Why not on blocks of one recording: they share its trajectory, and what a cut-off gains on one
    block carries to the next but not to another motion (the LWR4+'s fast lwr4_3: its blocks rank
    5 Hz 6 % and 20 Hz 17 % better than 10 Hz; on lwr4_1 and lwr4_2 those files predict 17.0 / 15.9
    and 13.6 / 12.8 % against 13.3 / 12.6 % at 10 Hz): one recording keeps the default, as the
    rotor inertias are not chosen by its blocks either.

    Why a common target: each candidate is fitted to the torques filtered at its own cut-off
    ("parallel filtering"); scored against those too, a lower cut-off wins by its smoother target
    alone. Every candidate's held-out prediction (the same folds, each joint's own transition
    velocity, ripple and spring chosen at that cut-off) is scored against the raw, unfiltered
    torques: what ``kukaid validate`` compares with and what the admittance control's residual
    sees, the same for every candidate; its noise adds the same to each candidate's squared error
    and so does not rank them. A long log is thinned for the choice (:func:`_choice_settings`);
    the chosen cut-off is then fitted on all its samples."""
    fs = min(1.0 / lg.sample_time for lg in logs)
    if settings.cutoff is not None or not settings.choose or len(logs) < 2:
        t = _terms(logs, robot, settings, drive, base)
        how = "given" if settings.cutoff is not None else f"the default {CUTOFF:g} Hz (at most fs/10)" + (
            "; one recording: its blocks do not choose it" if settings.choose else "")
        t.choices["cutoff"] = {"chosen": round(_cutoff(settings, fs), 6), "how": how}
        return t
    trials, thin, failed = {}, {}, {}
    for fc in cutoff_candidates(logs):
        s_fc, thin[fc] = _choice_settings(logs, replace(settings, cutoff=fc))
        try:
            trials[fc] = _terms(logs, robot, s_fc, drive, base, raw=True)
        except FitError as e:   # e.g. a slow cut-off's reversal window leaves too few samples of a fast motion
            failed[fc] = str(e)
    if not trials:
        raise FitError(next(iter(failed.values())))
    default = _cut(_cutoff(settings, fs))
    chosen, mean, ranked = choose_cutoff({fc: t.err_raw for fc, t in trials.items()}, default)
    how = "held-out error" if ranked else (
        f"the default: no candidate predicts the held-out recordings (mean error above {100 * NO_RANKING:.0f} %)")
    t = trials[chosen]
    if thin[chosen] > 1:
        t = _terms(logs, robot, replace(settings, cutoff=chosen), drive, base)
    t.choices["cutoff"] = {
        "chosen": chosen, "how": how, "candidates": sorted(trials), "default": default,
        "folds": trials[chosen].choices["held_out"]["folds"],
        "target": "the raw (unfiltered) measured torques, the same for every candidate",
        "rule": f"the lowest mean held-out relative error over the joints; the default {default:g} Hz unless another "
                f"is lower by more than {100 * (SIMPLER_WITHIN - 1):.0f} %",
        "relative_error": [trials[fc].err_raw.tolist() for fc in sorted(trials)], "mean_relative_error": mean,
        "samples": [int(trials[fc].m.q.shape[0]) for fc in sorted(trials)],
        "thinned": [thin[fc] for fc in sorted(trials)], "not_possible": {f"{fc:g}": e for fc, e in failed.items()}}
    return t


def fit_robot(logs: Sequence[AxisLog], robot: RobotModel, settings: RobotFitSettings | None = None,
              coupling: np.ndarray | None = None) -> dict:
    """Identify base parameters, a physically consistent estimate and per-joint friction.

    Parameters
    ----------
    logs : axis logs with axes A1..An (no others), all moving (n = the robot's joints).
    robot : the robot model (URDF).
    settings : see :class:`RobotFitSettings`.
    coupling : wrist coupling for motor-side torques (see :class:`DriveModel`).

    Returns
    -------
    The content of a ``kukaid.robot_params/1`` file (see :mod:`kukaid.params.robot`).
    """
    # every product and factorisation here is of narrow matrices (a hundred columns or so): BLAS
    # threads gain nothing and, on a busy machine, make each call wait for cores
    with _one_blas_thread():
        return _fit_robot(logs, robot, settings, coupling)


def _fit_robot(logs: Sequence[AxisLog], robot: RobotModel, settings: RobotFitSettings | None,
               coupling: np.ndarray | None) -> dict:
    settings = settings or RobotFitSettings()
    if not logs:
        raise FitError("no logs to fit")
    from kukaid.identify.adequacy import check_not_held

    for lg in logs:
        check_not_held(lg)
        check_torque_scale(lg, robot)
    check_each_recording_once(logs, FitError)  # one recording twice would be its own held-out check
    n = robot.n
    motor_currents = all(lg.attrs.get("source") in MOTOR_TORQUE_SOURCES for lg in logs)
    rotor_why = ("as given" if settings.rotor is not None else
                 "fitted: the logs' torques come from the motor currents, which carry the rotors' inertia"
                 if motor_currents else "left out: the logs do not say their torques come from the motor currents "
                 "(KUKA Trace, KUKAVARPROXY, the virtual KR C4; --rotor-inertia if they do), and a link-side "
                 "torque sensor does not see the rotors")
    settings = replace(settings, rotor=motor_currents if settings.rotor is None else settings.rotor)
    if settings.torque_side == "motor" and np.all(np.asarray(robot.ratio, float) == 1.0):
        raise FitError(f"{robot.source}: torques on the motor side need the joints' gear ratios, and this URDF gives "
                       "none (no <transmission> with a <mechanicalReduction>): with ratio 1 the motor torques would be "
                       "read as joint torques; add the transmissions, or give joint-side torques (--torque-side joint)")
    drive = _drive(robot, settings, coupling)
    for lg in logs:
        check_torque_size(lg, robot, drive, settings.torque_side)
    base = robot.base_parameters()
    t = _cutoff_terms(logs, robot, settings, drive, base)
    settings, m, fe, K, p, ib, harmonic, spring_col, pick, choices = (
        t.settings, t.m, t.fe, t.K, t.p, t.ib, t.harmonic, t.spring_col, t.pick, t.choices)
    N = m.q.shape[0]
    nb = base.size
    fold = choices.pop("rotor_folded", None)
    fcols = np.asarray(fold["columns"] if fold else [], int)
    choices["rotor"] = {"fitted": settings.rotor, "motor_current_logs": motor_currents, "why": rotor_why,
                        **({"folded": fold["motors"], "folded_into": fold["into"], "folded_why": fold["why"]}
                           if fold else {})}
    # the chosen equations: joint j at its transition velocity, its ripple harmonics, its samples
    G, gb, cc, used = _chosen(fe, pick, harmonic, p, spring_col=spring_col)
    used &= fe.used
    keep = m.keep.copy()
    for j, (_, _, rw, _) in enumerate(pick):
        if not rw:
            keep[:, j] = True
    m = replace(m, keep=keep)
    kw = keep.astype(float)
    counts = kw.sum(axis=0)
    sig = _weights(G, gb, cc, ib, counts, settings)
    w = 1.0 / sig ** 2
    Gw, gw, cw = np.einsum("j,jkl->kl", w, G), w @ gb, float(w @ cc)
    Gwb, gwb = Gw[np.ix_(ib, ib)], gw[ib]
    if fcols.size:   # least squares without the folded rotors' columns: the base parameters carry them
        fold_ls = np.isin(ib, fcols)
        Gwb, gwb = Gwb.copy(), gwb.copy()
        Gwb[fold_ls, :], Gwb[:, fold_ls], gwb[fold_ls] = 0.0, 0.0, 0.0
    beta = _solve(Gwb, gwb)
    M = float(kw.sum())
    s2 = max(cw - 2 * gwb @ beta + beta @ Gwb @ beta, 0.0) / max(M - ib.size, 1)
    cov = s2 * np.linalg.pinv(Gwb)
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    dsc = 1.0 / np.sqrt(np.maximum(np.diag(Gwb), 1e-300))
    Gs = dsc[:, None] * Gwb * dsc[None, :]
    live = np.diag(Gwb) > 0              # ripple harmonics left out and folded rotors are zero columns
    cond = float(np.sqrt(np.linalg.cond(Gs[np.ix_(live, live)])))
    # directions the data do not see (a folded rotor's zero column; a rotor that is one column with a
    # link inertia is folded above, :func:`folded_rotors`): the pseudo-inverse gives them no variance,
    # but their parameters have no standard deviation (null)
    ev, V = np.linalg.eigh(Gs)
    null = V[:, ev < 1e-10 * ev.max()]
    sd[np.any(np.abs(null) > 1e-6, axis=1)] = np.nan
    extra_n = extra_names(robot, settings)

    pi_c = None
    solver_info = None
    extra = beta[nb:]
    if settings.consistent:
        nonneg = np.array(_nonneg(extra_n))

        def solve(Gw_, gw_, cw_, M_, bounds, x0=None):  # a solve that fails names the logs, as the checks do
            try:
                return _consistent(Gw_, gw_, cw_, M_, robot, extra_n, nonneg, settings, beta[nb:].copy(), ~used,
                                   bounds, x0)
            except FitError as e:
                raise FitError(f"{_log_names(logs)}: {e}") from None
        pi_c, extra, solver_info = solve(Gw, gw, cw, M, True)
        on_bound = _masses_on_bound(robot, pi_c, settings.mass_bounds)
        if on_bound and K > 1:
            # a mass on its bound: does held-out error demand more? the same folds, bounded and free
            check = _mass_bound_check(fe, pick, harmonic, p, w, robot, solve, pi_c, extra, K, spring_col)
            check["links_on_bound"] = on_bound
            choices["mass_bounds"] = check
            if check["released"]:
                pi_c, extra, solver_info = solve(Gw, gw, cw, M, False, np.concatenate([pi_c, extra]))
                settings = replace(settings, mass_bounds=None, total_mass_bounds=None)
        elif on_bound:
            choices["mass_bounds"] = {"links_on_bound": on_bound, "released": False,
                                      "why": "one recording without held-out folds: the bounds stay"}
    beta_out = base.of(pi_c) if pi_c is not None else beta[:nb]
    # metrics on the fitted (filtered) samples: a second pass over the blocks
    fit_ls, pred = predictions(robot, m, settings, drive, base.independent,
                               [beta, np.concatenate([beta_out, extra])])
    resid = (m.tau - fit_ls) / sig[None, :]
    with _one_blas_thread():
        cfac = [correlation_factor(resid[m.keep[:, j], j], 20) for j in range(n)]
    rel = np.linalg.norm(m.tau - pred, axis=0) / np.maximum(np.linalg.norm(m.tau, axis=0), 1e-12)
    at_bound = [nm for nm, v, nn, u in zip(extra_n, extra, _nonneg(extra_n), used) if nn and u and abs(v) < 1e-7]
    checks = consistency(pi_c) if pi_c is not None else None
    # a link on the boundary of the consistent set: its pseudo-inertia (nearly) singular
    if pi_c is not None and settings.mass_bounds is not None:
        m0 = robot.pi_nominal[0::10]
        r = pi_c[0::10] / np.where(m0 > 0, m0, np.inf)
        at_bound += [f"{name}.m" for name, x, has in zip(robot.link_names, r, m0 > 0)
                     if has and (x < settings.mass_bounds[0] * 1.001 or x > settings.mass_bounds[1] * 0.999)]
    at_bound += [name for name, chk in zip(robot.link_names, checks or [])
                 if chk["pseudo_inertia_min_eig"] < 1e-8 * max(chk["mass"], 1e-9)]
    bundled = robot.source in BUNDLED
    params = {
        "schema": ROBOT_SCHEMA,
        "robot": {"name": robot.model.name, "urdf": robot.source if bundled else str(Path(robot.path).resolve()),
                  "sha256": robot.sha256, "joints": list(robot.joint_names), "links": list(robot.link_names)},
        "axes": list(range(1, n + 1)),
        "torque_side": settings.torque_side,
        "base_parameters": {"names": list(base.names), "values": beta_out.tolist(),
                            "least_squares": beta[:nb].tolist(), "sigma": _nulls(sd[:nb]),
                            "independent": base.independent.tolist(), "dependent": base.dependent.tolist(),
                            "R": base.R.tolist()},
        "standard_parameters": None if pi_c is None else {
            link: dict(zip(LINK_PARAMS, pi_c[10 * k: 10 * k + 10].tolist()))
            for k, link in enumerate(robot.link_names)},
        "friction": {"model": settings.friction, "vs": settings.vs if settings.friction == "stribeck" else None,
                     "offset": settings.offset,
                     "qd_range": None if settings.viscous_beyond != "hold" else [
                         [min(float(lo), 0.0), max(float(hi), 0.0)] for lo, hi in zip(m.qd.min(0), m.qd.max(0))],
                     "values": dict(zip(extra_n, np.asarray(extra).tolist())),
                     "least_squares": dict(zip(extra_n, beta[nb:].tolist())),
                     "sigma": dict(zip(extra_n, _nulls(sd[nb:])))},
        "drive": None if not (settings.torque_side == "motor" or settings.rotor) else {
            "ratio": drive.ratio.tolist(), "coupling": np.asarray(drive.coupling).tolist()},
        "settings": {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(settings).items()},
        "metrics": {"samples": int(N), "choices": choices, "condition_number": cond, "noise_sigma": sig.tolist(),
                    "residual_correlation_factor": float(max(cfac)),
                    "relative_error_fit": rel.tolist(),
                    "consistency": checks,
                    "physically_consistent": bool(checks is not None and all(c["ok"] for c in checks)),
                    "at_bound": at_bound,
                    "solver": solver_info},
        "provenance": {"logs": [str(lg.attrs.get("source_file", "")) for lg in logs],
                       "log_fingerprints": [log_fingerprint(lg) for lg in logs],
                       # the low-pass every reader of the file filters new logs with (settings.cutoff;
                       # None: the default, at most fs/10 of each log), and where it came from
                       "preprocess": {"cutoff": choices["cutoff"]["chosen"], "order": settings.order,
                                      "cutoff_from": choices["cutoff"]["how"]}},
    }
    if not np.any(relative_sigma(params) < DETERMINED):  # the prior and the bounds made every number
        params["metrics"]["warnings"] = [
            f"{_log_names(logs)}: the logs determine none of the {nb} base parameters (sigma < {100 * DETERMINED:g} "
            f"%; {N} samples fitted, condition number {cond:.3g}): too short, or too little motion, for the whole "
            "robot; its figures hold on these samples only (kukaid validate it on another recording)"]
    return params


#: a base parameter is well excited when its standard deviation is under this share of its value
WELL_EXCITED = 0.005


def well_excited(params: dict, share: float = WELL_EXCITED) -> np.ndarray:
    """(b,) bool: the base parameters of a robot fit that the data determine well, from the fit
    alone: ``sigma * metrics.residual_correlation_factor < share * |estimate|``.

    The least-squares sigma assume white residuals; the filtered residuals are correlated, which
    makes them optimistic by the correlation factor (about 2): a rule on the bare sigma counts as
    well excited parameters whose real standard deviation is twice the share (at 0.5 %, a 2 %
    error is then a 2-sigma event, as on one simulated seed where a parameter with sigma 0.49 %
    came out 2.1 % off)."""
    bp = params["base_parameters"]
    sd = np.asarray(bp["sigma"], float)                  # None (no standard deviation): NaN, never well excited
    cf = float((params.get("metrics") or {}).get("residual_correlation_factor") or 1.0)
    # sigma 0: a direction the regressor does not see at all (the pseudo-inverse gives it no variance)
    return (sd > 0) & (max(cf, 1.0) * sd < share * np.abs(np.asarray(bp["values"], float)))


def _nulls(x: np.ndarray) -> list:
    """A list for JSON: NaN (no value) as None."""
    return [None if not math.isfinite(v) else float(v) for v in x]


def _nonneg(names: Sequence[str]) -> list[bool]:
    return [nm.endswith((".Fc", ".Fv", ".rotor_inertia")) for nm in names]


def predict_robot(params: dict, log: AxisLog, robot: RobotModel | None = None,
                  where: str = "robot parameter file") -> dict[int, np.ndarray]:
    """Predicted joint torques of a robot parameter file (named ``where``) on ``log``: {axis: (N,) N·m}.

    The positions are filtered and differentiated as in the fit; the prediction is compared with
    the raw measured torques by the caller (:meth:`kukaid.identify.fitted.RobotFile.predict`)."""
    validate_robot_params(params, where)
    robot = robot or RobotModel(params["robot"]["urdf"])
    check_fitted_urdf(params, robot.sha256, robot.path)
    if robot.n != len(params["axes"]):
        raise ParamFileError(f"{robot.path}: {robot.n} joints, the parameter file has {len(params['axes'])} axes")
    check_torque_scale(log, robot)
    s = params["settings"]
    # a file written before the ripple existed was fitted without it
    settings = RobotFitSettings(**{"ripple": 0, **{k: s[k] for k in RobotFitSettings.__dataclass_fields__ if k in s}})
    n = robot.n
    m = motion(log, n, settings, filter_tau=False)
    drive = DriveModel.direct(n) if not settings.rotor else DriveModel(
        np.asarray(params["drive"]["ratio"]), np.asarray(params["drive"]["coupling"]), np.zeros(n))
    names = extra_names(robot, settings)
    missing = [k for k in names if k not in params["friction"]["values"]]
    if missing:  # a term the file's settings fit
        raise ParamFileError(f"{where}: missing field 'friction.values.{missing[0]}'"
                             + (f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""))
    extra = np.array([params["friction"]["values"][k] for k in names])
    effects = params.get("effects") or {}
    temp = log_temperatures(log, n) if any(k.startswith("thermal") for k in effects) else None
    tau = np.empty_like(m.q)
    for rows, mb in _blocks(m):      # block by block: an hour's log never holds its (N, n, p) regressor
        F = extras(robot, mb, settings, drive, qd_range=params["friction"].get("qd_range"))
        s = effect_signals(robot, mb.q, robot.regressor(mb.q, mb.qd, mb.qdd), F, params, names,
                           None if temp is None else temp[rows], gravity=bool(effects), qd=mb.qd, qdd=mb.qdd,
                           time=np.asarray(log.time, float)[rows] if m.q.shape[0] == log.n_samples else None)
        tau[rows] = s.rigid + F @ extra + robot_effects.torque(effects, s)
    if settings.torque_side == "motor":
        drive = DriveModel(np.asarray(params["drive"]["ratio"]), np.asarray(params["drive"]["coupling"]), np.zeros(n))
        tau = drive.motor_torque(tau)
    return {a: tau[:, a - 1] for a in range(1, n + 1)}


def log_temperatures(log: AxisLog, n: int) -> np.ndarray:
    """(N, n) the log's motor temperatures of axes A1..An, degC (a thermal effect needs them)."""
    if getattr(log, "temp", None) is None:
        raise FitError(f"{log.attrs.get('source_file', 'axis log')}: a thermal effect of the parameter file needs "
                       "the log's motor temperature channel (temp)")
    return np.asarray(log.temp, float)[:, [log.index(a) for a in range(1, n + 1)]]


def effect_signals(robot: RobotModel, q: np.ndarray, Y: np.ndarray, F: np.ndarray, params: dict,
                   names: Sequence[str], temp: np.ndarray | None = None,
                   gravity: bool = True, qd: np.ndarray | None = None, qdd: np.ndarray | None = None,
                   time: np.ndarray | None = None) -> robot_effects.EffectSignals:
    """What a robot file's effects read on one block of samples (:mod:`kukaid.models.robot_effects`):
    its rigid-body torque (from the standard regressor ``Y`` (B, n, 10 n)), gravity torque (zeros
    when ``gravity`` is false), the last link's m, m c columns, its Coulomb column and friction
    torque (from its extra columns ``F`` named ``names``), the velocities ``qd`` rad/s and sample
    times as given, and with ``qd`` and ``qdd`` its rigid-body torque at a moved state
    (:func:`rigid_at`)."""
    bp = params["base_parameters"]
    ind, beta = np.asarray(bp["independent"], int), np.asarray(bp["values"], float)
    vals = params["friction"]["values"]
    n = robot.n
    at = np.arange(n)
    coul = [names.index(f"A{j + 1}.Fc") for j in range(n)]
    visc = [names.index(f"A{j + 1}.Fv") for j in range(n)]
    sign = F[:, at, coul]
    friction = sign * np.array([vals.get(names[c], 0.0) for c in coul]) + \
        F[:, at, visc] * np.array([vals.get(names[c], 0.0) for c in visc])
    z = np.zeros_like(q)
    k0 = robot.n_std - 10
    return robot_effects.EffectSignals(q=q, sign=sign, friction=friction, rigid=Y[:, :, ind] @ beta,
                                       gravity=robot.regressor(q, z, z)[:, :, ind] @ beta if gravity else z,
                                       payload=Y[:, :, k0:k0 + 4], temp=temp, qd=qd, time=time,
                                       rigid_at=None if qd is None or qdd is None else
                                       rigid_at(robot, q, qd, qdd, ind, beta))


def rigid_at(robot: RobotModel, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, independent: np.ndarray,
             beta: np.ndarray):
    """``fn(j, dq, dqd, dqdd)`` -> (N, n) N·m: the rigid-body torque (base parameters ``beta`` of the
    standard regressor's columns ``independent``) with joint j's position, velocity and acceleration
    moved by ``dq, dqd, dqdd`` (N,) from ``q, qd, qdd`` (N, n), block by block."""
    def fn(j, dq, dqd, dqdd):
        out = np.empty_like(q)
        for a in range(0, q.shape[0], BLOCK):
            r = slice(a, min(a + BLOCK, q.shape[0]))
            Q, Qd, Qdd = q[r].copy(), qd[r].copy(), qdd[r].copy()
            Q[:, j] += dq[r]
            Qd[:, j] += dqd[r]
            Qdd[:, j] += dqdd[r]
            out[r] = robot.regressor(Q, Qd, Qdd)[:, :, independent] @ beta
        return out
    return fn


#: a base parameter is shown as determined by the data when its corrected standard deviation is
#: under this share of its value (the table; :data:`WELL_EXCITED` is the stricter rule for "well")
DETERMINED = 0.1
#: at most this many base parameters are listed (the best determined); the file holds them all
TABLE_BASE_ROWS = 14


def table_number(x: float | None, digits: int = 4, zero: float = 1e-7) -> str:
    """A number for the table: '-' for none, 0 for a value that is zero up to the solver's tolerance
    (a parameter on its bound: not -6.3e-09)."""
    if x is None or not math.isfinite(float(x)):
        return "-"
    x = float(x)
    return "0" if abs(x) < zero else f"{x:.{digits}g}"


def _short(name: str, width: int) -> str:
    """A base parameter's name within ``width``: its leading terms, then how many more."""
    if len(name) <= width:
        return name
    terms = name.replace(" - ", " + -").split(" + ")
    out = terms[0]
    for k, t in enumerate(terms[1:], 1):
        more = f" (+{len(terms) - k - 1} terms)" if k < len(terms) - 1 else ""
        cand = f"{out} + {t}".replace("+ -", "- ")
        if len(cand) + len(more) > width:
            rest = len(terms) - k
            return (out + f" (+{rest} terms)")[:width]
        out = cand
    return out[:width]


def _pct(r: float) -> str:
    p = 100 * r
    return f"{p:.2g}%" if p < 100 else f"{p:.0f}%"


def cutoff_line(co: dict) -> str:
    """The line of the table and the report on the low-pass cut-off and its evidence (``metrics.choices.cutoff``)."""
    line = f"low-pass {table_number(co.get('chosen'), 3)} Hz"
    if co.get("how") != "held-out error":
        return f"{line}: {co.get('how')}"
    errs = " / ".join(f"{100 * e:.1f}" for e in co.get("mean_relative_error") or [])
    cands = " / ".join(table_number(c, 3) for c in co.get("candidates") or [])
    return (f"{line} chosen by held-out error against the raw torques ({cands} Hz: mean {errs} %; the default "
            f"{table_number(co.get('default'), 3)} Hz unless another is {100 * (SIMPLER_WITHIN - 1):.0f} % better)")


def relative_sigma(params: dict) -> np.ndarray:
    """Per base parameter, its sigma times the residual correlation factor over |its estimate| (the
    value the file predicts with, not the least-squares one): what ``fit`` and ``report`` print as
    sigma %; inf for an estimate of 0, NaN without a sigma."""
    bp = params["base_parameters"]
    cf = float((params.get("metrics") or {}).get("residual_correlation_factor") or 1.0)
    val = np.asarray(bp["values"], float)
    sd = np.array([np.nan if x is None else x for x in bp.get("sigma", [None] * val.size)], float)
    return np.where(np.abs(val) > 1e-12, cf * sd / np.maximum(np.abs(val), 1e-300), np.inf)


def format_robot_table(params: dict) -> str:
    """Plain-text summary of a robot fit (at most 40 lines): per-joint friction and the choices made
    for it, link masses against the URDF, the base parameters the data determine (corrected
    relative sigma under :data:`DETERMINED`; the best :data:`TABLE_BASE_ROWS`), one line on what
    the data leave undetermined, and the fit's checks. Everything is in the file as well."""
    mt = params.get("metrics") or {}
    st = params.get("settings") or {}
    fr = params["friction"]
    vals = fr["values"]
    axes = params.get("axes") or []
    n = len(axes)
    rob = params.get("robot") or {}
    cf = float(mt.get("residual_correlation_factor") or 1.0)
    lines = [f"robot {rob.get('name', '?')}: {n} axes, {mt.get('samples', '?')} samples fitted",
             "relative error on them: " + " ".join(f"A{a} {100 * r:.1f}%" for a, r in zip(axes, mt.get("relative_error_fit")
                                                                                      or []))]
    # per-joint friction
    v = st.get("v_smooth")
    d = st.get("deadband")
    per = lambda x: list(x) if isinstance(x, list) else [x] * n  # noqa: E731
    v, d = per(v if v is not None else 0.0), per(d if d is not None else 0.0)
    K = ((mt.get("choices") or {}).get("ripple") or {}).get("chosen") or [st.get("ripple", 0)] * n
    rng = fr.get("qd_range")
    head = f"{'joint':<6}{'Fc N·m':>9}{'Fv N·m·s/rad':>13}{'offset N·m':>11}{'k N·m/rad':>10}{'v rad/s':>9}" \
           f"{'dead-band rad/s':>16}{'ripple':>7}{'Fv held beyond rad/s':>21}"
    lines += ["friction per joint: Fc tanh(x/v), x the speed beyond the dead-band; Fv qd (held beyond the fitted",
              "speeds); offset; spring k q; position ripple harmonics", head]
    for j, a in enumerate(axes):
        held = "-" if not rng else f"{rng[j][0]:+.2g}/{rng[j][1]:+.2g}"
        lines.append(f"A{a:<5}{table_number(vals.get(f'A{a}.Fc')):>9}{table_number(vals.get(f'A{a}.Fv')):>13}"
                     f"{table_number(vals.get(f'A{a}.offset')):>11}{table_number(vals.get(f'A{a}.k')):>10}{table_number(v[j], 2):>9}"
                     f"{table_number(d[j], 2, 1e-12):>16}{K[j]:>7}{held:>21}")
    if fr.get("model") == "stribeck":
        lines.append("Stribeck excess Fs-Fc: " + " ".join(f"A{a} {table_number(vals.get(f'A{a}.Fs-Fc'))}" for a in axes)
                     + f" (vs {fr.get('vs')} rad/s)")
    ch = mt.get("choices") or {}
    rot = [(k, x) for k, x in vals.items() if k.endswith(".rotor_inertia")]
    if rot:
        folded = (ch.get("rotor") or {}).get("folded") or []
        lines.append("rotor inertia kg·m²: " + " ".join(f"{k.split('.')[0]} {table_number(x)}" for k, x in rot)
                     + (f" ({', '.join(folded)}: one column with link inertias, in the least-squares base "
                        "parameters; split from them by the prior)" if folded else ""))
    elif (ch.get("rotor") or {}).get("motor_current_logs") is False:
        lines.append("no rotor inertias: the logs do not say their torques come from the motor currents "
                     "(--rotor-inertia if they do)")
    # choices and their evidence
    ho = ch.get("held_out")
    if ho:
        lines.append(f"v, ripple and spring chosen per joint by held-out error ({ho.get('folds')}): the simplest within "
                     f"{100 * (SIMPLER_WITHIN - 1):.0f} % of the best")
    co = ch.get("cutoff")
    if co:
        lines.append(cutoff_line(co))
    vn = (ch.get("v_smooth") or {}).get("velocity_noise")
    if vn:
        lines.append(f"dead-band {NOISE_DEADBAND:g} x the velocity noise of the positions ({min(vn):.2g} to "
                     f"{max(vn):.2g} rad/s): no Coulomb torque from noise at rest")
    # link masses
    std = params.get("standard_parameters")
    mb = st.get("mass_bounds")
    if std and rob.get("urdf"):
        why = "not found: --urdf PATH"
        try:
            urdf = RobotModel(rob["urdf"])
            if rob.get("sha256") and urdf.sha256 != rob["sha256"]:  # edited since the fit: its masses are others
                why = "is not the one the file was fitted with (its sha256): --urdf PATH of that one"
                raise ParamFileError(why)
            nominal = urdf.pi_nominal[0::10]
            ratio = [std[lk]["m"] / m0 if m0 > 0 else float("nan") for lk, m0 in zip(rob.get("links", std), nominal)]
            flag = lambda r: "*" if mb and (r <= mb[0] * 1.001 or r >= mb[1] * 0.999) else ""  # noqa: E731
            lines.append("link masses / URDF: " + " ".join(f"{r:.2f}{flag(r)}" for r in ratio)
                         + (f" (bounds {mb[0]:g}-{mb[1]:g}x, * on a bound)" if mb else " (no bounds)"))
        except Exception:  # noqa: BLE001 (the URDF moved or was edited: the masses alone)
            lines.append("link masses kg: " + " ".join(table_number(std[lk]["m"]) for lk in std)
                         + f" (its URDF {rob['urdf']} {why} gives them as multiples of the URDF's)")
    mcheck = ch.get("mass_bounds")
    if mcheck and mcheck.get("why"):
        lines.append(f"masses on a bound ({', '.join(mcheck.get('links_on_bound') or [])}): {mcheck['why']}")
    # base parameters the data determine
    bp = params["base_parameters"]
    val = np.asarray(bp["values"], float)
    relsd = relative_sigma(params)
    has = np.flatnonzero(np.isfinite(relsd))
    order = has[np.argsort(relsd[has])]
    ndet = int(np.sum(relsd[has] < DETERMINED))
    lines.append(f"base parameters, best determined first ({ndet} of {val.size} with sigma < {100 * DETERMINED:g} %):")
    lines.append(f"  {'parameter':<52}{'estimate':>11}{'sigma %':>9}")
    for i in order[:TABLE_BASE_ROWS]:
        lines.append(f"  {_short(bp['names'][i], 52):<52}{table_number(val[i]):>11}{_pct(relsd[i]):>9}")
    undet = val.size - ndet
    if undet:
        nosd = int(val.size - has.size)
        lines.append(f"not identifiable from these data: {undet} of {val.size} base parameters (sigma >= "
                     f"{100 * DETERMINED:g} %{f' or none: {nosd}' if nosd else ''}); "
                     + ("they lean on the URDF's links" if st.get("prior_weight", PRIOR_WEIGHT) > 0 else
                        "nothing pulls them toward the URDF's links (--prior-weight 0): their estimates are "
                        "whatever the bounds and the physical consistency leave"))
    at = mt.get("at_bound") or []
    lines.append(f"sigma: least squares x the residual correlation factor {cf:.2f}; condition number "
                 f"{table_number(mt.get('condition_number'))}; physically consistent: {'yes' if mt.get('physically_consistent') else 'no'}")
    lines.append(f"on a bound: {', '.join(at) or 'none'}")
    eff = params.get("effects") or {}
    if eff:
        lines.append(f"effects named by kukaid diagnose, predicted with ({len(eff)}):")
        lines += [f"  {robot_effects.describe(k, e)}" for k, e in eff.items()]
    lines += [f"warning: {w}" for w in mt.get("warnings") or ()]
    return "\n".join(lines)
