"""The torque residual of every axis of a robot: the vector Γr = Γp - Γm from the robot model.

Γm are the measured joint torques ($TORQUE_AXIS_ACT[1..n]); Γp the identified robot model's
prediction (:class:`RobotTorqueModel`)::

    Γp = Y_b(q, qd, qdd) β + M_rot qdd + Fc sign(qd) + Fv qd + (Fs - Fc) sign(qd) exp(-(qd/vs)²) + offset

with ``Y_b`` Pinocchio's joint-torque regressor on the base columns (or, with standard
parameters, the recursive Newton-Euler algorithm on the model carrying them), so the torque one
axis needs includes what the motion of every other axis couples into it (inertial, Coriolis,
centrifugal, gravity).  For a perfect model Γr equals the external torque on the joints, with the
paper's sign: pushing joint j towards positive q_j gives Γr_j > 0.

Online and causal, as the one-axis :class:`kukaid.control.torque_residual.TorqueResidual`: the
velocities and accelerations are differences of the positions; the prediction is evaluated on
those raw signals and then low-passed by the same causal Butterworth filter as the measured
torque (the filter is linear, so both sides of the difference see identical dynamics).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from kukaid.errors import KukaidError, ParamFileError
from kukaid.models.robot import smooth_sign


class RobotTorqueModel:
    """Γp(q, qd, qdd) of a whole robot (SI: rad, rad/s, rad/s² -> N·m per joint).

    Parameters
    ----------
    model : Pinocchio model of the robot (built once from its URDF).
    pi : (n, 10) standard inertial parameters per link (Pinocchio order) -> RNEA; or
    base : (independent columns, β) of the regressor's base parameters, optionally with
        (dependent columns, R) where ``β = π[independent] + R π[dependent]``: then RNEA on one
        standard parameter set with those base parameters (the URDF's values for the dependent
        ones; the torques are the same for every such set, and RNEA is faster), else the regressor.
    Fc, Fv, offset : (n,) Coulomb N·m, viscous N·m·s/rad, offset N·m.
    v_smooth, deadband : (n,) the Coulomb term's transition velocity and dead-band, rad/s
        (:func:`kukaid.models.robot.smooth_sign`).
    qd_range : (n, 2) the velocities the viscous term is held within (a fit's velocity range), rad/s.
    k : (n,) spring N·m/rad; ripple : (n, 2, K) N·m, per joint the cos and sin coefficients of the
        harmonics 1..K of its own angle (:class:`kukaid.identify.robot_fit.RobotFitSettings`).
    dFs, vs : (n,) Stribeck excess ``Fs - Fc`` N·m and velocity rad/s (optional).
    rotor : (n, n) joint-side rotor inertia matrix ``G^T diag(I_rotor) G`` kg·m² (or (n,) diagonal).
    """

    def __init__(self, model, *, pi: np.ndarray | None = None, base: tuple[np.ndarray, np.ndarray] | None = None,
                 Fc: Any = 0.0, Fv: Any = 0.0, offset: Any = 0.0, dFs: Any = 0.0, vs: Any = 0.05,
                 rotor: np.ndarray | None = None, dependent: tuple[np.ndarray, np.ndarray] | None = None,
                 k: Any = 0.0, v_smooth: Any = 0.0, ripple: np.ndarray | None = None,
                 qd_range: np.ndarray | None = None, deadband: Any = 0.0) -> None:
        import pinocchio as pin

        self._pin = pin
        n = model.nv
        self.n = n
        if (pi is None) == (base is None):
            raise KukaidError("robot torque model: give either standard parameters pi or base parameters")
        self.model = model.copy()
        if pi is not None:
            pi = np.asarray(pi, dtype=float).reshape(n, 10)
            for j in range(1, self.model.njoints):
                self.model.inertias[j] = pin.Inertia.FromDynamicParameters(pi[j - 1])
            self.base = None
        else:
            self.base = (np.asarray(base[0], dtype=int), np.asarray(base[1], dtype=float))
            if dependent is not None:
                ind, beta = self.base
                dep, R = np.asarray(dependent[0], dtype=int), np.asarray(dependent[1], dtype=float).reshape(ind.size, -1)
                pi_eq = np.concatenate([model.inertias[j].toDynamicParameters() for j in range(1, model.njoints)])
                pi_eq[ind] = beta - (R @ pi_eq[dep] if dep.size else 0.0)
                if np.all(pi_eq[0::10] != 0):  # Pinocchio's spatial inertia needs a non-zero mass per link
                    for j in range(1, self.model.njoints):
                        self.model.inertias[j] = pin.Inertia.FromDynamicParameters(pi_eq[10 * (j - 1):10 * j])
                    self.base = None
        self.model.armature = np.zeros(n)
        self.data = self.model.createData()
        vec = lambda x: np.broadcast_to(np.asarray(x, dtype=float), (n,)).copy()  # noqa: E731
        self.Fc, self.Fv, self.offset, self.dFs, self.vs = vec(Fc), vec(Fv), vec(offset), vec(dFs), vec(vs)
        self.k, self.v_smooth, self.deadband = vec(k), vec(v_smooth), vec(deadband)
        rg = None if qd_range is None else np.asarray(qd_range, dtype=float).reshape(n, 2)
        self._vlo, self._vhi = (None, None) if rg is None else (rg[:, 0].copy(), rg[:, 1].copy())
        # (n, 2, K): per joint, the cos and sin coefficients of harmonics 1..K of its own angle
        self.ripple = None if ripple is None or np.size(ripple) == 0 else np.asarray(ripple, float).reshape(n, 2, -1)
        self._harm = None if self.ripple is None else np.arange(1, self.ripple.shape[2] + 1)
        rot = np.zeros((n, n)) if rotor is None else np.asarray(rotor, dtype=float)
        self.rotor = np.diag(rot) if rot.ndim == 1 else rot
        self._stribeck = bool(np.any(self.dFs != 0))
        self._has_rotor = bool(np.any(self.rotor != 0))

    def rigid(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """Rigid-body joint torques (n,), N·m."""
        pin = self._pin
        if self.base is None:
            return pin.rnea(self.model, self.data, q, qd, qdd).copy()
        ind, beta = self.base
        return pin.computeJointTorqueRegressor(self.model, self.data, q, qd, qdd)[:, ind] @ beta

    def friction(self, qd: np.ndarray, q: np.ndarray | None = None) -> np.ndarray:
        """Friction, offset and the joint's own spring ``k q`` (when ``q`` is given) per joint (n,), N·m."""
        s = smooth_sign(qd, self.v_smooth, self.deadband)
        f = self.Fc * s + self.Fv * (qd if self._vlo is None else np.clip(qd, self._vlo, self._vhi)) + self.offset
        if q is not None:
            f = f + self.k * q
            if self.ripple is not None:
                ph = np.outer(q, self._harm)
                f = f + np.sum(self.ripple[:, 0] * np.cos(ph) + self.ripple[:, 1] * np.sin(ph), axis=1)
        if self._stribeck:
            f = f + self.dFs * s * np.exp(-(qd / self.vs) ** 2)
        return f

    def __call__(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """Γp (n,), N·m, at one state."""
        tau = self.rigid(q, qd, qdd) + self.friction(qd, q)
        if self._has_rotor:
            tau = tau + self.rotor @ qdd
        return tau

    # -- constructors ----------------------------------------------------------------------------
    @classmethod
    def from_params(cls, params: dict, where: str = "robot parameter file") -> "RobotTorqueModel":
        """From a ``kukaid.robot_params/1`` dictionary (``kukaid fit --robot``): its base parameters
        (the estimate it predicts with), per-joint friction, offset and spring, rotor inertias: the
        same terms as :func:`kukaid.identify.robot_fit.predict_robot`."""
        from kukaid.models.urdf import load_model, robot_urdf, urdf_sha256
        from kukaid.params.robot import check_fitted_urdf

        if params.get("effects"):      # a file refined by kukaid diagnose -o: not modelled here yet
            raise ParamFileError(f"{where}: its effects ({', '.join(params['effects'])}, named by kukaid diagnose) "
                                 "are not in the real-time torque model yet; use the file without them")
        try:
            urdf = robot_urdf(params["robot"]["urdf"])
            check_fitted_urdf(params, urdf_sha256(urdf), urdf)  # edited since the fit: not the robot the file describes
            model = load_model(params["robot"]["urdf"])
            n = model.nv
            bp = params["base_parameters"]
            fr = params["friction"]
            vals = fr["values"]
            get = lambda key: np.array([float(vals.get(f"A{j}.{key}", 0.0)) for j in range(1, n + 1)])  # noqa: E731
            rotor = None
            ir = [vals.get(f"M{k}.rotor_inertia") for k in range(1, n + 1)]
            if any(v is not None for v in ir):
                drive = params.get("drive") or {}
                ratio = np.asarray(drive.get("ratio", np.ones(n)), dtype=float)
                coupling = np.asarray(drive.get("coupling", np.zeros((n, n))), dtype=float)
                G = np.diag(ratio) @ (np.eye(n) + coupling)
                rotor = G.T @ np.diag([float(v or 0.0) for v in ir]) @ G
            dep = (np.asarray(bp["dependent"], int), np.asarray(bp["R"], float)) if "R" in bp else None
            st = params.get("settings") or {}
            K = int(st.get("ripple") or 0)
            ripple = np.array([[[float(vals.get(f"A{j}.ripple_{cs}{h}", 0.0)) for h in range(1, K + 1)]
                                for cs in ("cos", "sin")] for j in range(1, n + 1)]) if K else None
            return cls(model, base=(np.asarray(bp["independent"], int), np.asarray(bp["values"], float)),
                       dependent=dep, Fc=get("Fc"), Fv=get("Fv"), offset=get("offset"), dFs=get("Fs-Fc"),
                       vs=float(fr.get("vs") or st.get("vs") or 0.05), rotor=rotor, k=get("k"),
                       v_smooth=st.get("v_smooth") or 0.0, ripple=ripple, qd_range=fr.get("qd_range"),
                       deadband=st.get("deadband") or 0.0)
        except (KeyError, TypeError, ValueError) as e:
            raise ParamFileError(f"{where}: not a usable kukaid.robot_params/1 file ({type(e).__name__}: {e})") from None

    @classmethod
    def from_truth(cls, truth: dict, model=None) -> "RobotTorqueModel":
        """From a simulator's truth (``kukaid.robot-truth/1``, a log's ``truth`` attribute; its
        ``drive`` section, when present, gives the rotor inertias on coupled drives)."""
        from kukaid.models.urdf import load_model

        model = model if model is not None else load_model(truth["robot"])
        f = truth["friction"]
        Fc = np.asarray(f["Fc"], float)
        rotor = np.asarray(truth["armature"], float)
        drive = truth.get("drive")
        if drive:  # rotors on coupled drives: G^T diag(I_rotor) G on the joint side
            n = model.nv
            G = np.diag(np.asarray(drive["ratio"], float)) @ (np.eye(n) + np.asarray(drive["coupling"], float))
            rotor = G.T @ np.diag(np.asarray(drive["rotor_inertia"], float)) @ G
        return cls(model, pi=np.asarray(truth["pi"], float), Fc=Fc, Fv=f["Fv"], dFs=np.asarray(f["Fs"], float) - Fc,
                   vs=f["vs"], offset=truth["offset"], rotor=rotor)


class _Butterworth:
    """Causal Butterworth low-pass of n channels at once (second-order sections, transposed
    direct form II); starts at steady state on the first sample."""

    def __init__(self, n: int, cutoff: float, fs: float, order: int) -> None:
        from scipy.signal import butter, sosfilt_zi

        if not (math.isfinite(fs) and fs > 0 and math.isfinite(cutoff) and 0 < cutoff < fs / 2):
            raise KukaidError(f"robot residual: cut-off {cutoff} Hz must be in (0, {fs / 2:g}) Hz at {fs:g} Hz")
        sos = butter(order, cutoff, fs=fs, output="sos")
        self._b, self._a = np.ascontiguousarray(sos[:, :3]), np.ascontiguousarray(sos[:, 4:6])
        self._zi0 = sosfilt_zi(sos)  # (sections, 2)
        self._z: np.ndarray | None = None
        self.n = n

    def reset(self, x0: np.ndarray | None = None) -> None:
        self._z = None if x0 is None else np.ascontiguousarray(self._zi0[:, :, None] * np.asarray(x0, float)[None, None, :])

    def step(self, x: np.ndarray) -> np.ndarray:
        """Filter one sample (n,); returns a new array."""
        if self._z is None:
            self.reset(x)
        y = np.empty(self.n)
        _sos_kernel()(np.asarray(x, dtype=float), self._z, self._b, self._a, y)
        return y


def sos_step(x, z, b, a, y):
    """One sample of cascaded second-order sections over channels (scalar code, numba-compilable):
    input ``x`` (n,), state ``z`` (sections, 2, n) updated in place, output into ``y`` (n,)."""
    for j in range(x.shape[0]):
        v = x[j]
        for s in range(b.shape[0]):
            out = b[s, 0] * v + z[s, 0, j]
            z[s, 0, j] = b[s, 1] * v - a[s, 0] * out + z[s, 1, j]
            z[s, 1, j] = b[s, 2] * v - a[s, 1] * out
            v = out
        y[j] = v


_kernel = None


def _sos_kernel():
    """:func:`sos_step` compiled by numba when available (``KUKAID_NO_NUMBA=1``: plain Python)."""
    global _kernel
    if _kernel is None:
        import os

        try:
            if os.environ.get("KUKAID_NO_NUMBA"):
                raise ImportError
            from numba import njit
        except ImportError:
            _kernel = sos_step
        else:
            _kernel = njit(cache=True, nogil=True)(sos_step)
    return _kernel


@dataclass(frozen=True)
class RobotResidualSample:
    """One step (SI, (n,) arrays): residual ``gamma_r`` N·m, prediction ``gamma_p``, filtered torque
    ``tau_f``, filtered ``q``, ``qd``, ``qdd``, ``detected`` (per axis)."""

    gamma_r: np.ndarray
    gamma_p: np.ndarray
    tau_f: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    detected: np.ndarray


class RobotResidual:
    """Online torque residual of every axis (module docstring).

    Parameters
    ----------
    model : :class:`RobotTorqueModel`.
    sample_time : s between measurements.
    cutoff, order : the causal Butterworth low-pass (Hz; the paper's 5 Hz, 3rd order).
    threshold, release : per-axis detection thresholds with hysteresis, N·m (default: none).
    torque_side : "joint", or "motor" with ``drive_G`` (n, n): measured motor-side torques are
        converted to the joint side, ``tau_joint = G^T tau_motor``.
    """

    def __init__(self, model: RobotTorqueModel, sample_time: float = 0.012, cutoff: float = 5.0, order: int = 3,
                 threshold: Any = math.inf, release: Any = None, torque_side: str = "joint",
                 drive_G: np.ndarray | None = None) -> None:
        if not (math.isfinite(sample_time) and sample_time > 0):
            raise KukaidError(f"robot residual: sample time must be > 0 s, got {sample_time}")
        n = model.n
        self.model, self.n, self.sample_time = model, n, float(sample_time)
        fs = 1.0 / self.sample_time
        # one filter over the 5 n channels: q, qd, qdd, measured torque, prediction
        self._filter = _Butterworth(5 * n, cutoff, fs, order)
        self._x = np.empty(5 * n)
        self.threshold = np.broadcast_to(np.asarray(threshold, float), (n,)).copy()
        self.release = self.threshold * 0.7 if release is None else np.broadcast_to(np.asarray(release, float), (n,)).copy()
        if torque_side not in ("joint", "motor"):
            raise KukaidError(f"robot residual: torque side must be 'joint' or 'motor', got {torque_side!r}")
        self._GT = None if torque_side == "joint" else np.asarray(drive_G, float).T
        self.reset()

    def reset(self) -> None:
        """Forget the past: the next measurement starts the filters at steady state."""
        self._filter.reset()
        self._q_prev: np.ndarray | None = None
        self._qd_prev = np.zeros(self.n)
        self._detected = np.zeros(self.n, dtype=bool)

    def end_detection(self, axis: int) -> None:
        """End the detection of ``axis`` (1..n) now; a new one needs its threshold again."""
        self._detected = self._detected.copy()  # the last sample keeps what it reported
        self._detected[axis - 1] = False

    def update(self, q: np.ndarray, tau: np.ndarray, dt: float | None = None) -> RobotResidualSample:
        """Feed one measurement (positions rad, torques N·m, one per axis); return the residual."""
        q = np.asarray(q, dtype=float)
        tau = np.asarray(tau, dtype=float)
        if q.shape != (self.n,) or tau.shape != (self.n,):
            raise KukaidError(f"robot residual: expected {self.n} positions and torques, got {q.shape}, {tau.shape}")
        if self._GT is not None:
            tau = self._GT @ tau
        h = self.sample_time if dt is None else float(dt)
        if self._q_prev is None:
            self._q_prev = q
        qd = (q - self._q_prev) / h
        qdd = (qd - self._qd_prev) / h
        self._q_prev, self._qd_prev = q, qd
        n, x = self.n, self._x
        x[:n], x[n:2 * n], x[2 * n:3 * n], x[3 * n:4 * n], x[4 * n:] = q, qd, qdd, tau, self.model(q, qd, qdd)
        y = self._filter.step(x)
        pred, tau_f = y[4 * n:], y[3 * n:4 * n]
        gamma_r = pred - tau_f
        a = np.abs(gamma_r)
        self._detected = np.where(self._detected, a >= self.release, a >= self.threshold)
        return RobotResidualSample(gamma_r, pred, tau_f, y[:n], y[n:2 * n], y[2 * n:3 * n], self._detected)


@dataclass(frozen=True)
class GuidedAxisSample:
    """One step of :class:`GuidedAxisResidual` for the admittance loop (the fields it reads, as
    :class:`kukaid.control.torque_residual.ResidualSample`): ``gamma_r``, ``gamma_p``, ``tau_f`` N·m
    and ``q`` rad, ``qd`` rad/s, ``qdd`` rad/s² of the guided axis, ``mode`` ("dynamic": the robot
    model has one mode), ``detected``, and the whole vector step ``robot``."""

    gamma_r: float
    gamma_p: float
    tau_f: float
    q: float
    qd: float
    qdd: float
    mode: str
    detected: bool
    robot: RobotResidualSample


class GuidedAxisResidual:
    """The admittance loop's estimator for one guided axis of a robot: the robot model's Γr of that
    axis, from the positions and torques of every axis, so the torque the others' motion couples
    into the guided axis is predicted rather than taken for a push.

    Parameters
    ----------
    model : :class:`RobotTorqueModel`.
    axis : the guided axis, 1..n.
    sample_time, cutoff, order : as :class:`RobotResidual` (s, Hz).
    threshold, release : detection on the guided axis's |Γr| with hysteresis, N·m.
    """

    ignored_effects: tuple[str, ...] = ()

    def __init__(self, model: RobotTorqueModel, axis: int, sample_time: float = 0.012, threshold: float = 5.0,
                 release: float | None = None, cutoff: float = 5.0, order: int = 3) -> None:
        if not 1 <= int(axis) <= model.n:
            raise KukaidError(f"robot residual: guided axis A{axis} is not an axis of the robot (A1..A{model.n})")
        self.axis = int(axis)
        self.sample_time, self.cutoff, self.order = float(sample_time), float(cutoff), int(order)
        th = np.full(model.n, math.inf)
        th[self.axis - 1] = float(threshold)
        rel = None if release is None else np.where(np.arange(model.n) == self.axis - 1, float(release), math.inf)
        self.residual = RobotResidual(model, sample_time=sample_time, cutoff=cutoff, order=order, threshold=th,
                                      release=rel)

    def end_detection(self) -> None:
        """End the guided axis's present detection now (the loop's judgement, as
        :meth:`kukaid.control.torque_residual.TorqueResidual.end_detection`)."""
        self.residual.end_detection(self.axis)

    def update(self, q: np.ndarray, tau: np.ndarray, dt: float | None = None) -> GuidedAxisSample:
        """Feed the positions (rad) and torques (N·m) of every axis; the guided axis's step."""
        r = self.residual.update(q, tau, dt)
        j = self.axis - 1
        return GuidedAxisSample(float(r.gamma_r[j]), float(r.gamma_p[j]), float(r.tau_f[j]), float(r.q[j]),
                                float(r.qd[j]), float(r.qdd[j]), "dynamic", bool(r.detected[j]), r)


def robot_residual(q: np.ndarray, tau: np.ndarray, model: RobotTorqueModel, sample_time: float,
                   **options: Any) -> dict[str, np.ndarray]:
    """Run :class:`RobotResidual` over recorded samples (causally, as online): (N, n) arrays
    ``gamma_r``, ``gamma_p``, ``tau_f`` (N·m) and ``detected``."""
    res = RobotResidual(model, sample_time=sample_time, **options)
    q, tau = np.asarray(q, float), np.asarray(tau, float)
    out = {k: np.empty(q.shape) for k in ("gamma_r", "gamma_p", "tau_f")}
    det = np.zeros(q.shape, dtype=bool)
    for i in range(q.shape[0]):
        s = res.update(q[i], tau[i])
        out["gamma_r"][i], out["gamma_p"][i], out["tau_f"][i], det[i] = s.gamma_r, s.gamma_p, s.tau_f, s.detected
    out["detected"] = det
    return out
