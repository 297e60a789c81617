"""The six-axis virtual KR C4: a whole robot from its URDF under the KR C4's per-axis position servo.

Physics (SI), one semi-implicit Euler step per servo cycle (``servo_rate``, 1 kHz)::

    (M(q) + diag(armature)) qdd + C(q, qd) qd + g(q) = tau_m + tau_ext - F(qd)

evaluated with Pinocchio's articulated-body algorithm on the *true* robot (:class:`RobotTruth`:
the URDF with seeded, physically consistent inertials, rotor inertia and friction).  One model is
built once; the plant, the servo's feedforward and the truth each own a data object.

* friction per joint: ``F = (Fc + (Fs - Fc) exp(-(qd/vs)²)) tanh(qd/eps) + Fv qd + offset``
  (Coulomb-viscous when ``Fs = Fc``), integrated implicitly (its velocity slope is added to the
  joint's inertia for the step), so the stiff Coulomb regularisation stays stable at 1 kHz; a
  truth with ``friction_coupling`` C has it on the motors' velocities ``(I + C) qd``, seen at the
  joints through ``(I + C)^T`` (a KUKA wrist's), its slope ``h (I + C)^T diag(F') (I + C)`` in the
  step's mass matrix;
* an elastic gear (the truth's ``gear_stiffness``, ``gear_damping``): the joint's motor a body of
  its own (its rotor inertia, friction and the servo's torque) on a spring to its link, in
  substeps of the servo cycle with the link held; the encoder (the servo's feedback, the logged
  position) on the motor. The velocity loop then acts on the motor alone above the spring's
  resonance: a servo rate below ``Kv J_i / J_motor`` is refused (a KR 6's A2 needs about 4 kHz);
* servo per axis, as the single-axis simulator's (:mod:`kukaid.sim.krc4`): ``v_ref = qd_ff +
  Kp (q_ref - q)``, ``tau_m = J_i qdd_ff + g_nom(q_ref) + J_i Kv (v_ref - qd) + integral``,
  limited to the joint's torque limit; ``J_i`` is the diagonal of the *nominal* mass matrix at the
  middle of the joint ranges and ``g_nom`` the nominal gravity (machine data, not the truth).  The
  commanded positions arrive at the IPO rate and are interpolated by a C2 cubic spline;
* measurement as the drives report it, every ``sample_time``: position ($AXIS_ACT_MEAS) rounded
  to ``quant_deg``, torque ($TORQUE_AXIS_ACT[i]) = motor torque at the axis + Gaussian noise of
  ``noise_rel`` times the joint's torque limit.

An external-torque function (a person's hand, :meth:`VirtualRobotKRC4.set_external_torque`) is
evaluated every sample and held; the inertia its hand moves with a joint (``fn.inertia()``) is
added to that joint's inertia, so the hand's reaction ``-I qdd`` is the present acceleration's.

The measured torque is therefore ``M qdd + C qd + g + F - tau_ext`` + noise: the residual
``Γr = Γp - Γm`` of a perfect robot model equals the external torque.  A one-axis trajectory
(:class:`kukaid.excite.Trajectory`) moves its axis while the others stay locked where they are.
"""
from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any, Callable

import numpy as np

from kukaid.errors import KukaidError
from kukaid.errors import SimConfigError
from kukaid.sim.krc4 import _Spline, trajectory_attrs
from kukaid.models.urdf import gear_ratios, load_model
from kukaid.sim.robot_truth import NOMINAL_ARMATURE, RobotTruth, draw_truth

SOURCE = "virtual-krc4-robot"

# field -> (kind, low, high, doc)
ROBOT_FIELDS: dict[str, tuple[str, float, float, str]] = {
    "truth_seed": ("int", 0, 2**32 - 1, "seed of the robot's true inertials and friction"),
    "perturb": ("float", 0.0, 1.0, "relative distance of the true inertials from the URDF's"),
    "friction_scale": ("float", 0.0, 100.0, "scale of the default friction (Coulomb 4 %, viscous 3 % of the torque limit)"),
    "stribeck": ("bool", 0, 1, "true friction has a Stribeck peak (else Coulomb-viscous)"),
    "armature": ("bool", 0, 1, "true robot has reflected rotor inertia"),
    "servo_rate": ("float", 250.0, 20000.0, "servo and physics rate, Hz"),
    "ipo_period": ("float", 1e-3, 1.0, "interpolation (IPO) cycle of the commanded trajectory, s"),
    "sample_time": ("float", 1e-3, 1.0, "sample interval of the log, s"),
    "Kp": ("float", 0.0, 1e3, "position loop gain, 1/s"),
    "Kv": ("float", 1.0, 1e4, "velocity loop gain, rad/s"),
    "Ki": ("float", 0.0, 1e3, "velocity loop integral gain, 1/s"),
    "noise_rel": ("float", 0.0, 0.1, "torque noise sigma as a fraction of the joint's torque limit"),
    "quant_deg": ("float", 0.0, 1.0, "position resolution, degrees (0: none)"),
    "friction_eps": ("float", 1e-6, 1.0, "velocity of the Coulomb regularisation tanh(qd/eps), rad/s"),
}


