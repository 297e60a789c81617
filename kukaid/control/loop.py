"""The sensorless admittance loop: measure, estimate Γr, update the reference, bound it, send it.

Per control cycle (12 ms = the KRC sample time; the paper's ~24 ms as an option):

1. the new measurements go through :class:`~kukaid.control.torque_residual.TorqueResidual`;
2. the watchdog checks the age of the latest measurement (stale or missing: hold and stop);
3. while an external torque is detected, the admittance (eqs. 15-16) integrates Γr, with a
   constant or an RBF-adapted damping (eqs. 17-22); otherwise it integrates zero (the reference
   decelerates with the time constant I/D and stops), except a torque against the reference's
   motion (a person braking the coasting axis), which is applied until the reference stands;
   the damping is at least the floor of the oscillation monitor
   (:mod:`kukaid.control.stability`); under the start threshold a detection holds only while
   Γr / D is faster than the model's Stribeck velocity (slower, the model's friction is least
   certain, and its error alone would creep a heavily damped axis on);
4. the reference is clipped by :class:`~kukaid.control.safety.ReferenceLimiter` and sent.

Before the admittance is enabled the axis makes the paper's initiation move (section 3.4: move
``init_move`` rad and stop, so the Maxwell-slip elements are saturated, eq. 12) and rests for
``init_rest`` s while Γu is estimated.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field, asdict
from typing import Any, Callable

import numpy as np

from kukaid.control.admittance import Admittance, check_admittance
from kukaid.control.filters import CausalButterworth
from kukaid.control.rbf import RBFConfig, RBFDamping
from kukaid.control.robot_residual import GuidedAxisResidual, RobotTorqueModel
from kukaid.control.safety import ReferenceLimiter, SafetyLimits, Watchdog
from kukaid.control.stability import CouplingConfig, CouplingFloor, OscillationMonitor, StabilityConfig, StickSlipWatch
from kukaid.control.torque_residual import DYNAMIC, RELEASE_SHARE, TorqueResidual
from kukaid.errors import KukaidError

PHASE_INIT, PHASE_REST, PHASE_ADMITTANCE, PHASE_STOPPED = 0, 1, 2, 3


#: the longest time constant I / D (s) with which the reference's speed falls once nobody pushes: a
#: lighter damping (D 1e-6 with I 20: trial 18) coasts on after a release, and integrates any model error
#: read as a push for as long (the axis ran 11 degrees back with nobody there); the paper's D 50 with I 20
#: is 0.4 s, the adaptive law's default floor 0.3 x that 1.3 s
MAX_COAST = 2.0

#: the lowest cut-off (Hz) of the estimator's low-pass: its 3rd-order Butterworth delays Γr by about
#: 2 / (2 pi fc) (0.32 s at 1 Hz), and a push read that late is still read after the hand let go (new-user
#: trial 21: at 1 Hz every one of eight pull and human runs detected a push after the release, at 0.05 Hz
#: the axis ran 89 degrees to the window's edge, 10.6 s of it with nobody there, and the run "completed";
#: at 2 Hz none of the eight did)
MIN_CUTOFF = 2.0


@dataclass(frozen=True)
class LoopConfig:
    """Settings of :func:`run_admittance` (SI).

    I kg·m², D N·m·s/rad (constant damping, and D0 of the adaptive one); damping "constant" or
    "adaptive"; threshold / release N·m; cycle s; duration s (of the admittance phase);
    init_move rad, init_time s, init_rest s; cutoff Hz: the estimator's low-pass (the paper's 5 Hz,
    3rd order; its delay, 63 ms at 1 Hz, is most of the loop's delay, so a higher cut-off
    lets a stiffer grip be guided with less damping, at the price of a noisier Γr);
    rbf (adaptive damping settings); limits (safety);
    stability (the online oscillation monitor that raises the damping, both modes); passivity
    (the adaptive law's floor: the damping the person must feel at the coupled mode's frequency);
    no_rest_model: run a model with no friction model at rest anyway (a robot model: it has no
    quasi-static mode, so at rest static friction can read as a push and move the axis; off by default,
    :func:`check_guidable` refuses such a model unless this is set).
    """

    I: float = 20.0
    D: float = 50.0
    damping: str = "constant"
    threshold: float = 5.0
    release: float | None = None
    cycle: float = 0.012
    sample_time: float = 0.012
    duration: float = 10.0
    init_move: float = math.radians(1.0)
    init_time: float = 0.6
    init_rest: float = 0.6
    u_window: float = 0.12
    cutoff: float = 5.0
    rbf: RBFConfig | None = None
    limits: SafetyLimits = field(default_factory=SafetyLimits)
    stability: StabilityConfig = field(default_factory=StabilityConfig)
    coupling: CouplingConfig = field(default_factory=CouplingConfig)
    no_rest_model: bool = False

    def __post_init__(self) -> None:
        if self.damping not in ("constant", "adaptive"):
            raise KukaidError(f"run-admittance: damping must be 'constant' or 'adaptive', got {self.damping!r}")
        check_admittance(self.I, self.D, self.cycle)
        n = self.cycle / self.sample_time
        if n < 0.999 or abs(n - round(n)) > 1e-6:  # each cycle uses the samples the KRC has delivered
            raise KukaidError(f"run-admittance: control cycle {self.cycle:g} s must be a whole number of sample times "
                              f"({self.sample_time:g} s: {self.sample_time:g}, {2 * self.sample_time:g}, "
                              f"{3 * self.sample_time:g} ... s)")
        if not (math.isfinite(self.threshold) and self.threshold > 0):
            raise KukaidError(f"run-admittance: threshold must be a finite number > 0 N·m, got {self.threshold}")
        if self.threshold >= self.limits.tau_max:  # the torque stop acts on |Γr|: a push detected at it trips first
            raise KukaidError(f"run-admittance: threshold {self.threshold:g} N·m must be below the torque limit "
                              f"{self.limits.tau_max:g} N·m: a push that could reach it trips the torque stop first")
        if self.release is not None and not (math.isfinite(self.release) and 0 <= self.release <= self.threshold):
            raise KukaidError(f"run-admittance: release {self.release} N·m must be in [0, threshold {self.threshold}] N·m "
                              "(a detection ends below it)")
        if not (math.isfinite(self.cutoff) and 0 < self.cutoff < 0.5 / self.sample_time):
            raise KukaidError(f"run-admittance: the estimator's cut-off {self.cutoff} Hz must be in (0, "
                              f"{0.5 / self.sample_time:g}) Hz (half the sampling rate)")
        if self.cutoff < MIN_CUTOFF:
            raise KukaidError(f"run-admittance: the estimator's cut-off {self.cutoff:g} Hz is below {MIN_CUTOFF:g} Hz: "
                              f"its low-pass would delay Γr by {2 / (2 * math.pi * self.cutoff):.2g} s, so a push "
                              "is still read after the hand lets go and the axis moves on by itself (the paper's "
                              "5 Hz delays it 0.064 s)")
        if not (math.isfinite(self.duration) and self.duration > 0):
            raise KukaidError(f"run-admittance: duration must be > 0 s, got {self.duration}")
        if self.damping == "adaptive":
            r = self.rbf or RBFConfig(D0=self.D, D_min=0.3 * self.D, D_max=2.0 * self.D)
            check_admittance(self.I, r.D_max, self.cycle)
            object.__setattr__(self, "rbf", r)
        lightest = self.rbf.D_min if self.damping == "adaptive" else self.D
        if lightest < self.I / MAX_COAST:
            what = "the adaptive damping's lower bound D_min" if self.damping == "adaptive" else "the damping D"
            raise KukaidError(f"run-admittance: {what} = {lightest:g} N·m·s/rad is below I / {MAX_COAST:g} s = "
                              f"{self.I / MAX_COAST:g}: once nobody pushes, the reference would coast on with a "
                              f"time constant I / D = {self.I / lightest:.3g} s, integrating any error of the model "
                              "read as a push for as long; raise it or lower I")


    @property
    def release_torque(self) -> float:
        """|Γr| below which a detection ends, N·m (``release``, default 0.3 ``threshold``: once in contact the axis
        follows down to this smaller holding torque, not only to the start threshold)."""
        return RELEASE_SHARE * self.threshold if self.release is None else float(self.release)


@dataclass
class AdmittanceRun:
    """What :func:`run_admittance` returns: per-cycle arrays (``data``), ``metrics``, ``status``."""

    data: dict[str, np.ndarray]
    metrics: dict[str, Any]
    status: str
    config: LoopConfig

    def __iter__(self):
        return iter((self.data, self.metrics))


def run_admittance(backend: Any, model: Any, config: LoopConfig | None = None, zeta0: Any = None,
                   progress: Callable[[float], None] | None = None,
                   on_row: Callable[[dict[str, Any]], None] | None = None) -> AdmittanceRun:
    """Run the loop on ``backend`` (a :class:`kukaid.robot.Robot`) with the identified ``model``.

    Returns an :class:`AdmittanceRun`; ``status`` is "completed" or "stopped: <reason>" (a stale
    or missing measurement, the torque limit, a controller error, an interrupt).  Whatever ends
    the run, the backend is told to hold and what was recorded until then is returned.
    ``progress(t)`` is called with the seconds run so far, ``on_row(row)`` with every cycle's
    record as it is made (to write it to disk while the robot moves).
    """
    cfg = config or LoopConfig()
    check_guidable(model, cfg.no_rest_model, cfg.init_move)
    if isinstance(model, RobotTorqueModel):  # a robot model: Γr of the guided axis from every axis's motion
        est = GuidedAxisResidual(model, backend.axis, sample_time=cfg.sample_time, threshold=cfg.threshold,
                                 release=cfg.release_torque, cutoff=cfg.cutoff)
    else:
        est = TorqueResidual(model, sample_time=cfg.sample_time, threshold=cfg.threshold, release=cfg.release,
                             zeta0=zeta0, u_window=cfg.u_window, cutoff=cfg.cutoff)
    samples = backend.start()
    try:
        if not samples:
            raise KukaidError("run-admittance: no measurement from the backend at start")
        for s in samples:
            r = est.update(*_measured(s, est))
        check_init_room(model, cfg, samples[-1].q)
        limiter = ReferenceLimiter(cfg.limits, cfg.cycle, samples[-1].q)
        stab = cfg.stability
        if cfg.damping == "adaptive" and cfg.coupling.enabled:
            # the grip floor acts on the second half-cycle; the monitor backs it up one half-cycle later
            stab = dataclasses.replace(stab, lobes=max(stab.lobes, cfg.coupling.monitor_lobes),
                                       enabled=stab.enabled and cfg.coupling.monitor_lobes < 100,
                                       raise_rule=cfg.coupling.monitor_rule, zeta=cfg.coupling.zeta)
        mon = OscillationMonitor(stab, cfg.cycle, cfg.D, D_limit=0.9 * 2.0 * cfg.I / cfg.cycle, I=cfg.I)
        grip = None
        if cfg.damping == "adaptive" and cfg.coupling.enabled:  # the constant damping stays the paper's
            lp = CausalButterworth(est.cutoff, 1.0 / est.sample_time, est.order)  # the estimator's low-pass
            grip = CouplingFloor(cfg.coupling, cfg.cycle, cfg.I, D_cap=mon.D_cap, filter_delay=lp.phase_delay, D0=cfg.D)
        slip = StickSlipWatch(cfg.cycle, cap=getattr(est, "floor_cap", 3.0) * cfg.threshold)
        log, status = _loop(backend, est, r, limiter, mon, grip, slip, samples[-1], cfg, progress, on_row)
    except BaseException:
        backend.hold()
        backend.close()
        raise
    backend.close()
    data = {k: np.asarray(v, dtype=bool if k in ("dynamic", "detected", "clipped") else float)
            for k, v in log.items()}
    data["phase"] = data["phase"].astype(np.int8)
    metrics = run_metrics(data, cfg)
    metrics["status"] = status
    metrics["clipped_cycles"] = int(limiter.clipped)
    events = sorted(mon.events + (grip.events if grip is not None else []), key=lambda e: e["time"])
    metrics["stability_events"] = len(events)
    if events:  # when and why the damping was raised (times on the run's time axis)
        t_adm = (cfg.init_time if cfg.init_move else 0.0) + cfg.init_rest
        metrics["stability_log"] = [{**e, "time": e["time"] + t_adm} for e in events[:20]]
    if grip is not None:
        # no grip seen (no rebound of a hand): none estimated, not a stiffness of 0 (the report's table: —)
        metrics["grip_stiffness"] = grip.K_est if grip.K_est > 0 else math.nan
        metrics["loop_delay"] = grip.T_est
        metrics["robot_lag"] = grip.robot_lag
    if est.ignored_effects:
        metrics["ignored_effects"] = est.ignored_effects
    rest_thr = getattr(est, "rest_threshold_max", cfg.threshold)
    metrics["rest_threshold_max"] = float(rest_thr)
    if rest_thr > 1.2 * cfg.threshold:  # the model's friction at rest is clearly worse than the threshold assumes
        rms = float(est.rest_rms_max)
        metrics["rest_rms_max"] = rms
        cap = est.floor_cap * cfg.threshold
        rose = (f"the threshold at rest rose from {cfg.threshold:g} N·m to its cap of {rest_thr:.3g} N·m "
                f"({est.floor_cap:g} x --threshold; {est.floor_k:g} x the RMS asked for {est.floor_k * rms:.3g} N·m)"
                if rest_thr >= cap * (1 - 1e-9) else
                f"the threshold at rest rose from {cfg.threshold:g} to {rest_thr:.3g} N·m ({est.floor_k:g} x the RMS)")
        metrics.setdefault("warnings", []).append(
            f"at rest, with nothing detected, Γr wandered so far (up to {rms:.3g} N·m RMS) that {rose}, and a push "
            "there needs that much: a hand that leaned on the axis before it was taken for a push, or the parameter "
            "file's friction at rest off (then refit its Maxwell-slip elements: kukaid fit --presliding; a drive "
            "whose friction at rest is not Maxwell-slip, e.g. LuGre bristles, keeps the threshold raised after a "
            "refit)")
    standing = float(getattr(est, "standing_max", 0.0))
    metrics["standing_max"] = standing
    if standing > 0.0:  # not a push, but the run should say it happened
        metrics.setdefault("warnings", []).append(
            f"at rest Γr stood at up to {standing:.3g} N·m when the start threshold fell below it (a hand still on "
            "the axis after braking it, or the parameter file's friction at rest off by that much): it was not "
            "taken for a push, and a push there needed that much more")
    # the widest drift Γu followed in one rest (a servo winding up, a hand leaning in, a hand held on while
    # the axis stood): a push against it needed that much more; not a warning: a held hand makes one in
    # most guided runs on a LuGre plant (2-12 N·m)
    metrics["rest_drift_max"] = float(getattr(est, "drift_max", 0.0))
    metrics["stick_slip_margin"] = slip.margin
    if slip.margin > 0.0:
        metrics.setdefault("warnings", []).append(
            f"a stick-slip cycle with nobody there: {slip.starts} detections in a row started against the axis's last "
            f"motion just after it stopped, so the start threshold at a stop was raised to {slip.margin:.3g} N·m for "
            "the rest of the run: the parameter file's friction at a stop is not this axis's (a breakaway above the "
            "file's); refit it on a recent log (kukaid fit ... --presliding LOG)")
    return AdmittanceRun(data=data, metrics=metrics, status=status, config=cfg)


def init_reference(cfg: LoopConfig, q_start: float, x: float) -> float:
    """The initiation move's reference (rad) at ``x`` (0 to 1) of its duration: a quintic from ``q_start``
    to ``q_start + init_move`` (eq. 12's move), as the loop runs it and :func:`check_init_room` checks it."""
    return q_start + cfg.init_move * x ** 3 * (10 - 15 * x + 6 * x * x)


def init_move_needed(model: Any) -> float:
    """The shortest initiation move (rad) that saturates every Maxwell-slip element of a one-axis ``model``
    from any state: twice the largest break-away displacement (0 for a model without elements)."""
    ms = getattr(model, "maxwell_slip", None)
    return 2.0 * float(np.max(ms.breakaway)) if ms is not None and len(ms.k) else 0.0


def check_init_room(model: Any, cfg: LoopConfig, q_start: float) -> None:
    """Refuse, before anything moves, a one-axis run whose initiation move from ``q_start`` (rad) the reference
    limits (the position window, ``qd_max``, ``qdd_max``) would cut below :func:`init_move_needed`: the move is
    the loop's check of the parameter file, and a move cut to nothing skipped it (new-user trial 21: a file with
    gravity's sign flipped, stopped before control from 30 degrees in [-60, 90], was guided from 30 in [-60, 30]
    and ran the axis 90 degrees to the window's other edge with nobody there, "completed"; with --qd-max 0.03 the
    same file was guided too).  The move and the rest after it are run through the limiter as the loop runs them."""
    if isinstance(model, RobotTorqueModel) or not cfg.init_move:
        return
    need = init_move_needed(model)
    lim = ReferenceLimiter(cfg.limits, cfg.cycle, q_start)
    reach = peak = 0.0
    for k in range(int(math.ceil((cfg.init_time + cfg.init_rest) / cfg.cycle))):
        x = min((k + 1) * cfg.cycle / cfg.init_time, 1.0)
        q, _ = lim.apply(init_reference(cfg, q_start, x))
        reach = max(reach, (q - q_start) * math.copysign(1.0, cfg.init_move))
        peak = max(peak, abs(lim.v))
    qd_thr = float(getattr(model, "qd_thr", 0.0))
    if reach >= need and peak >= qd_thr:
        return
    lo, hi = cfg.limits.q_min, cfg.limits.q_max
    edge = hi if cfg.init_move > 0 else lo
    if reach >= need:  # far enough, but never as fast as the file's dynamic mode: its sliding model goes unchecked
        raise KukaidError(f"run-admittance: the initiation move ({math.degrees(cfg.init_move):+g} deg, --init-move) "
                          f"would reach at most {math.degrees(peak):.3g} deg/s, below the parameter file's dynamic-mode "
                          f"speed (mode_switch.qd_thr {qd_thr:.3g} rad/s = {math.degrees(qd_thr):.3g} deg/s): the move "
                          "is the check of the file before control, and below that speed its sliding model (gravity, "
                          "friction) goes unchecked; nothing moved; raise --qd-max/--qdd-max, or give a longer "
                          "--init-move (its speed grows with its length), or check the file's qd_thr (kukaid show)")
    if abs(edge - q_start) < need:  # the window's edge
        room = q_start - lo if cfg.init_move > 0 else hi - q_start
        fix = (f"move the other way (--init-move {-math.degrees(cfg.init_move):+g}; {math.degrees(room):.3g} deg of "
               "room there), or start farther from the window's edge" if room >= need else
               "start farther from the window's edge")
        what = f"the position window [{math.degrees(lo):.4g}, {math.degrees(hi):.4g}] deg"
    else:
        what, fix = "the reference's speed and acceleration limits (--qd-max, --qdd-max)", "raise them"
    raise KukaidError(f"run-admittance: the initiation move ({math.degrees(cfg.init_move):+g} deg, --init-move) from "
                      f"{math.degrees(q_start):.4g} deg would be cut by {what} after {math.degrees(reach):+.3g} deg, "
                      f"less than the {math.degrees(need):.3g} deg that set the file's Maxwell-slip elements: the move "
                      "is the check of the parameter file before control, and without it a wrong file moves the axis "
                      f"by itself; nothing moved; {fix}")


#: the fewest dynamic-mode samples of the initiation move whose mean Γr along it the loop judges (the
#: default 1 degree move gives about 40 at 12 ms)
MIN_ALONG = 10

#: the most Γr may push along the loop's own initiation move (its mean while read as moving), as a share of the
#: start threshold, before the run is stopped before control.  Measured (stop 43) with the people, rest and foreign
#: benchmarks' own fitted files: at most 0.81 (99th percentile 0.78, 1080 people runs; 0.77 at rest, 0.26 on
#: the foreign plant); the demo's file with Fc, Fs and Fv scaled 1.3 x (0.91-1.10, 64 runs) detected after a
#: release in 4 runs, one of them 12.8 degrees, the first at 0.934; 1.2 x (0.61-0.80) in none
RUNAWAY_SHARE = 0.85

#: the default detection threshold, N·m (the paper's), and, on an axis with more friction, its share of the
#: file's Coulomb friction (on every axis of the paper's A3's size, Coulomb friction up to 19.6 N·m, below 5)
THRESHOLD, THRESHOLD_SHARE = 5.0, 0.25


def default_threshold(model: Any) -> float:
    """The detection threshold when none is given, N·m: 5 (the paper's), or a quarter of a one-axis model's
    Coulomb friction when that is more.  A model's error at rest grows with the axis's friction, and on a
    gravity-loaded axis (an A2, gravity 3-5 x the paper's A3's, friction 1-2 x) 5 N·m left LuGre plants moving
    by themselves in 18 of 480 runs with nobody there (`admittance_rest.py --files fitted --outside heavy`),
    10 of them not with this."""
    fc = getattr(getattr(model, "friction", None), "Fc", None)
    return max(THRESHOLD, THRESHOLD_SHARE * abs(float(fc))) if fc is not None else THRESHOLD


def check_guidable(model: Any, no_rest_model: bool = False, init_move: float | None = None) -> None:
    """Refuse, before anything moves, a model whose friction at rest cannot tell static friction from a
    push, so that the axis would move by itself with nobody touching it: a one-axis model without
    Maxwell-slip elements (measured: 3.5 degrees in 20 s), and a robot model, which has no quasi-static
    mode (the LWR4+ fit moved A2 of its virtual robot 2.6 degrees in 5 s) unless ``no_rest_model``
    (:attr:`LoopConfig.no_rest_model`) asks for it to be run anyway.  With ``init_move`` (rad), a
    one-axis model's initiation move must saturate every element from any state (twice the largest
    break-away displacement): it sets their state (eq. 12), and it is the loop's check of the file
    before control (a file whose elements break away at 50-70 N·m passed a run without the move and
    moved the axis 1.7 degrees with nobody there, where the move stops it before control)."""
    if isinstance(model, RobotTorqueModel):
        if not no_rest_model:
            raise KukaidError("run-admittance: a robot parameter file has no friction model at rest (no quasi-static "
                              "mode), so at rest static friction cannot be told from a push and the axis moves by itself "
                              "(the LWR4+ fit, A2 on its virtual robot: 2.6 degrees in 5 s with nobody there); guide the "
                              "axis with a one-axis file with Maxwell-slip elements (kukaid fit ... --presliding LOG), or "
                              "pass --no-rest-model to run this one anyway")
        return
    if no_rest_model:
        raise KukaidError("run-admittance: --no-rest-model is for a robot parameter file (a one-axis file has its "
                          "model at rest)")
    ms = getattr(model, "maxwell_slip", None)
    if ms is None or len(ms.k) == 0:
        raise KukaidError("run-admittance: the parameter file has no Maxwell-slip elements, so at rest static "
                          "friction cannot be told from a push and the axis would move by itself; fit them from a "
                          "pre-sliding experiment (kukaid excite presliding, kukaid capture, then kukaid fit ... "
                          "--presliding LOG)")
    need = init_move_needed(model)
    if init_move is not None and abs(init_move) < need:
        raise KukaidError(f"run-admittance: an initiation move of {math.degrees(init_move):g} deg (--init-move) is "
                          f"shorter than {math.degrees(need):.3g} deg, twice the largest break-away displacement of the "
                          "file's Maxwell-slip elements: the move sets their state (eq. 12), and with nobody touching "
                          "it checks the file before control (a model that misses it by more than the threshold at "
                          "rest can reach stops the run there); without it the axis can move by itself; give "
                          f"--init-move of at least {math.degrees(need):.3g} deg either way (default 1)")


def _measured(s: Any, est: Any) -> tuple[Any, Any]:
    """What the estimator reads of a sample: every axis for a robot model, else the controlled axis."""
    if isinstance(est, GuidedAxisResidual):
        if s.q_all is None:
            raise KukaidError("run-admittance: a robot parameter file needs the positions and torques of every axis, "
                              "and the backend gives only the controlled one")
        return s.q_all, s.tau_all
    return s.q, s.tau


_KEYS = ("time", "q", "tau", "tau_ext_true", "gamma_r", "gamma_p", "sigma", "sigma_dot", "q_cmd", "D",
         "dynamic", "detected", "phase", "clipped", "osc_index", "D_floor", "D_grip")


def _loop(backend: Any, est: TorqueResidual, r: Any, limiter: ReferenceLimiter, mon: OscillationMonitor,
          grip: CouplingFloor | None, slip: StickSlipWatch,
          first: Any, cfg: LoopConfig,
          progress: Callable[[float], None] | None,
          on_row: Callable[[dict[str, Any]], None] | None) -> tuple[dict[str, list], str]:
    """The control cycles from the estimator's latest step ``r`` and measurement ``first``; returns
    the per-cycle record and the status."""
    dog = Watchdog(cfg.limits.max_age)
    dog.feed(first.t)
    q_start, t0, last = first.q, first.t, first
    adm = Admittance(cfg.I, cfg.D, cfg.cycle, sigma0=q_start)
    rbf = RBFDamping(cfg.rbf) if cfg.damping == "adaptive" else None
    if rbf is not None:
        rbf.set_cycle(cfg.cycle)
    t_init_end = cfg.init_time if cfg.init_move else 0.0
    t_adm = t_init_end + cfg.init_rest
    rest = RestHold(cfg.cycle)
    q_hold = q_start + cfg.init_move
    log: dict[str, list] = {k: [] for k in _KEYS}
    D_now = cfg.D
    m = getattr(est, "model", None)  # a one-axis model with Stribeck friction: its Stribeck velocity
    v_hold = float(m.vs) if getattr(m, "friction_kind", None) == "stribeck" else 0.0
    n_cycles = int(math.ceil((t_adm + cfg.duration) / cfg.cycle - 1e-9))
    phase = PHASE_INIT
    # the most a model's error at rest may be: what the start threshold at rest can rise to
    init_cap = getattr(est, "floor_cap", 3.0) * cfg.threshold
    init_max = abs(r.gamma_r)  # Γr's largest size during the loop's own move and rest, N·m
    for k in range(n_cycles):
        tr = (k + 1) * cfg.cycle  # time since start at the end of this cycle
        if tr <= t_adm:  # initiation move (eq. 12), then rest while Γu settles
            x = min(tr / cfg.init_time, 1.0) if cfg.init_move else 1.0
            phase = PHASE_INIT if tr <= t_init_end else PHASE_REST
            q_ref = init_reference(cfg, q_start, x)
            if phase == PHASE_REST:
                q_hold = rest.step(q_hold, last.q, moving=r.mode == DYNAMIC, contact=r.detected)
                q_ref = q_hold
            q_cmd, clipped = limiter.apply(q_ref)
            adm.reset(q_cmd)
            sd = 0.0
        else:
            why = _unguidable(init_max, init_cap, log, cfg) if phase != PHASE_ADMITTANCE else None
            if why:
                backend.hold()
                return log, (f"stopped: before control, with nobody touching the axis, {why}, so nothing was guided; "
                             f"{_init_advice(cfg)}")
            if phase != PHASE_ADMITTANCE and hasattr(est, "nobody_was_there"):
                est.nobody_was_there()  # the loop's own move and rest: nothing read there was a hand
            phase = PHASE_ADMITTANCE
            sd0 = adm.sigma_dot
            if hasattr(est, "cycle_margin"):  # a one-axis model: its friction at a stop
                est.cycle_margin = slip.step(sd0, r.detected, r.gamma_r)
            if r.detected and abs(r.gamma_r) < min(cfg.threshold, D_now * v_hold):
                # below the start threshold a detection holds only while what it commands is faster than
                # the Stribeck velocity: slower, the model's friction is at its least certain, and a
                # residual of a few N·m from it (a person gone, a damping raised to 500) crept the axis on
                est.end_detection()
                r = dataclasses.replace(r, detected=False)
            # a detected push drives the admittance; below the detection only a torque against
            # the reference's motion is applied (a person braking the coasting axis), and never
            # so far that it reverses it: it can only take energy out
            braking = not r.detected and sd0 * r.gamma_r < 0.0
            gamma = r.gamma_r if (r.detected or braking) else 0.0
            floor = mon.step(r.gamma_r, D_now, contact=r.detected)
            D_base = cfg.D
            if rbf is not None:  # no learning while the monitor damps an oscillation
                D_base = rbf.step(r.gamma_r, direction=adm.sigma_dot if adm.sigma_dot != 0 else gamma,
                                  adapt=r.detected and not mon.oscillating)
            if grip is not None:
                floor = max(floor, grip.step(r.gamma_r, contact=r.detected, D_in_use=D_now))
            D_now = max(D_base, floor)
            sigma, sd = adm.step(gamma, D_now)
            if (braking and sd * sd0 < 0.0) or (not r.detected and abs(sd) < rest.v_stop):
                adm.reset(sigma, 0.0)  # braked or coasted to a stop: the reference stands
                sd = 0.0
            if sd == 0.0:
                sigma = rest.step(sigma, last.q, moving=r.mode == DYNAMIC, contact=r.detected)
                adm.reset(sigma, 0.0)
            else:
                rest.restart()
            q_cmd, clipped = limiter.apply(sigma)
            if clipped:  # no wind-up: the admittance continues from what was sent
                adm.reset(q_cmd, limiter.v)
                sd = limiter.v
        stop = None
        try:
            new = backend.cycle(q_cmd, cfg.cycle)
        except KeyboardInterrupt:
            new, stop = [], "interrupted"
        except KukaidError as e:  # the controller stopped answering, refused a write, ...
            new, stop = [], str(e)
        for s in new:
            r = est.update(*_measured(s, est), (s.t - last.t) if s.t > last.t else None)
            if phase != PHASE_ADMITTANCE:
                init_max = max(init_max, abs(r.gamma_r))
            if r.detected and phase != PHASE_ADMITTANCE:
                # the initiation move and the rest after it are the loop's own, before anyone may touch the
                # axis: what the estimator detects there is its model's error, and a detection carried into
                # the admittance phase drove the axis (held-out LuGre plants: 1.4-6 degrees, nobody there)
                est.end_detection()
                r = dataclasses.replace(r, detected=False)
            last = s
            dog.feed(s.t)
        if grip is not None and phase == PHASE_ADMITTANCE and new:
            grip.observe_robot(q_cmd, last.q)
        if stop is None and not dog.check(backend.now()):
            stop = dog.tripped
        if stop is None and slip.stop is not None:
            stop = f"{slip.stop} at t = {last.t - t0:.3f} s"
        # the torque stop bounds the torque a person or an obstacle exerts (as the KRC's collision detection
        # bounds the measured torque's difference from its model): the measured torque carries the gravity load
        # and the other axes' motion too, which tripped a 100 N·m stop on A2 of a KR 6 under a 55 N·m push from
        # above and let a push from below reach 145 N·m.  During the loop's own initiation move and rest Γr steers
        # nothing and nobody touches the axis: what it reads there is the model's error, which stops the run
        # before control (above)
        if stop is None and phase == PHASE_ADMITTANCE and abs(r.gamma_r) > cfg.limits.tau_max:
            stop = (f"external torque Γr {r.gamma_r:.1f} N·m (the model's torque minus the measured {last.tau:.1f} "
                    f"N·m) beyond the limit {cfg.limits.tau_max:g} N·m at t = {last.t - t0:.3f} s")
        t_row = last.t
        if stop is not None:
            backend.hold()
            phase = PHASE_STOPPED
            t_row = max(last.t, backend.now())  # a stale measurement: the row is the moment motion stopped
        row = {"time": t_row - t0, "q": last.q, "tau": last.tau, "tau_ext_true": last.tau_ext_true,
               "gamma_r": r.gamma_r, "gamma_p": r.gamma_p, "sigma": adm.sigma, "sigma_dot": sd, "q_cmd": q_cmd,
               "D": D_now, "dynamic": r.mode == DYNAMIC, "detected": r.detected, "phase": phase, "clipped": clipped,
               "osc_index": mon.index, "D_floor": mon.floor,
               "D_grip": grip.floor if grip is not None else 0.0}
        if last.q_all is not None:  # a robot backend reads every axis each cycle: kept in the run's data
            row["q_all"], row["tau_all"] = np.asarray(last.q_all, float), np.asarray(last.tau_all, float)
        for key, v in row.items():
            log.setdefault(key, []).append(v)
        if on_row is not None:
            on_row(row)
        if stop is not None:
            return log, f"stopped: {stop}"
        if progress is not None and k % 25 == 0:
            progress(tr)
    return log, "completed"


class RestHold:
    """Where the reference stands when the axis rests: where the axis actually stopped.

    A position servo with an integrator keeps pushing towards a reference the axis stopped short
    of or overshot (the settling of the initiation move, the tail of a coasting reference), and
    against static friction its torque then ramps with no motion at all: to a sensorless estimator
    exactly a person holding the axis.  So once the reference has stood for ``settle`` s with the
    estimator quasi-static and nothing detected, the reference moves (once per rest) to the
    measured position, if that is within ``max_shift`` rad (farther is not settling: then the
    reference stays).  A reference coasting slower than ``v_stop`` rad/s with nothing detected is
    stopped.
    """

    def __init__(self, cycle: float, settle: float = 0.25, max_shift: float = math.radians(0.05),
                 v_stop: float = 2e-3) -> None:
        self.need = max(1, int(round(settle / cycle)))
        self.max_shift, self.v_stop = max_shift, v_stop
        self.count = 0
        self.done = False

    def restart(self) -> None:
        """The reference moves (or a push is on): the next rest is counted from its start."""
        self.count, self.done = 0, False

    def step(self, q_ref: float, q_meas: float, moving: bool, contact: bool) -> float:
        """The reference to hold this cycle (``q_ref`` standing; ``moving``/``contact``: start over)."""
        if moving or contact:
            self.restart()
            return q_ref
        self.count += 1
        if self.done or self.count < self.need:
            return q_ref
        self.done = True
        return q_meas if abs(q_meas - q_ref) <= self.max_shift else q_ref


def run_metrics(data: dict[str, np.ndarray], cfg: LoopConfig) -> dict[str, Any]:
    """Detection delay, Γr vs true external torque, the paper's experiment-4 costs, steady state.

    * ``detection_delay`` s: from the first cycle with |tau_ext_true| >= threshold to the first
      detection (admittance phase; NaN when there is no truth or no push);
    * ``residual_rmse`` N·m (all of the admittance phase), also ``_dynamic`` / ``_quasi_static``;
    * ``mean_sq_dgamma`` N²m² and ``mean_cost`` (ξ = ½ dΓr² + ½ λ Γr², eq. 19) over the
      interaction (first to last detection), with λ = ``lam``;
    * ``false_detections``: detected cycles with |tau_ext_true| < 1 N·m before the first push;
    * ``settled``: at the end the reference stands (|σ̇| < 1e-3 rad/s), no detection, and (with
      the truth) nobody pushes: the true external torque over the last 0.25 s is below the
      detection threshold on average (a push still on but never detected is not a settled run);
    * ``displacement`` rad: the measured q at the end minus q when the admittance started (the summary's
      "measured displacement"); ``peak_speed`` rad/s: the largest speed of the reference sent while it
      moved (within --qd-max), not the axis's ("reference peak speed": 0 when nothing was detected,
      though the axis may creep);
    * ``false_after_release`` (with the truth): detected cycles from 0.3 s after the last cycle
      with |tau_ext_true| >= 1 N·m on (nobody touching);
    * ``warnings``: the run did not settle; (with the truth) the estimate disagreed grossly with
      what happened — Γr's error RMS above both the threshold and half the true torque's RMS (a
      push the controller did not see, or a simulation that went wrong) — or a push still on at
      the end; a detection with nobody touching (before the first push or after the release); Γr
      beyond the threshold with nobody touching (not taken for a push), also during the initiation move
      and rest (``init_residual_max`` N·m: nothing detected there drives the axis; ``init_push_along`` N·m,
      Γr's mean along the initiation move while read as moving, which stops the loop from ``RUNAWAY_SHARE`` x the
      threshold); the initiation move
      cut short by the position window.  :func:`run_admittance`
      adds one when the threshold at rest had to rise by over 20 % (the model's friction at rest is off).
    """
    lam = cfg.rbf.lam if cfg.rbf is not None else RBFConfig().lam
    ph = data["phase"] == PHASE_ADMITTANCE
    t, gr, te = data["time"], data["gamma_r"], data["tau_ext_true"]
    det, dyn = data["detected"], data["dynamic"]
    out: dict[str, Any] = {"lambda": lam, "threshold": cfg.threshold, "release": cfg.release_torque,
                           "damping": cfg.damping, "I": cfg.I, "D": cfg.D, "cycle": cfg.cycle, "cutoff": cfg.cutoff}
    has_truth = bool(np.any(np.isfinite(te[ph])))
    idx = np.flatnonzero(ph)
    if idx.size == 0:
        return out
    if has_truth:
        push = np.flatnonzero(ph & (np.abs(te) >= cfg.threshold))
        d_on = np.flatnonzero(ph & det)
        if push.size:
            # the push's detection: the first from when the hand touched (|tau_ext_true| >= 1 N·m), at most 1 s
            # before its torque reached the threshold; one already on then began with nobody there (a false
            # detection, said apart), and gives no delay (it gave -0.996 s on the LWR4+'s A1)
            untouched = np.flatnonzero((np.abs(te) < 1.0) & (np.arange(t.size) < push[0]))
            start = max(untouched[-1] + 1 if untouched.size else 0, push[0] - int(round(1.0 / cfg.cycle)))
            later = d_on[d_on >= start]
            carried = start > 0 and bool(det[start - 1])
            out["detection_delay"] = float(t[later[0]] - t[push[0]]) if later.size and not carried else math.nan
        else:
            out["detection_delay"] = math.nan
        e = gr - te
        out["residual_rmse"] = float(np.sqrt(np.mean(e[ph] ** 2)))
        for name, m in (("dynamic", ph & dyn), ("quasi_static", ph & ~dyn)):
            out[f"residual_rmse_{name}"] = float(np.sqrt(np.mean(e[m] ** 2))) if m.any() else math.nan
        first_push = push[0] if push.size else idx[-1] + 1
        pre = ph & (np.arange(t.size) < first_push) & (np.abs(te) < 1.0)
        out["false_detections"] = int(np.sum(det & pre))
    d_idx = np.flatnonzero(ph & det)
    if d_idx.size:
        w = slice(d_idx[0], d_idx[-1] + 1)
        g = gr[w]
        dg = np.diff(gr[max(d_idx[0] - 1, 0):d_idx[-1] + 1])
        dg = dg[-g.size:]
        out["mean_sq_dgamma"] = float(np.mean(dg ** 2))
        out["mean_cost"] = float(np.mean(0.5 * dg ** 2 + 0.5 * lam * g ** 2))
        out["interaction_time"] = float(t[d_idx[-1]] - t[d_idx[0]])
        out["mean_abs_gamma"] = float(np.mean(np.abs(g)))
    else:
        out["mean_sq_dgamma"] = out["mean_cost"] = math.nan
    out["displacement"] = float(data["q"][idx[-1]] - data["q"][idx[0]])
    # the speed of the reference sent while it moved (the limiter's: the admittance's own σ̇ at the end of a
    # cycle may be beyond --qd-max before the next cycle clips it; a rest's one shift to where the axis
    # stopped is no motion)
    sent = data.get("q_cmd")  # a record without it (an older log): the admittance's own σ̇
    step = (np.abs(np.diff(sent, prepend=sent[:1])) / cfg.cycle if sent is not None else np.abs(data["sigma_dot"]))
    moving = ph & (data["sigma_dot"] != 0.0)
    out["peak_speed"] = float(np.max(step[moving])) if moving.any() else 0.0
    out["settled"] = bool(abs(data["sigma_dot"][idx[-1]]) < 1e-3 and not det[idx[-1]])
    warnings: list[str] = []
    if not out["settled"]:
        warnings.append("the run did not settle: at the end the reference still moves or a push is detected")
    if has_truth:
        te_rms = float(np.sqrt(np.nanmean(te[ph] ** 2)))
        if out["residual_rmse"] > max(cfg.threshold, 0.5 * te_rms):
            warnings.append(f"the estimated external torque disagrees grossly with the true one: error RMS "
                            f"{out['residual_rmse']:.3g} N·m against a true RMS of {te_rms:.3g} N·m "
                            f"(the motion does not reflect what the operator did)")
        tail = ph & (t >= t[idx[-1]] - 0.25)
        te_end = float(np.nanmean(np.abs(te[tail])))
        if te_end >= cfg.threshold:
            out["settled"] = False
            if not det[idx[-1]]:
                warnings.append(f"at the end the true external torque is {te_end:.3g} N·m on average (last 0.25 s), "
                                f"above the detection threshold {cfg.threshold:g} N·m, and nothing is detected")
        # nobody touching: from the release (the last true torque >= 1 N·m, + 0.3 s) on
        touched = np.flatnonzero(ph & (np.abs(te) >= 1.0))
        after = ph & (np.arange(t.size) > touched[-1] + int(round(0.3 / cfg.cycle))) if touched.size else ph
        out["false_after_release"] = int(np.sum(det & after)) if touched.size else 0
        untouched = ph & (np.abs(te) < 1.0) & ~det
        if touched.size and not np.any(det[ph]) and np.max(np.abs(te[ph])) < cfg.threshold:
            # a person pushed, never as hard as the threshold, and nothing was guided (trial 21: --threshold 99)
            warnings.append(f"the operator pushed (true external torque up to {np.max(np.abs(te[ph])):.3g} N·m) and no "
                            f"push was detected, so nothing was guided: the threshold {cfg.threshold:g} N·m "
                            "(--threshold) is above what they pushed")
        if out["false_detections"] or out["false_after_release"]:
            # a run nobody touched (--operator none) has no first push and no release to count from
            when = (f"{out['false_detections']} cycles before the first push, {out['false_after_release']} after the "
                    "release" if touched.size else f"{out['false_detections']} cycles, and nobody touched it in this run")
            warnings.append(f"detected a push with nobody touching the axis: {when} (the axis moved by itself)")
        elif untouched.any() and np.max(np.abs(gr[untouched])) >= cfg.threshold:
            warnings.append(f"with nobody touching the axis Γr reached {np.max(np.abs(gr[untouched])):.3g} N·m, "
                            f"beyond the threshold {cfg.threshold:g} N·m (not taken for a push: the threshold at "
                            "rest had risen, or the axis was starting or stopping)")
    cut = np.flatnonzero(np.asarray(data.get("clipped", False), bool) & (data["phase"] == PHASE_INIT))
    at_edge = cut.size and min(abs(data["q_cmd"][cut[0]] - cfg.limits.q_min),
                               abs(data["q_cmd"][cut[0]] - cfg.limits.q_max)) < 1e-9
    if cut.size and not at_edge:  # the speed and acceleration limits slowed it (the window did not cut it)
        init_rows = data["phase"] < PHASE_ADMITTANCE
        moved = float(np.max(np.abs(data["q_cmd"][init_rows] - data["q"][0])))
        warnings.append(f"the initiation move ({math.degrees(cfg.init_move):+g} deg, --init-move) was slowed by the "
                        f"reference's speed and acceleration limits (--qd-max, --qdd-max) and moved "
                        f"{math.degrees(moved):.3g} deg before control")
    elif cut.size:  # the window stopped the initiation move short (a start near its edge)
        edge, moved = data["q_cmd"][cut[0]], data["q_cmd"][cut[0]] - data["q"][0]
        warnings.append(f"the initiation move ({math.degrees(cfg.init_move):+g} deg, --init-move) was cut by the "
                        f"position window at {math.degrees(edge):g} deg after {math.degrees(moved):+.3g} deg: the "
                        "Maxwell-slip elements are set by it only if that passes their break-away (eq. 12); start "
                        "farther from the window's edge, or move the other way "
                        f"(--init-move {-math.degrees(cfg.init_move):+g})")
    init = data["phase"] < PHASE_ADMITTANCE
    if init.any():  # the loop's own move and rest: nobody touches the axis, Γr is the model's error there
        out["init_residual_max"] = float(np.max(np.abs(gr[init])))
        along = push_along(data["phase"], data["dynamic"], gr, cfg.init_move)
        if along is not None:
            out["init_push_along"] = along
        if out["init_residual_max"] >= cfg.threshold:
            warnings.append(f"during the initiation move and rest Γr reached {out['init_residual_max']:.3g} N·m, beyond "
                            f"the threshold {cfg.threshold:g} N·m, with nobody touching the axis (not taken for a push): "
                            f"the parameter file's model is off by that much there; {_init_advice(cfg)}")
    out["warnings"] = warnings
    out["D_range"] = [float(np.min(data["D"][ph])), float(np.max(data["D"][ph]))]
    return out


def push_along(phase: Any, dynamic: Any, gamma_r: Any, init_move: float) -> float | None:
    """Γr's mean (N·m) along the initiation move over the cycles it was read as moving (None: fewer than
    :data:`MIN_ALONG`), from a run's per-cycle ``phase``, ``dynamic`` and ``gamma_r``."""
    rows = (np.asarray(phase) == PHASE_INIT) & np.asarray(dynamic, bool)
    if np.count_nonzero(rows) < MIN_ALONG:
        return None
    return float(np.mean(np.asarray(gamma_r, float)[rows])) * math.copysign(1.0, init_move)


def _unguidable(init_max: float, init_cap: float, log: dict[str, list], cfg: LoopConfig) -> str | None:
    """Why the model's error on the loop's own initiation move and rest (nobody touching: ``init_max`` its
    largest size; the rows so far in ``log``: Γr along the move, :func:`push_along`, and over the rest's last
    0.2 s) says that, guided, the axis would move by itself; None when it does not."""
    if init_max > init_cap:  # beyond what the threshold at rest can ever rise to: a file in N·mm, a gravity sign
        return (f"the model's error during the initiation move and rest reached {init_max:.3g} N·m, beyond "
                f"{init_cap:.3g} N·m ({init_cap / cfg.threshold:g} x the threshold, the most the threshold at rest can "
                "rise to): guided with this parameter file the axis would move by itself")
    pushes_on = push_along(log["phase"], log["dynamic"], log["gamma_r"], cfg.init_move) or 0.0
    if pushes_on >= RUNAWAY_SHARE * cfg.threshold:
        # a file whose friction exceeds the axis's (new-user trial 21: Fc, Fs and Fv 1.5 x the plant's, 8.8 N·m
        # here, ran the axis 71 degrees after a release): guided, that error alone holds a detection while the
        # axis moves, and it runs on by itself after the person lets go
        return (f"the model's error pushed along the initiation move by {pushes_on:.3g} N·m on average, "
                f"{pushes_on / cfg.threshold:.2f} x the threshold {cfg.threshold:g} N·m (at most {RUNAWAY_SHARE:g} x; a "
                "model whose friction exceeds the axis's, e.g. fitted on a colder drive): guided, that error alone "
                "would keep the axis moving after a release")
    rest = np.asarray(log["gamma_r"], float)[np.asarray(log["phase"]) == PHASE_REST]
    rest_end = rest[-max(1, round(0.2 / cfg.cycle)):]
    standing = float(np.mean(rest_end)) if rest_end.size else 0.0
    if cfg.no_rest_model and abs(standing) >= cfg.threshold:
        # no friction model at rest (a robot file run with --no-rest-model): an offset of 4 N·m against the move,
        # threshold 3, ran the axis 0.52 rad with nobody there
        return (f"Γr stood at {standing:.3g} N·m at the end of the rest, beyond the threshold {cfg.threshold:g} N·m: "
                "control would start by moving the axis")
    return None


def _init_advice(cfg: LoopConfig) -> str:
    """What to do about a model error on the loop's own initiation move and rest: a robot model has no
    friction model at rest (--no-rest-model), so there its static friction is the error, and a refit
    does not remove it (new-user trial 14: 7.3 N·m on a KR 6 file fitted on that very robot)."""
    if cfg.no_rest_model:
        return ("a robot parameter file has no friction model at rest, and the axis's static friction reads as that "
                "much: raise --threshold above it, or guide with a one-axis file with Maxwell-slip elements "
                "(kukaid fit ... --presliding LOG)")
    return "check the file's units and signs (kukaid show), refit it on a recent log of this axis, or raise --threshold"


def config_dict(cfg: LoopConfig) -> dict[str, Any]:
    """The configuration as a JSON-able dict."""
    d = asdict(cfg)
    d["limits"] = {k: (v if math.isfinite(v) else None) for k, v in d["limits"].items()}
    return d
