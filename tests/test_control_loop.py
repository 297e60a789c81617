"""The closed admittance loop on the virtual KR C4 (truth away from the paper's values): what a
person pushing the axis gets, what a standing axis does, and every way a run stops."""
from __future__ import annotations

import math

import numpy as np
import pytest

from kukaid.robot import SimRobot
from kukaid.control.loop import PHASE_ADMITTANCE, LoopConfig, run_admittance
from kukaid.control.rbf import RBFConfig
from kukaid.control.safety import SafetyLimits
from kukaid.errors import ControllerError
from kukaid.params import model_from_params
from kukaid.sim import SimConfig, VirtualKRC4
from kukaid.sim.operator import PushOperator

# paper: Fc 15.70, Fs 17.56, vs 0.04, delta 2, Fv 14.15, Izz 2.28, Mx 18.48
TRUTH = dict(Fc=12.8, Fs=15.2, vs=0.05, delta=1.5, Fv=11.0, Izz=1.9, Mx=22.5, ms_W=(6.0, 1.0, 5.0))
Q0 = math.radians(30.0)


def _run(operator=None, seed=3, **cfg_kw):
    cfg = SimConfig().replace(**TRUTH)
    model = model_from_params(cfg.truth_params())
    be = SimRobot(VirtualKRC4(cfg, seed=seed), Q0, operator)
    return run_admittance(be, model, LoopConfig(**cfg_kw))


def _push(amplitude, start=2.0, duration=3.5):
    # the admittance starts after the 0.6 s initiation move and 0.6 s rest
    return PushOperator(amplitude=amplitude, t_start=start, duration=duration, ramp=0.4)


@pytest.mark.parametrize("amplitude", [12.0, -15.0])
def test_steady_push_moves_the_axis_at_push_over_damping(amplitude):
    """Sensorless: a steady push of tau N·m gives the reference speed tau / D (eq. 15 in steady
    state: 10 N·m at D = 50 is 0.2 rad/s), in the push's direction, and the estimated external
    torque follows the true one."""
    op = _push(amplitude)
    run = _run(op, D=50.0, I=20.0, duration=7.0)
    d = run.data
    assert run.status == "completed"
    plateau = (d["time"] > op.t_start + 1.6) & (d["time"] < op.t_end - 0.4)  # after ~3 I/D
    speed = np.mean(d["sigma_dot"][plateau])
    assert speed == pytest.approx(amplitude / 50.0, rel=0.10), speed
    err = d["gamma_r"][plateau] - d["tau_ext_true"][plateau]
    assert np.sqrt(np.mean(err ** 2)) < 0.1 * abs(amplitude)
    assert run.metrics["detection_delay"] < 0.15
    assert np.sign(run.metrics["displacement"]) == np.sign(amplitude)
    assert run.metrics["settled"] and run.metrics["false_detections"] == 0


def test_standing_axis_with_vibration_detects_nothing_and_stays():
    run = _run(None, duration=5.0)
    ph = run.data["phase"] == PHASE_ADMITTANCE
    assert not run.data["detected"][ph].any()
    assert abs(math.degrees(run.metrics["displacement"])) < 0.01
    assert np.all(run.data["sigma_dot"][ph] == 0.0)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_a_controller_whose_samples_jitter_starts(seed):
    """A sim config's timing jitter (up to 5 ms, allowed) delays the first sample past one interval on
    about half the seeds: the run stopped at once with "no measurement from the backend at start"."""
    cfg = SimConfig().replace(**TRUTH, jitter=0.005)
    be = SimRobot(VirtualKRC4(cfg, seed=seed), Q0)
    run = run_admittance(be, model_from_params(cfg.truth_params()), LoopConfig(duration=1.5))
    assert run.status == "completed"


def test_adaptive_damping_gives_way_to_a_steady_push_within_its_bounds():
    rbf = RBFConfig(D0=50.0, D_min=20.0, D_max=90.0)
    op = _push(14.0)
    const = _run(op, duration=8.0)
    adapt = _run(op, duration=8.0, damping="adaptive", rbf=rbf)
    D = adapt.data["D"][adapt.data["phase"] == PHASE_ADMITTANCE]
    assert D.min() >= 20.0 - 1e-9 and D.max() <= 90.0 + 1e-9
    push = (adapt.data["time"] > op.t_start + 0.5) & (adapt.data["time"] < op.t_end)
    assert np.mean(adapt.data["D"][push]) < 50.0  # the robot gives way to a steady push ...
    assert adapt.metrics["displacement"] > const.metrics["displacement"]  # ... and goes further
    assert adapt.metrics["settled"]
    # trial 20: a push with no arm behind it never rebounds, so no grip is estimated: not a stiffness of 0
    # (the run's PDF showed "0" for it and "—" for the constant run)
    assert math.isnan(adapt.metrics["grip_stiffness"]) and "grip_stiffness" not in const.metrics


