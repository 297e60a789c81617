"""The virtual KR C4: one robot axis under the KR C4's own position control, measured as a KRC does.

Physics (SI), integrated with ``substeps`` semi-implicit Euler steps per servo cycle::

    Izz qdd = tau_m + tau_ext - Mx cos q - My sin q - F_friction - tau_effects

* ``tau_m`` motor torque from a cascaded position / velocity servo at ``servo_rate`` (1 kHz):
  ``v_ref = qd_ff + Kp (q_ref - q)``, ``tau_m = ctrl_Izz qdd_ff + ctrl_Mx cos q_ref
  + ctrl_Izz Kv (v_ref - qd) + integral``, limited to ``+-tau_max`` (anti-windup by clamping).
  The commanded trajectory arrives at the IPO rate (12 ms) and is interpolated with a C2 cubic
  spline, which also gives the velocity and (continuous) acceleration feedforward.
  The controller's model (``ctrl_Izz``, ``ctrl_Mx``) is machine data, not the truth.
* friction: :mod:`kukaid.sim.friction_sim` (Maxwell-slip at standstill, exactly Stribeck when
  sliding, continuous in between); hidden effects: :mod:`kukaid.sim.effects`; ambient vibration:
  :mod:`kukaid.sim.vibration`.
* measurement as the KRC gives it: every ``sample_time`` (12 ms, optional uniform timing jitter),
  position ($AXIS_ACT_MEAS) rounded to ``quant_deg`` degrees, torque ($TORQUE_AXIS_ACT) = motor
  torque + Gaussian noise of ``noise_sigma``; motor temperature from a first-order thermal model
  driven by friction and copper losses.

So the measured torque is ``Izz qdd + gravity + friction + effects - tau_ext`` + noise: the
paper's residual ``Γr = Γp - Γm`` equals ``tau_ext`` for a perfect model.

Random numbers come from independent streams spawned from ``seed`` (torque noise, vibration,
jitter, :meth:`read`), so the same seed and the same calls give the same log bit for bit, however
:meth:`advance` is chunked (as long as the external torque is not a function).
"""
from __future__ import annotations

import json
import math
from typing import Any, Callable

import numpy as np

from kukaid.errors import KukaidError
from kukaid.sim import kernel as K
from kukaid.sim.config import SimConfig
from kukaid.sim.vibration import vibration_gain

SOURCE = "virtual-krc4"


# -- commanded position schedules ---------------------------------------------------------------
class _Hold:
    def __init__(self, q: float) -> None:
        self.q = float(q)
        self.t_end = -math.inf

    def eval(self, t: np.ndarray):
        n = t.size
        return np.full(n, self.q), np.zeros(n), np.zeros(n)


def trajectory_attrs(traj: Any) -> dict[str, Any]:
    """A simulated log's record of the trajectory it ran: experiment kind and parameters."""
    if traj is None:
        return {}
    attrs: dict[str, Any] = {"experiment": str(getattr(traj, "kind", "unknown"))}
    params = getattr(traj, "params", None)
    if params is not None:
        attrs["trajectory"] = json.loads(json.dumps(params, default=str))
    return attrs