@dataclass(frozen=True)
class RobotSimConfig:
    """Settings of the six-axis virtual KR C4 (see :data:`ROBOT_FIELDS` for units and ranges).

    ``robot`` is a bundled robot name (``kr6-r700-sixx``) or a URDF path.  The truth is drawn
    from ``truth_seed`` (so captures with different noise seeds record the same robot).
    """

    robot: str = "kr6-r700-sixx"
    truth_seed: int = 1
    perturb: float = 0.15
    friction_scale: float = 1.0
    stribeck: bool = False
    armature: bool = True
    servo_rate: float = 1000.0
    ipo_period: float = 0.012
    sample_time: float = 0.004
    Kp: float = 40.0
    Kv: float = 150.0
    Ki: float = 30.0
    noise_rel: float = 0.002
    quant_deg: float = 1e-4
    friction_eps: float = 1e-3
    torque_side: str = "joint"
    coupling: Any = None

    def __post_init__(self) -> None:
        for name, (kind, lo, hi, doc) in ROBOT_FIELDS.items():
            v = getattr(self, name)
            bad = isinstance(v, bool) and kind != "bool" or not isinstance(v, (int, float))
            if bad or not (math.isfinite(v) and lo <= v <= hi) or (kind == "int" and v != int(v)):
                raise SimConfigError(f"robot sim config: field '{name}' ({doc}) must be a number in [{lo:g}, {hi:g}], "
                                     f"got {json.dumps(v, default=str)}")
            object.__setattr__(self, name, bool(v) if kind == "bool" else int(v) if kind == "int" else float(v))
        if not isinstance(self.robot, str) or not self.robot:
            raise SimConfigError("robot sim config: field 'robot' must be a robot name or a URDF path")
        if self.torque_side not in ("joint", "motor"):
            raise SimConfigError(f"robot sim config: field 'torque_side' must be \"joint\" or \"motor\", "
                                 f"got {json.dumps(self.torque_side, default=str)}")
        if self.coupling is not None:
            try:
                C = np.asarray(self.coupling, dtype=float)
                ok = C.ndim == 2 and C.shape[0] == C.shape[1] and np.all(np.isfinite(C))
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise SimConfigError("robot sim config: field 'coupling' (the drives' coupling: motor angles "
                                     "diag(ratio) (I + coupling) q) must be a square matrix of numbers, one row per axis")
            object.__setattr__(self, "coupling", C.tolist())
        if self.sample_time * self.servo_rate < 1 - 1e-9:
            raise SimConfigError(f"robot sim config: field 'sample_time' = {self.sample_time} is shorter than a servo cycle")

    def coupling_matrix(self, n: int, where: str = "robot sim config") -> np.ndarray:
        """The drives' coupling as an n x n matrix (zeros when none), refused naming ``where`` when it
        is of another size than the robot's ``n`` joints."""
        C = np.zeros((n, n)) if self.coupling is None else np.asarray(self.coupling, dtype=float)
        if C.shape != (n, n):
            raise SimConfigError(f"{where}: field 'coupling' must be {n} x {n} for this robot, got {C.shape}")
        return C

    def replace(self, **changes: Any) -> "RobotSimConfig":
        names = set(ROBOT_FIELDS) | {"robot", "torque_side", "coupling"}
        for k in changes:
            if k not in names:
                raise SimConfigError(f"robot sim config: unknown field '{k}' (known: {', '.join(sorted(names))})")
        return replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: Any, where: str = "robot sim config") -> "RobotSimConfig":
        if not isinstance(d, dict):
            raise SimConfigError(f"{where}: top level must be a JSON object")
        try:
            return cls().replace(**{k: v for k, v in d.items() if k not in ("comment", "_comment")})
        except SimConfigError as e:
            raise SimConfigError(str(e).replace("robot sim config", where, 1)) from None

    @classmethod
    def load(cls, path: str | Path) -> "RobotSimConfig":
        from kukaid.jsonfile import read_json

        return cls.from_dict(read_json(path, SimConfigError, "robot simulator configuration (JSON)", schemas=()),
                             str(path))