def test_position_window_is_never_left():
    hi = Q0 + math.radians(5.0)
    run = _run(_push(18.0), duration=6.0, limits=SafetyLimits(q_min=Q0 - 0.5, q_max=hi))
    assert run.status == "completed" and run.metrics["clipped_cycles"] > 0
    assert np.max(run.data["q_cmd"]) <= hi + 1e-12
    assert np.max(run.data["q"]) <= hi + math.radians(0.05)  # the servo's overshoot at the edge
    v = np.diff(run.data["q_cmd"]) / 0.012
    assert np.max(np.abs(v)) <= 0.5 + 1e-9  # the default speed limit of SafetyLimits


def test_the_reference_peak_speed_is_the_speed_sent_within_the_limit():
    """New-user trial 14: with a push the admittance wanted faster than --qd-max, the summary's
    "reference peak speed" read 0.5097 rad/s against the 0.5027 limit: the admittance's own σ̇ at the
    end of a cycle, before the next one clipped it; the reference sent never went beyond the limit."""
    qd_max = math.radians(10.0)
    run = _run(_push(25.0), duration=5.0, D=20.0, limits=SafetyLimits(qd_max=qd_max))
    assert run.metrics["clipped_cycles"] > 0
    assert np.max(np.abs(run.data["sigma_dot"])) > qd_max + 1e-3  # what the admittance wanted
    assert qd_max * 0.95 < run.metrics["peak_speed"] <= qd_max + 1e-9


def test_an_initiation_move_cut_by_the_window_is_said():
    """New-user trial 11: a start 0.5 degree from the window's edge cut the 1-degree initiation move in half,
    and the run said only "clipped_cycles 75"; now a warning says how far it went."""
    run = _run(duration=0.5, limits=SafetyLimits(q_min=Q0 - 0.5, q_max=Q0 + math.radians(0.5)))
    said = [w for w in run.metrics["warnings"] if w.startswith("the initiation move (+1 deg, --init-move) was cut")]
    assert len(said) == 1 and "at 30.5 deg after +0.5 deg" in said[0], run.metrics["warnings"]
    run = _run(duration=0.5, init_move=-math.radians(1.0),  # the other way: not cut, not said
               limits=SafetyLimits(q_min=Q0 - 0.5, q_max=Q0 + math.radians(0.5)))
    assert not any("initiation move" in w for w in run.metrics["warnings"]), run.metrics["warnings"]


def test_a_detection_on_before_the_hand_touched_gives_no_detection_delay():
    """New-user trial 11: an LWR4+ robot file with --no-rest-model (A1) said "detection_delay -0.996 s": the
    detection counted began with nobody touching the axis (a false detection, 62 cycles of it), up to 1 s
    before the push.  Now such a detection gives no delay; one that begins once the hand is on, before its
    torque reaches the threshold, is still the (negative) delay."""
    from kukaid.control.loop import run_metrics

    n = 400
    t = np.arange(n) * 0.012
    te = np.clip((t - 3.0) * 10.0, 0.0, 20.0)  # the hand from 3 s, 5 N·m (the threshold) at 3.5 s
    det = t >= 2.9  # on 0.1 s before the hand touched
    data = dict(time=t, phase=np.full(n, PHASE_ADMITTANCE), gamma_r=np.zeros(n), tau_ext_true=te, detected=det,
                dynamic=np.ones(n, bool), q=np.zeros(n), sigma_dot=np.zeros(n), D=np.full(n, 50.0))
    m = run_metrics(data, LoopConfig())
    assert math.isnan(m["detection_delay"]) and m["false_detections"] > 0
    m = run_metrics({**data, "detected": t >= 3.3}, LoopConfig())  # on with the hand (2 N·m), before 5 N·m
    assert m["detection_delay"] == pytest.approx(3.3 - 3.5, abs=0.013)


def test_torque_limit_stops_motion():
    run = _run(_push(30.0), duration=6.0, limits=SafetyLimits(tau_max=25.0))
    assert run.status.startswith("stopped: external torque Γr") and "25 N·m" in run.status
    assert abs(run.data["gamma_r"][-1]) > 25.0
    assert run.data["phase"][-1] == 3


def test_torque_limit_bounds_the_push_not_the_gravity_load():
    """New-user trial 14: on A2 of a KR 6 the gravity load is about 45 N·m, and the default 100 N·m stop on the
    measured torque tripped under a 55 N·m push from above (it would have let one from below reach 145 N·m).
    The stop bounds the external torque Γr: a gravity load beyond --tau-max with a push below it runs on."""
    cfg = SimConfig().replace(**{**TRUTH, "Mx": 60.0})  # 52 N·m of gravity at 30 degrees
    model = model_from_params(cfg.truth_params())
    run = run_admittance(SimRobot(VirtualKRC4(cfg, seed=3), Q0, _push(-12.0)), model,
                         LoopConfig(duration=6.0, limits=SafetyLimits(tau_max=40.0)))
    assert run.status == "completed", run.status
    assert np.max(np.abs(run.data["tau"])) > 60.0  # the measured torque: the gravity load and the push
    assert np.max(np.abs(run.data["gamma_r"])) < 20.0