class _Spline:
    """Interpolation of IPO knots (t, q): a C2 cubic spline (continuous acceleration feedforward,
    as a KRC's fine interpolator), or linear ramps; holds the last value after the end.

    ``q`` is (N,) for one axis or (N, A) for A axes interpolated together."""

    def __init__(self, t: np.ndarray, q: np.ndarray, linear: bool = False) -> None:
        self.t = t
        self.q = q
        self.t_end = float(t[-1])
        self.cs = None
        if not linear and t.size >= 3:
            from scipy.interpolate import CubicSpline

            # end velocities: zero when the schedule starts/ends at rest, else one-sided differences
            v0 = np.where(np.abs(q[1] - q[0]) < 1e-15, 0.0, (q[1] - q[0]) / (t[1] - t[0]))
            v1 = np.where(np.abs(q[-1] - q[-2]) < 1e-15, 0.0, (q[-1] - q[-2]) / (t[-1] - t[-2]))
            self.cs = CubicSpline(t, q, bc_type=((1, v0), (1, v1)))

    def eval(self, tt: np.ndarray):
        t, q = self.t, self.q
        shape = (tt.size,) + q.shape[1:]
        qo = np.empty(shape)
        vo = np.zeros(shape)
        ao = np.zeros(shape)
        before = tt < t[0]  # the knot itself belongs to the segment (velocity feedforward at a new setpoint)
        after = tt >= t[-1]
        qo[before] = q[0]
        qo[after] = q[-1]
        mid = ~(before | after)
        if mid.any():
            x = tt[mid]
            if self.cs is None:
                i = np.clip(np.searchsorted(t, x, side="right") - 1, 0, t.size - 2)
                hseg = (t[i + 1] - t[i]).reshape((-1,) + (1,) * (q.ndim - 1))
                s = (x - t[i]).reshape(hseg.shape) / hseg
                qo[mid] = q[i] + s * (q[i + 1] - q[i])
                vo[mid] = (q[i + 1] - q[i]) / hseg
            else:
                qo[mid] = self.cs(x)
                vo[mid] = self.cs(x, 1)
                ao[mid] = self.cs(x, 2)
        return qo, vo, ao


def _effect_params(cfg: SimConfig) -> dict[str, float]:
    e = cfg.effects
    out = {"off": 0.0, "rA": 0.0, "rN": 0.0, "rPhi": 0.0, "kappa": 0.0, "Tref": cfg.T_amb, "loadc": 0.0,
           "bA": 0.0, "btau": 0.1, "bvon": 0.01, "My": 0.0}
    if "gravity_sine" in e:
        out["My"] = e["gravity_sine"]["My"]
    if "torque_offset" in e:
        out["off"] = e["torque_offset"]["offset"]
    if "position_ripple" in e:
        r = e["position_ripple"]
        out.update(rA=r["A"], rN=r["n"], rPhi=r["phi"])
    if "thermal_drift" in e:
        d = e["thermal_drift"]
        out["kappa"] = d["kappa"]
        if d.get("T_ref") is not None:
            out["Tref"] = d["T_ref"]
    if "load_dependent_friction" in e:
        out["loadc"] = e["load_dependent_friction"]["c"]
    if "backlash" in e:
        b = e["backlash"]
        out.update(bA=b["A"], btau=b["tau"], bvon=b["v_on"])
    return out