# rows of the parameter array of :func:`servo_step`
_KP, _GKV, _GKI, _JC, _TMAX, _FC, _DF, _VS, _FV, _OFF, _ARM = range(11)
_NP = 11


def servo_step(qr, vr, ar, gff, q, v, I, te, P, h, ieps, tau, u, arm_eff):
    """One servo cycle of every axis (scalar code: plain Python or compiled by numba).

    Updates the integrators ``I`` in place and writes the motor torques ``tau``, the net joint
    torque ``u = tau + te - F(v)`` the dynamics sees, and the inertia added per joint for the
    step, ``arm_eff = armature + h dF/dv`` (implicit friction).
    """
    for j in range(q.shape[0]):
        ev = vr[j] + P[_KP, j] * (qr[j] - q[j]) - v[j]
        tmax = P[_TMAX, j]
        Ij = min(max(I[j] + P[_GKI, j] * ev, -tmax), tmax)
        I[j] = Ij
        tj = min(max(P[_JC, j] * ar[j] + gff[j] + P[_GKV, j] * ev + Ij, -tmax), tmax)
        tau[j] = tj
        vj = v[j]
        s = math.tanh(vj * ieps)
        g = P[_FC, j]
        if P[_DF, j] != 0.0:
            x = vj / P[_VS, j]
            g += P[_DF, j] * math.exp(-x * x)
        u[j] = tj + te[j] - (g * s + P[_FV, j] * vj + P[_OFF, j])
        arm_eff[j] = P[_ARM, j] + h * (g * (1.0 - s * s) * ieps + P[_FV, j])


def _motor_friction(w, fc, dfs, vs, fv, ieps):
    """The truth's friction law at the velocities ``w`` (the kernel's, vectorised) and the slope its
    implicit step uses (the Stribeck term's own derivative left out, as the kernel does)."""
    s = np.tanh(w * ieps)
    g = fc + dfs * np.exp(-(w / vs) ** 2)
    return g * s + fv * w, g * (1.0 - s * s) * ieps + fv


def _coupled_friction(mix, v, fc, dfs, vs, fv, ieps, h, u, Mq):
    """The motors' friction on their velocities ``mix @ v`` (rad/s, joint units) taken from the net
    joint torque ``u`` through ``mix^T``, its velocity slope ``h mix^T diag(f') mix`` added to the
    step's mass matrix ``Mq`` (implicit, as the kernel's per-joint friction); returns both."""
    f, slope = _motor_friction(mix @ v, fc, dfs, vs, fv, ieps)
    return u - mix.T @ f, Mq + h * (mix.T * slope) @ mix


def integrate(q, v, a, h):
    """Semi-implicit Euler step in place: ``v += h a``, then ``q += h v``."""
    for j in range(q.shape[0]):
        v[j] += h * a[j]
        q[j] += h * v[j]


_kernels = None


def _get_kernels():
    """(:func:`servo_step`, :func:`integrate`) compiled by numba (cached on disk) when available,
    else plain Python (same numbers, slower); ``KUKAID_NO_NUMBA=1`` forces plain Python."""
    global _kernels
    if _kernels is None:
        import os

        try:
            if os.environ.get("KUKAID_NO_NUMBA"):
                raise ImportError("disabled by KUKAID_NO_NUMBA")
            from numba import njit
        except ImportError:
            _kernels = (servo_step, integrate)
        else:
            _kernels = (njit(cache=True, nogil=True)(servo_step), njit(cache=True, nogil=True)(integrate))
    return _kernels