class _Failing(SimRobot):
    def __init__(self, *a, fail_at: float, exc: BaseException, **kw):
        super().__init__(*a, **kw)
        self.fail_at, self.exc, self.holds = fail_at, exc, 0

    def cycle(self, q_cmd, dt):
        if self.sim.t >= self.fail_at:
            raise self.exc
        return super().cycle(q_cmd, dt)

    def hold(self):
        self.holds += 1


@pytest.mark.parametrize("exc, reason", [(ControllerError("kvp: connection lost"), "stopped: kvp: connection lost"),
                                         (KeyboardInterrupt(), "stopped: interrupted")])
def test_a_failing_controller_or_ctrl_c_holds_and_keeps_the_record(exc, reason):
    cfg = SimConfig().replace(**TRUTH)
    be = _Failing(VirtualKRC4(cfg, seed=1), Q0, _push(12.0), fail_at=3.0, exc=exc)
    run = run_admittance(be, model_from_params(cfg.truth_params()), LoopConfig(duration=5.0))
    assert run.status == reason and be.holds >= 1
    assert run.data["time"][-1] == pytest.approx(3.0, abs=0.03)  # every cycle before the failure is kept
    assert "detection_delay" in run.metrics


def test_run_metrics_warn_when_the_estimate_misses_what_happened():
    """A true push the estimate did not see (Γr small, the hand at 80 N·m): not settled, and said."""
    from kukaid.control.loop import run_metrics

    n = 300
    t = np.arange(n) * 0.012
    te = np.where(np.arange(n) % 2 == 0, 80.0, -80.0)
    data = dict(time=t, phase=np.full(n, PHASE_ADMITTANCE), gamma_r=np.zeros(n), tau_ext_true=te,
                detected=np.zeros(n, bool), dynamic=np.ones(n, bool), q=np.zeros(n), sigma_dot=np.zeros(n),
                D=np.full(n, 50.0))
    m = run_metrics(data, LoopConfig())
    assert not m["settled"] and len(m["warnings"]) == 2
    assert "disagrees grossly" in m["warnings"][0]
    quiet = run_metrics({**data, "tau_ext_true": np.zeros(n)}, LoopConfig())
    assert quiet["settled"] and quiet["warnings"] == []


def test_a_detection_in_a_run_nobody_touched_names_no_push_and_no_release():
    """New-user trial 16: `run-admittance --params lwr.json --no-rest-model --axis 2 --operator none` warned
    "detected a push with nobody touching the axis: 33 cycles before the first push, 0 after the release":
    nobody pushed, so there was no first push and no release."""
    from kukaid.control.loop import run_metrics

    n = 300
    t = np.arange(n) * 0.012
    det = (t > 1.0) & (t < 1.396)  # 33 cycles
    data = dict(time=t, phase=np.full(n, PHASE_ADMITTANCE), gamma_r=np.zeros(n), tau_ext_true=np.zeros(n),
                detected=det, dynamic=np.ones(n, bool), q=np.zeros(n), sigma_dot=np.zeros(n), D=np.full(n, 50.0))
    m = run_metrics(data, LoopConfig())
    said = [w for w in m["warnings"] if w.startswith("detected a push with nobody touching")]
    assert said == [f"detected a push with nobody touching the axis: {int(det.sum())} cycles, and nobody touched it "
                    "in this run (the axis moved by itself)"], m["warnings"]


def test_no_setting_lets_the_loop_coast_on_or_act_on_old_measurements():
    """Trial 18: D 1e-6 (I 20) coasted on after a release and ran the axis 11 degrees back with nobody
    there; a max_age of 30 s let a 1.2 s link move a robot on measurements that old. The library refuses
    both, as the CLI does: the lightest damping (D, or the adaptive law's D_min) must give a coast's time
    constant I / D of at most 2 s, and max_age is at most 1 s."""
    from kukaid.errors import KukaidError, LimitError

    with pytest.raises(KukaidError, match=r"damping D = 1e-06 .* below I / 2 s = 10"):
        LoopConfig(D=1e-6)
    with pytest.raises(KukaidError, match=r"D_min = 5 .* time constant I / D = 4 s"):
        LoopConfig(damping="adaptive", rbf=RBFConfig(D0=50.0, D_min=5.0, D_max=100.0))
    LoopConfig(D=10.0)                     # I / D = 2 s: the longest allowed
    LoopConfig(damping="adaptive")         # the default floor, 0.3 x 50: 1.3 s
    with pytest.raises(LimitError, match=r"max_age = 30 s is above 1 s"):
        SafetyLimits(max_age=30.0)
    SafetyLimits(max_age=1.0)