class VirtualKRC4:
    """A simulated KR C4 with one moving axis; see the module docstring for the physics.

    Parameters
    ----------
    cfg : SimConfig, default the paper's A3.
    seed : seed of all random streams (noise, vibration, jitter).
    axis : KUKA axis number reported in logs (default ``cfg.axis``).
    """

    def __init__(self, cfg: SimConfig | None = None, seed: int = 0, axis: int | None = None) -> None:
        self.cfg = cfg if cfg is not None else SimConfig()
        if not isinstance(self.cfg, SimConfig):
            raise TypeError("cfg must be a SimConfig")
        self.seed = int(seed)
        self.axis = int(axis if axis is not None else self.cfg.axis)
        c = self.cfg
        self.dt = 1.0 / c.servo_rate
        self._ticks_per_sample = c.sample_time / self.dt
        eff = _effect_params(c)
        p = np.zeros(K.N_PARAM)
        p[K.P_IZZ], p[K.P_MX], p[K.P_MY] = c.Izz, c.Mx, c.My + eff["My"]
        p[K.P_FC], p[K.P_FS], p[K.P_VS], p[K.P_DELTA], p[K.P_FV] = c.Fc, c.Fs, c.vs, c.delta, c.Fv
        p[K.P_SUMW], p[K.P_VBL] = c.sum_W, c.v_blend
        p[K.P_KP], p[K.P_KV], p[K.P_KI] = c.Kp, c.Kv, c.Ki
        p[K.P_CIZZ], p[K.P_CMX], p[K.P_TMAX] = c.ctrl_Izz, c.ctrl_Mx, c.tau_max
        p[K.P_TAMB], p[K.P_RTH], p[K.P_CTH], p[K.P_RCU] = c.T_amb, c.R_th, c.C_th, c.r_cu
        p[K.P_VIBG] = vibration_gain(c.vib_amplitude, c.vib_freq, c.vib_zeta) if c.vibration else 0.0
        p[K.P_VIBW], p[K.P_VIBZ] = 2 * math.pi * c.vib_freq, c.vib_zeta
        p[K.P_OFF], p[K.P_RA], p[K.P_RN], p[K.P_RPHI] = eff["off"], eff["rA"], eff["rN"], eff["rPhi"]
        p[K.P_KAPPA], p[K.P_TREF], p[K.P_LOADC] = eff["kappa"], eff["Tref"], eff["loadc"]
        p[K.P_BA], p[K.P_BTAU], p[K.P_BVON] = eff["bA"], eff["btau"], eff["bvon"]
        lugre = c.friction_law == "lugre"
        p[K.P_LUGRE], p[K.P_S0] = float(lugre), c.lugre_sigma0
        p[K.P_S1] = 2.0 * c.lugre_zeta * math.sqrt(c.lugre_sigma0 * c.Izz)
        p[K.P_FPA], p[K.P_FPN], p[K.P_FPPHI] = c.fric_pos_amp, c.fric_pos_n, c.fric_pos_phi
        self._p = p
        self._k = np.asarray(c.ms_k, dtype=float)
        self._w = np.asarray(c.ms_W, dtype=float) / c.sum_W
        # pre-sliding damping of each element (LuGre's sigma1): c_i = 2 zeta sqrt(k_i Izz)
        self._c = 2.0 * c.ms_damping * np.sqrt(self._k * c.Izz)
        self._kernel = K.get_kernel()
        # physics sub-steps: at least cfg.substeps, and enough for the stiffest mode (the
        # Maxwell-slip springs against the inertia) to be integrated accurately (w h <= 0.3)
        if lugre:
            w_max = math.sqrt(c.lugre_sigma0 / c.Izz)
            d_max = float(p[K.P_S1] + c.Fv) / c.Izz
        else:
            w_max = math.sqrt(float(np.sum(self._k)) / c.Izz)
            d_max = float(np.sum(self._c) + c.Fv) / c.Izz  # explicit damping rate, 1/s
        self.substeps = max(int(c.substeps), int(math.ceil(w_max * self.dt / 0.3)),
                            int(math.ceil(d_max * self.dt / 0.5)))
        self._tau_ext: float | Callable = 0.0
        self.reset(0.0)

    # -- state ---------------------------------------------------------------------------------
    def reset(self, q0: float = 0.0, direction: float | None = None) -> None:
        """Standstill at ``q0`` (rad), time 0, random streams restarted from the seed.

        The Maxwell-slip elements start at ``cfg.ms_zeta0`` relative to ``q0`` (clamped to their
        saturation), or, with ``direction`` = +1/-1, saturated as after a move in that direction
        (eq. 12).  The servo integrator starts at the torque that holds the axis there.  The
        external torque set by :meth:`set_external_torque` is kept.
        """
        c = self.cfg
        q0 = float(q0)
        if not math.isfinite(q0):
            raise KukaidError(f"virtual KR C4: reset position must be finite, got {q0}")
        k, W = self._k, np.asarray(c.ms_W)
        if direction is None or direction == 0:
            F = np.clip(-k * np.asarray(c.ms_zeta0), -W, W)
        else:
            F = np.sign(direction) * W
        self._F = F.astype(float)
        self._E = self._F / self._k  # spring stretches at rest
        lugre = c.friction_law == "lugre"
        if lugre:  # bristles at rest: unloaded, or deflected to stiction after a move (F = Fs)
            self._F = np.zeros_like(self._F)
            F = np.array([0.0 if not direction else float(np.sign(direction)) * c.Fs])
        st = np.zeros(K.N_STATE)
        st[K.S_Q] = q0
        st[K.S_T] = c.temp0
        st[K.S_QREF] = q0
        st[K.S_BDIR] = 0.0 if direction is None else float(np.sign(direction))  # gear contact side
        st[K.S_Z] = float(F.sum()) / c.lugre_sigma0 if lugre else 0.0
        eff = self._p
        hold = c.Mx * math.cos(q0) + eff[K.P_MY] * math.sin(q0) + float(F.sum()) + eff[K.P_OFF]
        if eff[K.P_RA]:
            hold += eff[K.P_RA] * math.sin(eff[K.P_RN] * q0 + eff[K.P_RPHI])
        st[K.S_I] = float(np.clip(hold - c.ctrl_Mx * math.cos(q0), -c.tau_max, c.tau_max))
        st[K.S_TAU] = st[K.S_I] + c.ctrl_Mx * math.cos(q0)
        self._st = st
        self._tau_hist = np.full(c.tau_delay, st[K.S_TAU])  # torque samples not yet reported (tau_delay)
        self._tick = 0
        self._t_req = 0.0
        ss = np.random.SeedSequence(self.seed)
        r_noise, r_vib, r_jit, r_read = (np.random.default_rng(s) for s in ss.spawn(4))
        self._rng_noise, self._rng_vib, self._rng_jit, self._rng_read = r_noise, r_vib, r_jit, r_read
        # schedule of KRC samples: sample k (k = 1, 2, ...) is due at k * sample_time (+ jitter),
        # taken at the end of a servo tick; generated in batches, in order (chunking-independent)
        self._sched = np.zeros(0, dtype=np.int64)
        self._sched_pos = 0
        self._sched_k = 1
        self._sched_last = -1
        self._ref: Any = _Hold(q0)
        self._last_cmd = q0
        self._t_last_cmd: float | None = None

    @property
    def t(self) -> float:
        """Simulated time, s."""
        return self._tick * self.dt

    @property
    def q(self) -> float:
        """True joint position, rad (not quantised)."""
        return float(self._st[K.S_Q])

    @property
    def qd(self) -> float:
        """True joint velocity, rad/s."""
        return float(self._st[K.S_V])

    def _extend_schedule(self, batch: int = 4096) -> None:
        """Append the ticks of the next ``batch`` samples (strictly increasing) to the schedule."""
        c = self.cfg
        k = self._sched_k + np.arange(batch)
        t = k * c.sample_time
        if c.jitter > 0:
            t = t + self._rng_jit.uniform(-c.jitter, c.jitter, batch)
        ticks = np.maximum(np.rint(t / self.dt).astype(np.int64) - 1, 0)
        # strictly increasing, also across batches: t'_i = max(t_i, t'_{i-1} + 1)
        u = np.maximum.accumulate(np.maximum(ticks - np.arange(batch), self._sched_last + 1))
        ticks = u + np.arange(batch)
        self._sched = np.concatenate([self._sched[self._sched_pos:], ticks])
        self._sched_pos = 0
        self._sched_k += batch
        self._sched_last = int(ticks[-1])

    # -- inputs --------------------------------------------------------------------------------
    def follow(self, traj: Any) -> None:
        """Track the commanded schedule ``traj.q`` (rad) at ``traj.t`` (s, IPO rate) from now on.

        ``traj.t[0]`` is mapped to the present simulated time; after the end the last value is held.
        """
        t = np.asarray(getattr(traj, "t"), dtype=float).ravel()
        q = np.asarray(getattr(traj, "q"), dtype=float).ravel()
        if t.size != q.size or t.size < 2:
            raise KukaidError(f"trajectory: t and q must have the same length >= 2 (got {t.size}, {q.size})")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(q))):
            raise KukaidError("trajectory: t and q must be finite numbers")
        if np.any(np.diff(t) <= 0):
            raise KukaidError("trajectory: time must be strictly increasing")
        t = t - t[0] + self.t
        self._ref = _Spline(t, q)
        self._last_cmd = float(q[-1])
        self._t_last_cmd = None

    def command(self, q_cmd: float) -> None:
        """A new position setpoint (rad), streamed (admittance control, RSI/KUKAVARPROXY style).

        The interpolator ramps linearly from the present reference to ``q_cmd`` over the interval
        since the previous setpoint (at least one IPO cycle, at most four), so setpoints streamed
        at a steady rate give a continuous reference velocity, one interval behind.
        """
        q_cmd = float(q_cmd)
        if not math.isfinite(q_cmd):
            raise KukaidError(f"virtual KR C4: commanded position must be finite, got {q_cmd}")
        now = self.t
        ipo = self.cfg.ipo_period
        last = self._t_last_cmd
        span = ipo if last is None else min(max(now - last, ipo), 4 * ipo)
        q_now = float(self._ref.eval(np.array([now]))[0][0])
        self._ref = _Spline(np.array([now, now + span]), np.array([q_now, q_cmd]), linear=True)
        self._last_cmd = q_cmd
        self._t_last_cmd = now

    def set_external_torque(self, tau: float | Callable[[float, float, float], float]) -> None:
        """External torque on the link (a person's push), N·m: a number or ``fn(t, q, qd)``.

        A function is evaluated once per KRC sample period (12 ms) and held in between.
        """
        if callable(tau):
            self._tau_ext = tau
        else:
            tau = float(tau)
            if not math.isfinite(tau):
                raise KukaidError(f"virtual KR C4: external torque must be finite, got {tau}")
            self._tau_ext = tau

    # -- running -------------------------------------------------------------------------------
    def advance(self, duration: float) -> dict[str, np.ndarray]:
        """Run the physics for ``duration`` s; return the KRC samples taken meanwhile (SI arrays).

        Keys: ``time`` s, ``q`` rad (quantised), ``tau`` N·m (noisy), ``q_cmd`` rad, ``temp`` °C,
        ``tau_ext_true`` N·m.
        """
        duration = float(duration)
        if not math.isfinite(duration) or duration < 0:
            raise KukaidError(f"virtual KR C4: duration must be a finite number >= 0 s, got {duration}")
        # count ticks from the accumulated requested time, so many short calls do not drift
        self._t_req += duration
        n = max(int(round(self._t_req / self.dt)) - self._tick, 0)
        blocks: list[dict[str, np.ndarray]] = []
        if callable(self._tau_ext):
            per = max(int(round(self._ticks_per_sample)), 1)
            done = 0
            while done < n:
                m = min(per, n - done)
                te = float(self._tau_ext(self.t, self.q, self.qd))
                if not math.isfinite(te):
                    raise KukaidError(f"virtual KR C4: external torque function returned {te} at t = {self.t:.3f} s")
                blocks.append(self._run_ticks(m, te))
                done += m
        else:
            # bounded chunks keep the temporary arrays small on long runs
            chunk = 200_000
            done = 0
            while done < n:
                m = min(chunk, n - done)
                blocks.append(self._run_ticks(m, float(self._tau_ext)))
                done += m
        if not blocks:
            return self._empty()
        if len(blocks) == 1:
            return blocks[0]
        return {key: np.concatenate([b[key] for b in blocks]) for key in blocks[0]}

    @staticmethod
    def _empty() -> dict[str, np.ndarray]:
        return {k: np.zeros(0) for k in ("time", "q", "tau", "q_cmd", "temp", "tau_ext_true")}

    def _run_ticks(self, n: int, tau_ext: float) -> dict[str, np.ndarray]:
        c = self.cfg
        t0 = self._tick
        # the servo of tick i acts on the reference at the tick's start; samples are taken at its end
        tt = (t0 + np.arange(n + 1)) * self.dt
        qref, vff, aff = self._ref.eval(tt)
        wn = self._rng_vib.standard_normal(n) if self._p[K.P_VIBG] != 0.0 else np.zeros(n)
        text = np.full(n, tau_ext)
        while self._sched_last < t0 + n:
            self._extend_schedule(max(4096, int(n / self._ticks_per_sample) + 2))
        end = self._sched_pos + int(np.searchsorted(self._sched[self._sched_pos:], t0 + n))
        samp = self._sched[self._sched_pos:end] - t0
        self._sched_pos = end
        m = samp.size
        out = [np.empty(m) for _ in range(6)]
        rec = self._kernel(n, self.dt, self.substeps, qref, vff, aff, wn, text, self._st, self._F, self._E, self._p,
                           self._k, self._w, self._c, samp, *out)
        assert rec == m
        self._tick += n
        if not np.all(np.isfinite(self._st)):
            raise KukaidError(f"virtual KR C4: the simulation diverged before t = {self.t:.3f} s; "
                              f"check the configuration (Izz, ms_k, Kv, servo_rate)")
        q, tau, qcmd, temp, te, _v = out
        if c.tau_delay:  # $TORQUE_AXIS_ACT reports the motor torque of tau_delay samples ago
            both = np.concatenate([self._tau_hist, tau])
            tau, self._tau_hist = both[:m], both[m:]
        return {
            "time": (t0 + 1 + samp) * self.dt,
            "q": self._quantise(q),
            "tau": self._quantise_tau(tau + c.noise_sigma * self._rng_noise.standard_normal(m)),
            "q_cmd": qcmd,
            "temp": np.round(temp, 2),
            "tau_ext_true": te,
        }

    def _quantise(self, q: np.ndarray) -> np.ndarray:
        qd = self.cfg.quant_deg
        if qd <= 0:
            return q.copy()
        return np.round(np.degrees(q) / qd) * qd * (math.pi / 180.0)

    def _quantise_tau(self, tau: np.ndarray) -> np.ndarray:
        r = self.cfg.tau_quant
        return tau if r <= 0 else np.round(tau / r) * r

    def read(self) -> dict[str, float]:
        """The latest measurement now: ``q`` rad (quantised), ``tau`` N·m (noisy, delayed and
        quantised as the samples are), ``temp`` °C."""
        q = float(self._quantise(np.array([self._st[K.S_Q]]))[0])
        tau_m = float(self._tau_hist[0]) if self._tau_hist.size else float(self._st[K.S_TAU])
        tau = float(self._quantise_tau(np.array([tau_m + self.cfg.noise_sigma * self._rng_read.standard_normal()]))[0])
        return {"q": q, "tau": tau, "temp": round(float(self._st[K.S_T]), 2)}

    def run(self, traj: Any, progress: Callable[[float], None] | None = None, settle: float = 0.5):
        """Follow ``traj`` to its end plus ``settle`` s; return the :class:`~kukaid.logs.core.AxisLog`.

        If the commanded position now differs from ``traj.q[0]`` the simulator is first reset
        to a standstill at ``traj.q[0]``.  ``progress(done_s)`` is called with the simulated
        seconds done so far.
        """
        from kukaid.logs import AxisLog

        q = np.asarray(traj.q, dtype=float)
        t = np.asarray(traj.t, dtype=float)
        if t.size < 2 or q.size != t.size:
            raise KukaidError(f"trajectory: t and q must have the same length >= 2 (got {t.size}, {q.size})")
        if abs(self._last_cmd - float(q[0])) > 1e-9:
            self.reset(float(q[0]))
        self.follow(traj)
        total = float(t[-1] - t[0]) + float(settle)
        chunk = 10.0
        parts = []
        done = 0.0
        while done < total - 1e-12:
            d = min(chunk, total - done)
            parts.append(self.advance(d))
            done += d
            if progress is not None:
                progress(done)
        data = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
        return AxisLog(time=data["time"], q=data["q"], tau=data["tau"], axes=(self.axis,), q_cmd=data["q_cmd"],
                       temp=data["temp"], tau_ext_true=data["tau_ext_true"], attrs=self.log_attrs(traj))

    def log_attrs(self, traj: Any = None) -> dict[str, Any]:
        """Provenance for a simulated log: truth, seed, experiment kind, trajectory params, config."""
        from kukaid import __version__

        attrs: dict[str, Any] = {
            "source": SOURCE,
            "truth": {**self.cfg.truth_params(), "axis": self.axis},
            "seed": self.seed,
            "sim_config": self.cfg.to_dict(),
            "sample_time": self.cfg.sample_time,
            "kukaid_version": __version__,
        }
        return {**attrs, **trajectory_attrs(traj)}