class VirtualRobotKRC4:
    """A simulated KR C4 moving all axes of a robot; see the module docstring for the physics.

    Parameters
    ----------
    cfg : :class:`RobotSimConfig` (default: the bundled KR 6 R700 sixx).
    seed : seed of the measurement noise.
    truth : the true robot (default: drawn from ``cfg.truth_seed``).

    Same interface as :class:`kukaid.sim.VirtualKRC4` (``reset``, ``follow``, ``command``,
    ``set_external_torque``, ``advance``, ``read``, ``run``, ``log_attrs``) with vectors over
    :attr:`axes` instead of numbers.
    """

    def __init__(self, cfg: RobotSimConfig | None = None, seed: int = 0, truth: RobotTruth | None = None) -> None:
        import pinocchio as pin

        self._pin = pin
        self.cfg = cfg if cfg is not None else RobotSimConfig()
        c = self.cfg
        self.seed = int(seed)
        self.model_nominal = load_model(c.robot)
        n = self.model_nominal.nv
        self.truth = truth if truth is not None else draw_truth(c.robot, self.model_nominal, seed=c.truth_seed,
                                                               size=c.perturb, friction_scale=c.friction_scale,
                                                               stribeck=c.stribeck)
        if self.truth.n != n:
            raise KukaidError(f"robot sim: the truth has {self.truth.n} joints, the robot {n}")
        if not c.armature:
            self.truth = replace(self.truth, armature=np.zeros(n))
        # the drives: motor angles G q, G = diag(gear ratio) (I + coupling); the rotors turn with the
        # motors, so their inertia on the joint side is G^T diag(I_rotor) G (the truth's armature
        # is its diagonal without coupling)
        ratio = gear_ratios(c.robot, tuple(self.model_nominal.names[1:]))
        C = c.coupling_matrix(n)
        self.ratio, self.coupling = ratio, C
        self.G = np.diag(ratio) @ (np.eye(n) + C)
        self.rotor_inertia = self.truth.armature / ratio ** 2  # motor side, kg·m²
        self._coupled = bool(np.any(C != 0))
        self._M_rotor = self.G.T @ np.diag(self.rotor_inertia) @ self.G
        # the truth's friction on coupled motor velocities (a KUKA wrist's): computed beside the
        # kernel, its velocity slope (I + C)^T diag(f') (I + C) joining the mass matrix for the step
        self._fmix = self.truth.friction_mix()
        if self._fmix is not None and self._fmix.shape != (n, n):
            raise KukaidError(f"robot sim: the truth's friction coupling must be {n} x {n}")
        # elastic gears: the motor a body of its own (its rotor inertia, friction), a spring to its link
        self._el = self.truth.elastic()
        if self._el.size and (self._coupled or self._fmix is not None):
            raise KukaidError("robot sim: elastic gears with coupled drives or coupled friction are not simulated")
        self._to_motor = np.linalg.inv(self.G)  # row vectors: tau_motor = tau_joint G^-1 (= G^-T tau_joint)
        self.model = self.truth.apply(self.model_nominal)
        self._data = self.model.createData()
        self._data_ff = self.model_nominal.createData()
        self.axes = tuple(range(1, n + 1))
        self.dt = 1.0 / c.servo_rate
        self._per = max(int(round(c.sample_time * c.servo_rate)), 1)
        lo, hi = np.asarray(self.model_nominal.lowerPositionLimit), np.asarray(self.model_nominal.upperPositionLimit)
        mid = np.where(np.isfinite(lo) & np.isfinite(hi), 0.5 * (lo + hi), 0.0)
        Mn = pin.crba(self.model_nominal, self._data_ff, mid)
        eff = np.asarray(self.model_nominal.effortLimit, dtype=float)
        # the controller's inertia per axis: nominal link inertia at mid-range plus the nominal rotor
        # inertia (machine data; the truth's is drawn around it)
        self.ctrl_J = np.diag(Mn).copy() + (NOMINAL_ARMATURE * self._effort(eff) if c.armature else 0.0)
        self.tau_max = np.where(np.isfinite(eff) & (eff > 0), eff, 1e4)
        self.noise_sigma = c.noise_rel * self._effort(eff)
        self._tau_ext: np.ndarray | Callable = np.zeros(n)
        if self._el.size:
            # the velocity loop, tuned for the joint's whole inertia, acts on the motor alone above the
            # spring's resonance: per servo cycle its gain must stay under 1 (at 1 kHz a KR 6's A2
            # with a 5e4 N·m/rad gear chatters at its torque limit)
            J_m = np.maximum(self.truth.armature[self._el], 1e-9)
            gain = c.Kv * self.ctrl_J[self._el] / J_m
            if np.any(gain * self.dt >= 1.0):
                raise SimConfigError(f"robot sim config: an elastic gear's motor alone under the velocity loop needs "
                                     f"servo_rate above {float(np.max(gain)):.0f} Hz, got {c.servo_rate:g}")
        self.reset(np.zeros(n))

    @staticmethod
    def _effort(eff: np.ndarray) -> np.ndarray:
        """The URDF's torque limits, 100 N·m where it gives none (the scale of defaults)."""
        return np.where(np.isfinite(eff) & (eff > 0), eff, 100.0)

    # -- state ---------------------------------------------------------------------------------
    @property
    def n(self) -> int:
        return len(self.axes)

    @property
    def t(self) -> float:
        return self._tick * self.dt

    @property
    def q(self) -> np.ndarray:
        return self._q.copy()

    @property
    def qd(self) -> np.ndarray:
        return self._v.copy()

    def _vec(self, x: Any, what: str) -> np.ndarray:
        v = np.asarray(x, dtype=float).ravel()
        if v.size == 1 and self.n > 1:
            v = np.full(self.n, float(v[0]))
        if v.size != self.n or not np.all(np.isfinite(v)):
            raise KukaidError(f"robot sim: {what} must be {self.n} finite numbers, got {np.asarray(x).tolist()}")
        return v

    def reset(self, q0: Any = 0.0) -> None:
        """Standstill at ``q0`` (rad, one per axis), time 0, noise restarted from the seed; the servo
        integrator starts at the torque that holds the robot there."""
        pin = self._pin
        q0 = self._vec(q0, "reset position")
        self._q, self._v = q0.copy(), np.zeros(self.n)
        hold = pin.computeGeneralizedGravity(self.model, self._data, q0) + self.truth.offset
        # an elastic joint's link (``q0`` is its motor, where the encoder is) hangs back by its spring's
        # deflection: the link's gravity torque over the stiffness (a few fixed-point steps)
        self._ql, self._vl = q0.copy(), np.zeros(self.n)
        if self._el.size:
            k = np.asarray(self.truth.gear_stiffness, float)[self._el]
            for _ in range(5):
                g = pin.computeGeneralizedGravity(self.model, self._data, self._ql)
                self._ql[self._el] = q0[self._el] - g[self._el] / k
        g_ff = pin.computeGeneralizedGravity(self.model_nominal, self._data_ff, q0)
        self._I = np.clip(hold - g_ff, -self.tau_max, self.tau_max)
        self._tau = hold.copy()
        self._tick = 0
        self._t_req = 0.0
        self._rng = np.random.default_rng(np.random.SeedSequence([self.seed, 0x0B0B]))
        self._rng_read = np.random.default_rng(np.random.SeedSequence([self.seed, 0x0BAD]))
        self._ref_hold = q0.copy()
        self._ref: Any = None
        self._last_cmd = q0.copy()
        self._t_last_cmd: float | None = None

    def _eval_ref(self, tt: np.ndarray):
        if self._ref is None:
            m = tt.size
            return np.tile(self._ref_hold, (m, 1)), np.zeros((m, self.n)), np.zeros((m, self.n))
        return self._ref.eval(tt)

    # -- inputs --------------------------------------------------------------------------------
    def follow(self, traj: Any) -> None:
        """Track ``traj.q`` ((N, A) rad over ``traj.axes``, or (N,) of one ``traj.axis`` with the other
        axes locked at their present command) at ``traj.t`` (s), from now on."""
        t = np.asarray(traj.t, dtype=float).ravel()
        q = np.asarray(traj.q, dtype=float)
        now_q = self._eval_ref(np.array([self.t]))[0][0]
        full = np.tile(now_q, (t.size, 1))
        if q.ndim == 1:
            axes = (int(getattr(traj, "axis", 0)),)
            q = q[:, None]
        else:
            axes = tuple(int(a) for a in getattr(traj, "axes", self.axes))
        if q.shape != (t.size, len(axes)) or t.size < 2:
            raise KukaidError(f"trajectory: q must have one row per time and one column per axis (got {q.shape})")
        for j, a in enumerate(axes):
            if a not in self.axes:
                raise KukaidError(f"trajectory: axis A{a} is not an axis of the robot (A1..A{self.n})")
            full[:, a - 1] = q[:, j]
        if not np.all(np.isfinite(full)) or np.any(np.diff(t) <= 0):
            raise KukaidError("trajectory: t must be strictly increasing and q finite")
        self._ref = _Spline(t - t[0] + self.t, full)
        self._last_cmd = full[-1].copy()
        self._t_last_cmd = None

    def command(self, q_cmd: Any) -> None:
        """New position setpoints (rad, one per axis), streamed; ramped linearly over the interval
        since the previous setpoint (one to four IPO cycles), as :meth:`VirtualKRC4.command`."""
        q_cmd = self._vec(q_cmd, "commanded position")
        now, ipo, last = self.t, self.cfg.ipo_period, self._t_last_cmd
        span = ipo if last is None else min(max(now - last, ipo), 4 * ipo)
        q_now = self._eval_ref(np.array([now]))[0][0]
        self._ref = _Spline(np.array([now, now + span]), np.vstack([q_now, q_cmd]), linear=True)
        self._last_cmd = q_cmd
        self._t_last_cmd = now

    def set_external_torque(self, tau: Any) -> None:
        """External joint torques (N·m, one per axis), or ``fn(t, q, qd) -> torques`` evaluated once
        per sample period and held in between.

        A function with ``fn.every_cycle = True`` is evaluated every servo cycle instead (a torque
        of the robot's own state, as a cogging torque or a gas spring is, acts continuously: held
        over a 4 ms sample, a ripple of order 16 rad/rad at 1.5 rad/s lags its position by 0.1 rad
        of phase, 10 % of its size).

        A function may carry ``fn.inertia() -> kg·m² per axis``: inertia that moves rigidly with the
        joints (a person's hand), asked right after each evaluation of ``fn`` and added to the joints'
        inertia until the next (implicit: the hand's reaction ``-I qdd`` is the one of the present
        acceleration, not a differenced, held one, which goes unstable on a link lighter than the
        hand).  ``tau_ext_true`` is then the hand's whole torque on the link, ``fn - I qdd``.
        """
        self._tau_ext = tau if callable(tau) else self._vec(tau, "external torque")

    # -- running -------------------------------------------------------------------------------
    def advance(self, duration: float) -> dict[str, np.ndarray]:
        """Run for ``duration`` s; the samples taken meanwhile: ``time`` (N,) s, ``q``, ``tau``, ``q_cmd``,
        ``tau_ext_true`` (N, A) in rad and N·m."""
        duration = float(duration)
        if not math.isfinite(duration) or duration < 0:
            raise KukaidError(f"robot sim: duration must be a finite number >= 0 s, got {duration}")
        self._t_req += duration
        n = max(int(round(self._t_req / self.dt)) - self._tick, 0)
        blocks = []
        done = 0
        while done < n:
            # blocks end on sample instants so an external-torque function is held per sample
            to_sample = 1 if getattr(self._tau_ext, "every_cycle", False) else self._per - (self._tick % self._per)
            m = min(n - done, to_sample if callable(self._tau_ext) else max(n - done, 1))
            m = min(m, 50_000)
            blocks.append(self._run_ticks(m))
            done += m
        if not blocks:
            return {k: np.zeros((0, self.n)) if k != "time" else np.zeros(0)
                    for k in ("time", "q", "tau", "q_cmd", "tau_ext_true")}
        return {k: np.concatenate([b[k] for b in blocks]) for k in blocks[0]}

    def _elastic_step(self, u, te, q, v, ql, vl, P0, ieps, h, substeps):
        """An elastic joint's motor and spring over one servo cycle, the link held: the motor
        ``J_m dw = tau_m - F(w) - tau_s`` with ``tau_s = k (theta - q_l) + d (w - qd_l)`` (``q, v``
        its motor's angle and velocity, joint units, the encoder's), in ``substeps`` semi-implicit
        steps (friction implicit); returns the spring's mean torque per elastic joint, which the link
        feels. ``u`` (the kernel's, friction left out) holds the motor torque plus ``te``."""
        el, tr = self._el, self.truth
        k, d = np.asarray(tr.gear_stiffness, float)[el], np.asarray(tr.gear_damping if tr.gear_damping is not None
                                                                   else np.zeros(self.n), float)[el]
        hs = h / substeps
        um = u[el] - te[el]
        J = P0[_ARM, el]
        fc, dfs, vsm, fv = P0[_FC, el], P0[_DF, el], P0[_VS, el], P0[_FV, el]
        th, om = q[el].copy(), v[el].copy()
        ts_sum = np.zeros(el.size)
        for _ in range(substeps):
            ts = k * (th - ql[el]) + d * (om - vl[el])
            f, slope = _motor_friction(om, fc, dfs, vsm, fv, ieps)
            om = om + hs * (um - f - ts) / (J + hs * slope)
            th = th + hs * om
            ts_sum += ts
        q[el], v[el] = th, om
        return ts_sum / substeps

    def _run_ticks(self, m: int) -> dict[str, np.ndarray]:
        pin, c, tr = self._pin, self.cfg, self.truth
        t0 = self._tick
        tt = (t0 + np.arange(m + 1)) * self.dt
        qref, vff, aff = self._eval_ref(tt)
        te = self._tau_ext
        carried = None  # inertia moving with the joints (a hand), kg·m² per axis
        if callable(te):
            fn = te
            te = self._vec(fn(self.t, self.q, self.qd), "external torque function's value")
            if callable(getattr(fn, "inertia", None)):
                carried = self._vec(fn.inertia(), "external torque function's inertia")
                if np.any(carried < 0):
                    raise KukaidError(f"robot sim: the external torque function's inertia must be >= 0, "
                                      f"got {carried.tolist()}")
        h = self.dt
        P = self._servo_params()
        arm = tr.armature
        ieps = 1.0 / c.friction_eps
        model, data, mnom, dnom = self.model, self._data, self.model_nominal, self._data_ff
        q, v, I = self._q.copy(), self._v.copy(), self._I.copy()
        tau, u, arm_eff = self._tau.copy(), np.empty(self.n), np.empty(self.n)
        te = np.asarray(te, dtype=float)
        # sample ticks: the end of every ``per``-th servo cycle
        first = (-(t0 + 1)) % self._per
        rec = np.arange(first, m, self._per)
        out_q = np.empty((rec.size, self.n))
        out_tau = np.empty((rec.size, self.n))
        out_te = np.tile(te, (rec.size, 1))
        k = 0
        nxt = rec[0] if rec.size else -1
        aba, grav = pin.aba, pin.computeGeneralizedGravity
        step, integrate = _get_kernels()
        coupled, M_rot, fmix = self._coupled or self._fmix is not None, self._M_rotor, self._fmix
        if carried is not None:
            P[_ARM] += carried
        if fmix is not None:       # the kernel's friction off (the offset stays): the motors' below
            fc, dfs, vsm, fv = P[_FC].copy(), P[_DF].copy(), P[_VS].copy(), P[_FV].copy()
            P[_FC], P[_DF], P[_FV] = 0.0, 0.0, 0.0
        el = self._el
        if el.size:     # an elastic joint's friction and rotor on its motor (:meth:`_elastic_step`)
            P0 = P.copy()
            P[_FC, el], P[_DF, el], P[_FV, el], P[_ARM, el] = 0.0, 0.0, 0.0, 0.0
            ql, vl = self._ql.copy(), self._vl.copy()
            # substeps: the motor-spring mode resolved (h sqrt(k / J_m) <= 0.3 per substep)
            wmax = float(np.max(np.sqrt(np.asarray(tr.gear_stiffness, float)[el] / np.maximum(P0[_ARM, el], 1e-6))))
            sub = max(1, int(math.ceil(h * wmax / 0.3)))
        if coupled:  # the rotor inertia is a full matrix: mass matrix and solve instead of ABA
            P[_ARM] = 0.0 if carried is None else carried
            model.armature = np.zeros(self.n)
            crba, nle, solve = pin.crba, pin.nonLinearEffects, np.linalg.solve
        for i in range(m):
            qr = qref[i]
            step(qr, vff[i], aff[i], grav(mnom, dnom, qr), q, v, I, te, P, h, ieps, tau, u, arm_eff)
            if coupled:
                Mq = crba(model, data, q)
                Mq = np.triu(Mq) + np.triu(Mq, 1).T + M_rot + np.diag(arm_eff)
                if fmix is not None:
                    u, Mq = _coupled_friction(fmix, v, fc, dfs, vsm, fv, ieps, h, u, Mq)
                a = solve(Mq, u - nle(model, data, q, v))
            elif el.size:   # the link's dynamics on its own state, its elastic joints driven by their springs
                tsm = self._elastic_step(u, te, q, v, ql, vl, P0, ieps, h, sub)
                ul = u.copy()
                ul[el] = tsm + te[el]
                model.armature = arm_eff
                a = aba(model, data, ql, vl, ul)
                integrate(ql, vl, a, h)
                rigid = np.ones(self.n, bool)
                rigid[el] = False
                q[rigid], v[rigid] = ql[rigid], vl[rigid]
            else:
                model.armature = arm_eff  # implicit friction: its velocity slope joins the inertia for the step
                a = aba(model, data, q, v, u)
            if not el.size:
                integrate(q, v, a, h)
            if i == nxt:
                out_q[k] = q
                out_tau[k] = tau
                if carried is not None:
                    out_te[k] = te - carried * a
                k += 1
                nxt = rec[k] if k < rec.size else -1
        model.armature = arm
        self._q, self._v, self._I, self._tau = q, v, I, tau
        if el.size:
            self._ql, self._vl = ql, vl
        self._tick += m
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
            raise KukaidError(f"robot sim: the simulation diverged before t = {self.t:.3f} s")
        return {
            "time": (t0 + 1 + rec) * h,
            "q": self._quantise(out_q),
            "tau": self._measured(out_tau + self.noise_sigma * self._rng.standard_normal(out_tau.shape)),
            "q_cmd": qref[rec + 1],
            "tau_ext_true": out_te,
        }

    def _servo_params(self) -> np.ndarray:
        """The servo's and the truth's per-axis numbers in the rows :func:`servo_step` reads."""
        c, tr = self.cfg, self.truth
        P = np.zeros((_NP, self.n))
        P[_KP], P[_GKV], P[_GKI] = c.Kp, self.ctrl_J * c.Kv, self.ctrl_J * c.Kv * c.Ki * self.dt
        P[_JC], P[_TMAX] = self.ctrl_J, self.tau_max
        P[_FC], P[_DF], P[_VS], P[_FV], P[_OFF], P[_ARM] = tr.Fc, tr.Fs - tr.Fc, tr.vs, tr.Fv, tr.offset, tr.armature
        return P

    def _quantise(self, q: np.ndarray) -> np.ndarray:
        qd = self.cfg.quant_deg
        if qd <= 0:
            return q.copy()
        return np.round(np.degrees(q) / qd) * qd * (math.pi / 180.0)

    def read(self) -> dict[str, np.ndarray]:
        """The latest measurement: ``q`` rad (quantised), ``tau`` N·m (noisy), per axis."""
        return {"q": self._quantise(self._q),
                "tau": self._measured(self._tau + self.noise_sigma * self._rng_read.standard_normal(self.n))}

    def _measured(self, tau_joint: np.ndarray) -> np.ndarray:
        """Torques as the log reports them: joint side, or motor side (``torque_side = "motor"``)."""
        return tau_joint @ self._to_motor if self.cfg.torque_side == "motor" else tau_joint

    def run(self, traj: Any, settle: float = 0.5, progress: Callable[[float], None] | None = None):
        """Reset to ``traj``'s start, follow it to its end plus ``settle`` s; the :class:`AxisLog`."""
        from kukaid.logs.core import AxisLog

        self.reset(self.start_position(traj))
        self.follow(traj)
        t = np.asarray(traj.t, dtype=float)
        total = float(t[-1] - t[0]) + float(settle)
        parts, done = [], 0.0
        while done < total - 1e-12:
            d = min(10.0, total - done)
            parts.append(self.advance(d))
            done += d
            if progress is not None:
                progress(done)
        data = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
        return AxisLog(time=data["time"], q=data["q"], tau=data["tau"], axes=self.axes, q_cmd=data["q_cmd"],
                       tau_ext_true=data["tau_ext_true"], attrs=self.log_attrs(traj))

    def start_position(self, traj: Any) -> np.ndarray:
        """Where ``traj`` starts, for every axis (a one-axis trajectory: the others at the present command)."""
        q = np.asarray(traj.q, dtype=float)
        if q.ndim == 2:
            out = self._eval_ref(np.array([self.t]))[0][0]
            for j, a in enumerate(getattr(traj, "axes", self.axes)):
                out[int(a) - 1] = q[0, j]
            return out
        out = self._eval_ref(np.array([self.t]))[0][0]
        out[int(traj.axis) - 1] = q[0]
        return out

    def log_attrs(self, traj: Any = None) -> dict[str, Any]:
        """Provenance of a simulated log: the truth (``kukaid.robot-truth/1``), seeds, configuration."""
        from kukaid import __version__

        attrs: dict[str, Any] = {
            "source": SOURCE,
            "robot": self.cfg.robot,
            "truth": {**self.truth.to_dict(), "drive": {
                "torque_side": self.cfg.torque_side, "ratio": self.ratio.tolist(), "coupling": self.coupling.tolist(),
                "rotor_inertia": self.rotor_inertia.tolist()}},
            "seed": self.seed,
            "sim_config": self.cfg.to_dict(),
            "sample_time": self.cfg.sample_time,
            "noise_sigma": self.noise_sigma.tolist(),
            "kukaid_version": __version__,
        }
        return {**attrs, **trajectory_attrs(traj)}
