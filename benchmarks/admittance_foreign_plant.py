"""Nobody touching the axis, on a plant kukaid's authors did not write: an elastic joint with
elasto-plastic motor friction and Karnopp stick-slip at the link, under a KR C4-like cascade.

Usage: python benchmarks/admittance_foreign_plant.py [--seeds 0-9] [--duration 60] [--jobs 1] [--json]
                                                     [--vibration SCALE] [--check]

The plant (written here from scratch; nothing of kukaid.sim is used) is one axis the size of the
paper's A3 (a KR 6 R700's), link side throughout::

    motor:  Jm  thd'' = tau_m - tau_g - F_m(z, thd)
    link:   JL  q''   = tau_g + tau_ext + tau_vib - M cos(q + phi_g) - F_L(q', net)
    gear:   tau_g = Kg (th - q) + cg (thd - qd)

* ``F_m``: the elasto-plastic model of Dupont et al. (2002) on the motor / gear input side: a bristle
  deflection ``z`` purely elastic below ``z_ba = beta Fcm/sigma0`` (true stiction, no creep), a smooth
  elasto-plastic transition to ``z_ss = Fcm/sigma0``, ``F_m = sigma0 z + sigma1 z' + Fvm thd``, its
  Coulomb level varying with the motor angle (1 + a sin(N th + psi)), no Stribeck hump;
* ``F_L``: Karnopp stick-slip at the link bearing: stuck (|q'| < DV) while the net torque is below the
  stiction ``Fs_L``, then Coulomb ``Fc_L`` plus viscous ``Fv_L q'``: a breakaway above the sliding
  level, with a drop;
* the measured position is the motor's ($AXIS_ACT_MEAS = motor encoder / gear ratio, quantised
  1e-4 degree), the measured torque the motor torque the servo commands ($TORQUE_AXIS_ACT: one
  12 ms sample late, Gaussian noise, quantised);
* the servo (4 kHz): the 12 ms IPO setpoints ramped linearly, smoothed by a critically damped 2nd-order
  fine interpolator (which also gives the velocity and acceleration feedforward), a position P loop
  on the motor position, a velocity PI loop on the motor velocity, feedforward of the controller's
  model (its inertia and gravity a few percent off; it knows nothing of phi_g);
* ambient micro-vibration: a band-pass noise torque on the link.  While the link sticks (Karnopp: rigid
  below the stiction) it takes the vibration up entirely, so the drawn 0-0.6 N·m leaves the motor
  torque at rest as it is; ``--vibration 3`` (up to 1.8 N·m, the link moving 3-4e-5 rad RMS on some
  seeds, the paper's A6 figure is 5e-5 rad) and ``--vibration 6`` are the stress rows, where the
  vibration makes the link slip at rest.

Ranges drawn from the seed (N·m, rad, s, link side):

===================  =====================================  ===================  ============================
link inertia JL      1.0-2.0 kg·m²                            rotor inertia Jm     0.3-0.9 kg·m² (reflected)
gravity M            15-25 N·m, phase phi_g +-2 degree        gear stiffness Kg    2e4-1e5 N·m/rad, zeta 0.05-0.15
Coulomb total        10-20 N·m, 55-80 % of it motor side      viscous total        5-15 N·m·s/rad, 70-90 % motor
motor bristles       sigma0 5e4-3e5 N·m/rad, beta 0.3-0.7,    motor friction       a 5-15 % of Fcm, N 100-160
                     sigma1 damping ratio 0.3-1.0                                 (period 2 pi/N at the link)
link stiction Fs_L   1.4-2.2 x Fc_L, DV 2e-4 rad/s            servo                Kp 30-50 1/s, Kv 100-180 rad/s,
torque signal        noise 0.2-0.6 N·m, quantum 0.01-0.1,                          Ki 20-50 1/s, model off 3-6 %
                     one sample late                          vibration            0-0.6 N·m RMS at 2-15 Hz
===================  =====================================  ===================  ============================

For every seed: the toolkit's identification on the plant (the default ``excite`` friction, inertia
and pre-sliding experiments, ``fit_axis``, and the pre-sliding experiment again with the larger
reversals the fit names when it warns, as a user would), printed against the truth; then, as
benchmarks/admittance_rest.py does, constant damping at 24 ms and adaptive damping at 12 ms, the
initiation move up (+1 degree, against gravity) and down, two scenarios:

* rest: ``--duration`` s of admittance with nobody there;
* after a guided move: a 15 N·m push (in the move's direction) for 2 s, released; judged from when
  the reference has coasted to a stop (``max(duration / 2, 10)`` s of control in all).

A run passes with drift < 0.05 degree (largest |q - q at the window's start|), no detected cycle in
the window and status completed.  For the guided move also: whether the push was detected and how
far the axis moved (a push never detected is no evidence of safety).

``--check``: the plant alone (servo step overshoot, what holds the link at rest), no admittance.
``--people``: instead, three simulated people per plant (``kukaid.sim.human``: a soft, an ordinary and a
firm grip) guide the axis to a goal, constant D 50 against adaptive damping at 24 and 12 ms: runs
completed, end error, detections after the release, ξ on the true hand torque (paired: mean
difference, its 95 % CI, wins). A person's arm is a function of the link's state, evaluated every
millisecond (``EXT_EVERY``).
"""
from __future__ import annotations

import argparse
import functools
import json
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, replace

import numpy as np

try:  # the inner loop compiled when numba is there (it is in kukaid's environment), else plain Python
    from numba import njit
except ImportError:  # pragma: no cover
    def njit(*a, **k):
        return (lambda f: f) if not (a and callable(a[0])) else a[0]

DEG = math.pi / 180.0
#: s between evaluations of an external torque given as a function (a person's arm)
EXT_EVERY = 0.001


# -- the plant's parameters ----------------------------------------------------------------------------
@dataclass(frozen=True)
class Foreign:
    """One seeded plant (SI, link side)."""

    seed: int = 0
    JL: float = 1.5
    Jm: float = 0.6
    M: float = 20.0
    phi_g: float = 0.0
    Kg: float = 5e4
    zeta_g: float = 0.1
    Fcm: float = 9.0           # motor-side Coulomb (elasto-plastic)
    sigma0: float = 1e5
    beta: float = 0.5
    zeta_b: float = 0.6
    Fvm: float = 8.0
    fa: float = 0.1            # position dependence of Fcm: 1 + fa sin(fn th + fphi)
    fn: float = 120.0
    fphi: float = 0.0
    FcL: float = 5.0           # link-side Karnopp
    FsL: float = 8.0
    FvL: float = 1.5
    DV: float = 2e-4
    Kp: float = 40.0
    Kv: float = 150.0
    Ki: float = 30.0
    ctrl_J: float = 2.1
    ctrl_M: float = 20.0
    tau_max: float = 150.0
    servo_rate: float = 4000.0
    substeps: int = 2
    fine_hz: float = 30.0      # the fine interpolator's corner (critically damped)
    ipo: float = 0.012
    sample_time: float = 0.012
    quant_deg: float = 1e-4
    noise: float = 0.4
    tau_quant: float = 0.05
    tau_delay: int = 1
    vib_rms: float = 0.2       # N·m on the link
    vib_hz: float = 5.0

    @property
    def Fc(self) -> float:
        return self.Fcm + self.FcL

    @property
    def Fv(self) -> float:
        return self.Fvm + self.FvL

    def truth(self) -> dict:
        """What identification would ideally find: the rigid axis's totals."""
        return {"Fc": self.Fc, "Fs": self.Fcm + self.FsL, "Fv": self.Fv, "Izz": self.JL + self.Jm,
                "Mx": self.M * math.cos(self.phi_g), "My": -self.M * math.sin(self.phi_g)}


def draw(seed: int) -> Foreign:
    """The plant of ``seed`` (ranges in the module docstring)."""
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0xF0E16]))
    u = rng.uniform
    JL, Jm = u(1.0, 2.0), u(0.3, 0.9)
    M = u(15.0, 25.0)
    Fc, Fv = u(10.0, 20.0), u(5.0, 15.0)
    sm, sv = u(0.55, 0.8), u(0.7, 0.9)
    FcL = Fc * (1 - sm)
    return Foreign(seed=int(seed), JL=JL, Jm=Jm, M=M, phi_g=u(-2.0, 2.0) * DEG, Kg=float(np.exp(u(np.log(2e4), np.log(1e5)))),
                   zeta_g=u(0.05, 0.15), Fcm=Fc * sm, sigma0=float(np.exp(u(np.log(5e4), np.log(3e5)))), beta=u(0.3, 0.7),
                   zeta_b=u(0.3, 1.0), Fvm=Fv * sv, fa=u(0.05, 0.15), fn=float(rng.integers(100, 161)), fphi=u(-math.pi, math.pi),
                   FcL=FcL, FsL=FcL * u(1.4, 2.2), FvL=Fv * (1 - sv),
                   Kp=u(30.0, 50.0), Kv=u(100.0, 180.0), Ki=u(20.0, 50.0),
                   ctrl_J=(JL + Jm) * (1 + u(0.03, 0.06) * rng.choice((-1, 1))),
                   ctrl_M=M * (1 + u(0.03, 0.06) * rng.choice((-1, 1))),
                   noise=u(0.2, 0.6), tau_quant=float(rng.choice((0.01, 0.02, 0.05, 0.1))),
                   vib_rms=u(0.0, 0.6), vib_hz=u(2.0, 15.0))


# -- the inner loop ------------------------------------------------------------------------------------
# state
TH, OM, Q, V, Z, INT, TAU, RF, RFD, VX, VXD, STUCK, TG = range(13)
NS = 13
# parameters
(PJL, PJM, PM, PPHI, PKG, PCG, PFCM, PS0, PBETA, PS1, PFVM, PFA, PFN, PFPHI, PFCL, PFSL, PFVL, PDV,
 PKP, PKV, PKI, PCJ, PCM, PTMAX, PWF, PVG, PVW) = range(27)
NP = 27


@njit(cache=True)
def _ticks(n, dt, nsub, r0, wn, text, st, p, samp, out_th, out_tau, out_q, out_r):
    """``n`` servo ticks of ``dt`` s (``nsub`` physics steps each) towards the raw setpoints ``r0`` (one a
    tick); records at the ticks ``samp`` (ascending); returns the samples recorded."""
    JL, Jm, M, phi = p[PJL], p[PJM], p[PM], p[PPHI]
    Kg, cg = p[PKG], p[PCG]
    Fcm, s0, beta, s1, Fvm = p[PFCM], p[PS0], p[PBETA], p[PS1], p[PFVM]
    fa, fn, fphi = p[PFA], p[PFN], p[PFPHI]
    FcL, FsL, FvL, DV = p[PFCL], p[PFSL], p[PFVL], p[PDV]
    Kp, Kv, Ki, cJ, cM, tmax = p[PKP], p[PKV], p[PKI], p[PCJ], p[PCM], p[PTMAX]
    wf = p[PWF]
    vg, vw = p[PVG], p[PVW]
    h = dt / nsub
    k = 0
    m = samp.shape[0]
    for i in range(n):
        # fine interpolator: critically damped 2nd order on the raw setpoint
        rf, rfd = st[RF], st[RFD]
        rfdd = wf * wf * (r0[i] - rf) - 2.0 * wf * rfd
        rfd += dt * rfdd
        rf += dt * rfd
        st[RF], st[RFD] = rf, rfd
        # cascade: position P, velocity PI, feedforward of the controller's model
        th, om = st[TH], st[OM]
        vref = rfd + Kp * (rf - th)
        ev = vref - om
        tau = cJ * rfdd + cM * math.cos(rf) + cJ * Kv * ev + st[INT]
        if tau > tmax:
            tau = tmax
        elif tau < -tmax:
            tau = -tmax
        else:
            st[INT] += dt * Ki * cJ * Kv * ev
        st[TAU] = tau
        # ambient vibration: a resonator driven by white noise, its output a torque on the link
        st[VXD] += dt * (-vw * vw * st[VX] - 0.6 * vw * st[VXD] + vg * wn[i])
        st[VX] += dt * st[VXD]
        tvib = st[VX]
        te = text[i]
        for _ in range(nsub):
            th, om, q, v, z = st[TH], st[OM], st[Q], st[V], st[Z]
            tg = Kg * (th - q) + cg * (om - v)
            # motor side: elasto-plastic (Dupont et al. 2002), implicit in z
            fss = Fcm * (1.0 + fa * math.sin(fn * th + fphi))
            zss = fss / s0
            zba = beta * zss
            az = abs(z)
            alpha = 0.0
            if om * z > 0.0 and az > zba:
                if az >= zss:
                    alpha = 1.0
                else:
                    alpha = 0.5 * math.sin(math.pi * (az - 0.5 * (zss + zba)) / (zss - zba)) + 0.5
            zn = (z + h * om) / (1.0 + h * alpha * abs(om) / zss)
            zd = (zn - z) / h
            Fm = s0 * zn + s1 * zd + Fvm * om
            om += h * (tau - tg - Fm) / Jm
            th += h * om
            # link side: Karnopp stick-slip
            net = tg + te + tvib - M * math.cos(q + phi)
            if abs(v) < DV:
                fst = net + JL * v / h
                if abs(fst) <= FsL:
                    FL = fst
                    st[STUCK] = 1.0
                else:
                    FL = FcL if fst > 0 else -FcL
                    st[STUCK] = 0.0
            else:
                FL = (FcL if v > 0 else -FcL) + FvL * v
                st[STUCK] = 0.0
            v += h * (net - FL) / JL
            q += h * v
            st[TH], st[OM], st[Q], st[V], st[Z], st[TG] = th, om, q, v, zn, tg
        while k < m and samp[k] == i:
            out_th[k] = st[TH]
            out_tau[k] = st[TAU]
            out_q[k] = st[Q]
            out_r[k] = r0[i]
            k += 1
    return k


# -- the simulator, as kukaid.robot.SimRobot drives one ---------------------------------------------------
class ForeignKRC4:
    """The plant under its servo, with the interface :class:`kukaid.robot.SimRobot` calls: ``reset``,
    ``follow``, ``command``, ``set_external_torque``, ``advance`` (blocks as ``VirtualKRC4.advance``
    returns them), ``t`` and ``cfg.sample_time``; ``run(traj)`` gives an :class:`~kukaid.logs.AxisLog`."""

    def __init__(self, cfg: Foreign, seed: int = 0, vibration: float | None = None) -> None:
        if vibration is not None:
            cfg = replace(cfg, vib_rms=cfg.vib_rms * vibration)
        self.cfg = cfg
        self.seed = int(seed)
        c = cfg
        self.dt = 1.0 / c.servo_rate
        self.per = int(round(c.sample_time / self.dt))
        Jeff = c.Jm * c.JL / (c.Jm + c.JL)
        p = np.zeros(NP)
        p[PJL], p[PJM], p[PM], p[PPHI] = c.JL, c.Jm, c.M, c.phi_g
        p[PKG], p[PCG] = c.Kg, 2 * c.zeta_g * math.sqrt(c.Kg * Jeff)
        p[PFCM], p[PS0], p[PBETA], p[PS1], p[PFVM] = c.Fcm, c.sigma0, c.beta, 2 * c.zeta_b * math.sqrt(c.sigma0 * c.Jm), c.Fvm
        p[PFA], p[PFN], p[PFPHI] = c.fa, c.fn, c.fphi
        p[PFCL], p[PFSL], p[PFVL], p[PDV] = c.FcL, c.FsL, c.FvL, c.DV
        p[PKP], p[PKV], p[PKI], p[PCJ], p[PCM], p[PTMAX] = c.Kp, c.Kv, c.Ki, c.ctrl_J, c.ctrl_M, c.tau_max
        p[PWF] = 2 * math.pi * c.fine_hz
        w = 2 * math.pi * c.vib_hz
        # white noise of unit variance a tick through s^2 + 0.6 w s + w^2: output RMS = vg sqrt(dt / (2 * 0.6 w * w^2))
        p[PVG] = c.vib_rms / math.sqrt(self.dt / (2 * 0.6 * w * w * w)) if c.vib_rms > 0 else 0.0
        p[PVW] = w
        self._p = p
        w_max = math.sqrt((c.Kg + c.sigma0) / c.Jm + c.Kg / c.JL)
        self.nsub = max(c.substeps, int(math.ceil(w_max * self.dt / 0.25)))
        self._te = 0.0
        self.reset(0.0)

    def reset(self, q0: float = 0.0) -> None:
        """Standstill with the motor (the measured position) at ``q0``: the link hangs in the gear by
        its gravity, friction unloaded, the integrator holding it."""
        c = self.cfg
        q0 = float(q0)
        st = np.zeros(NS)
        G = c.M * math.cos(q0 + c.phi_g)
        st[TH], st[Q] = q0, q0 - G / c.Kg
        st[RF] = q0
        st[TAU] = G
        st[INT] = G - c.ctrl_M * math.cos(q0)
        st[TG] = G
        self._st = st
        self._tick = 0
        self._t_req = 0.0
        self._kt, self._kq = np.array([0.0]), np.array([q0])  # raw setpoint knots (held beyond)
        self._spline = None
        self._t_last_cmd: float | None = None
        self._last_cmd = q0
        self._tau_prev = G
        r = [np.random.default_rng(s) for s in np.random.SeedSequence([self.seed, 0xF0E16]).spawn(2)]
        self._rng_noise, self._rng_vib = r

    @property
    def t(self) -> float:
        return self._tick * self.dt

    def follow(self, traj) -> None:
        t = np.asarray(traj.t, float).ravel()
        q = np.asarray(traj.q, float).ravel()
        self._kt, self._kq = t - t[0] + self.t, q.copy()
        from scipy.interpolate import CubicSpline  # a program's IPO points: a smooth spline through them
        self._spline = CubicSpline(self._kt, self._kq, bc_type="clamped") if t.size >= 3 else None
        self._last_cmd = float(q[-1])
        self._t_last_cmd = None

    def command(self, q_cmd: float) -> None:
        """A streamed setpoint: a ramp from the present raw setpoint over the interval since the last
        (one to four IPO cycles)."""
        now = self.t
        ipo = self.cfg.ipo
        span = ipo if self._t_last_cmd is None else min(max(now - self._t_last_cmd, ipo), 4 * ipo)
        q_now = float(np.interp(now, self._kt, self._kq) if self._spline is None or not self._kt[0] < now < self._kt[-1]
                      else self._spline(now))
        self._kt, self._kq = np.array([now, now + span]), np.array([q_now, float(q_cmd)])
        self._spline = None
        self._last_cmd = float(q_cmd)
        self._t_last_cmd = now

    def set_external_torque(self, tau) -> None:
        self._te = tau

    def advance(self, duration: float) -> dict[str, np.ndarray]:
        self._t_req += float(duration)
        n = max(int(round(self._t_req / self.dt)) - self._tick, 0)
        parts = []
        done = 0
        while done < n:
            # a function of the link's state (a person's arm) is evaluated every millisecond: held over a
            # 12 ms sample, a damped arm on the light link chattered +-60 N·m at the sample rate
            every = max(1, int(round(EXT_EVERY / self.dt)))
            to_next = every - (self._tick % every)
            mm = min(to_next if callable(self._te) else 200_000, n - done)
            te = float(self._te(self.t, float(self._st[Q]), float(self._st[V]))) if callable(self._te) else float(self._te)
            parts.append(self._run(mm, te))
            done += mm
        if not parts:
            return {k: np.zeros(0) for k in ("time", "q", "tau", "q_cmd", "temp", "tau_ext_true", "q_link")}
        if len(parts) == 1:
            return parts[0]
        return {k: np.concatenate([b[k] for b in parts]) for k in parts[0]}

    def _run(self, n: int, te: float) -> dict[str, np.ndarray]:
        c = self.cfg
        t0 = self._tick
        ticks = t0 + np.arange(n)
        tt = ticks * self.dt
        r0 = np.interp(tt, self._kt, self._kq)
        if self._spline is not None:
            inside = (tt > self._kt[0]) & (tt < self._kt[-1])
            r0[inside] = self._spline(tt[inside])
        wn = self._rng_vib.standard_normal(n) if self._p[PVG] else np.zeros(n)
        samp = np.flatnonzero((ticks + 1) % self.per == 0).astype(np.int64)
        m = samp.size
        out = [np.empty(m) for _ in range(4)]
        got = _ticks(n, self.dt, self.nsub, r0, wn, np.full(n, te), self._st, self._p, samp, *out)
        assert got == m
        self._tick += n
        if not np.all(np.isfinite(self._st)):
            raise RuntimeError(f"foreign plant seed {c.seed}: the simulation diverged before t = {self.t:.3f} s")
        th, tau, q, r = out
        if c.tau_delay and m:  # one sample late
            tau = np.concatenate([[self._tau_prev], tau])
            self._tau_prev = float(tau[-1])
            tau = tau[:-1]
        tau = tau + c.noise * self._rng_noise.standard_normal(m)
        if c.tau_quant > 0:
            tau = np.round(tau / c.tau_quant) * c.tau_quant
        qm = np.round(th / (c.quant_deg * DEG)) * (c.quant_deg * DEG) if c.quant_deg > 0 else th.copy()
        return {"time": (t0 + 1 + samp) * self.dt, "q": qm, "tau": tau, "q_cmd": r, "temp": np.full(m, 30.0),
                "tau_ext_true": np.full(m, te), "q_link": q}

    def run(self, traj, settle: float = 0.5):
        """Follow ``traj`` from a standstill at its start to its end plus ``settle`` s: the AxisLog a
        capture gives."""
        from kukaid.logs import AxisLog

        t = np.asarray(traj.t, float)
        self.reset(float(np.asarray(traj.q)[0]))
        self.follow(traj)
        d = self.advance(float(t[-1] - t[0]) + settle)
        attrs = {"source": "foreign-plant", "seed": self.seed, "sample_time": self.cfg.sample_time,
                 "experiment": str(getattr(traj, "kind", "unknown"))}
        if getattr(traj, "params", None) is not None:
            attrs["trajectory"] = json.loads(json.dumps(traj.params, default=str))
        return AxisLog(time=d["time"], q=d["q"], tau=d["tau"], axes=(3,), q_cmd=d["q_cmd"],
                       tau_ext_true=d["tau_ext_true"], attrs=attrs)


# -- identification, as a user would run it --------------------------------------------------------------
@functools.lru_cache(maxsize=4)
def fitted_params(seed: int, vibration: float | None) -> dict:
    """The parameter file ``kukaid fit`` gives on the plant of ``seed``: the default friction, inertia and
    pre-sliding experiments captured on it, fitted together; with the larger reversals the fit names
    when it warns an element saturates only at the experiment's largest deflection."""
    from kukaid import excite
    from kukaid.identify import fit_axis

    cfg = draw(seed)
    logs = [ForeignKRC4(cfg, seed=1000 + 3 * seed + k, vibration=vibration).run(traj)
            for k, traj in enumerate((excite.friction(), excite.inertia(), excite.presliding()))]
    fitted = fit_axis(friction=[logs[0]], inertia=[logs[1]], presliding=logs[2])
    fitted["metrics"]["first_warnings"] = list(fitted["metrics"].get("warnings", []))
    if any("--reversals-deg" in w for w in fitted["metrics"]["warnings"]):  # as the warning says: larger reversals
        wide = excite.presliding(reversals=tuple(math.radians(r) for r in (0.1, 0.05, 0.025, 0.0125)))
        first = fitted["metrics"]["first_warnings"]
        fitted = fit_axis(friction=[logs[0]], inertia=[logs[1]],
                          presliding=ForeignKRC4(cfg, seed=1000 + 3 * seed + 2, vibration=vibration).run(wide))
        fitted["metrics"]["first_warnings"] = first
        fitted["metrics"]["wide_reversals"] = True
    return fitted


def identification_row(seed: int, vibration: float | None) -> dict:
    """The fit against the plant's truth (the rigid axis's totals)."""
    c = draw(seed)
    f = fitted_params(seed, vibration)
    tr = c.truth()
    fr, inn, ms = f["friction"], f["inertial"], f["maxwell_slip"]
    return {"seed": seed, "Fc": fr["Fc"], "Fc_true": tr["Fc"], "Fs": fr.get("Fs", fr["Fc"]), "Fs_true": tr["Fs"],
            "Fv": fr["Fv"], "Fv_true": tr["Fv"], "Izz": inn["Izz"], "Izz_true": tr["Izz"],
            "Mx": inn["Mx"], "Mx_true": tr["Mx"], "My_true": tr["My"],
            "sum_W": float(sum(ms["W"])), "W": [float(w) for w in ms["W"]], "k": [float(k) for k in ms["k"]],
            "k_rest_true": c.sigma0 + c.Kg, "breakaway_true": c.Fcm + c.FsL,
            "wide_reversals": bool(f["metrics"].get("wide_reversals", False)),
            "warnings": list(f["metrics"].get("warnings", [])),
            "first_warnings": list(f["metrics"].get("first_warnings", []))}


# -- the admittance runs, as benchmarks/admittance_rest.py judges them -------------------------------------
Q0 = 30.0 * DEG
SCENARIOS = ("rest", "after a guided move")
DAMPINGS = (("constant", 0.024), ("adaptive", 0.012))


def one(args) -> dict:
    """One run: (seed, damping, cycle, move deg, scenario, duration s, vibration scale, dump dir)."""
    from kukaid.control.loop import PHASE_ADMITTANCE, LoopConfig, default_threshold, run_admittance
    from kukaid.params import model_from_params
    from kukaid.robot import SimRobot
    from kukaid.sim.operator import PushOperator  # the open-loop push of admittance_rest.py (no plant in it)

    seed, damping, cycle, move, scenario, duration, vibration, dump = args
    params = fitted_params(seed, vibration)
    op, t_from = None, 0.0
    if scenario == "after a guided move":
        op = PushOperator(amplitude=15.0 * move, t_start=2.0, duration=2.0, ramp=0.3)
        duration = max(duration / 2, 10.0)
    model = model_from_params(params)
    cfg = LoopConfig(damping=damping, cycle=cycle, duration=duration, init_move=math.radians(move),
                     threshold=default_threshold(model))
    row = {"seed": seed, "damping": damping, "cycle": cycle, "move": move, "scenario": scenario, "duration": duration,
           "threshold": cfg.threshold}
    try:
        run = run_admittance(SimRobot(ForeignKRC4(draw(seed), seed=seed, vibration=vibration), Q0, op), model, cfg)
    except Exception as e:  # refused before anything moved, or the plant diverged: a failure, said
        return {**row, "drift_deg": math.nan, "detected_cycles": 0, "rest_threshold_max": math.nan,
                "stick_slip_margin": 0.0, "passes": False, "status": f"error: {type(e).__name__}: {e}"[:300],
                "push_detected": None, "push_moved_deg": math.nan, "first_detection": None, "warnings": []}
    d = run.data
    adm = d["phase"] == PHASE_ADMITTANCE
    push_detected, push_moved = None, math.nan
    if op is not None:
        during = adm & (d["time"] >= op.t_start) & (d["time"] <= op.t_end + 0.5)
        push_detected = bool(d["detected"][during].any())
        i_a = np.flatnonzero(adm)
        if i_a.size:
            push_moved = float(np.degrees(np.max(np.abs(d["q"][adm] - d["q"][i_a[0]]))))
        standing = (d["time"] > op.t_end) & (d["sigma_dot"] == 0.0)
        if standing.any():  # judged from when the reference stands after the release (the move has ended)
            t_from = float(d["time"][standing][0])
        else:
            t_from = math.inf
    w = adm & (d["time"] >= t_from)
    first = None
    if not w.any():
        drift, n_det = math.nan, 0
    else:
        i0 = np.flatnonzero(w)[0]
        drift = float(np.degrees(np.max(np.abs(d["q"][w] - d["q"][i0]))))
        n_det = int(d["detected"][w].sum())
        if n_det:
            j = np.flatnonzero(w & d["detected"])[0]
            first = {"t": float(d["time"][j]), "since_window": float(d["time"][j] - d["time"][i0]),
                     "gamma_r": float(d["gamma_r"][j]), "gamma_p": float(d["gamma_p"][j]), "tau": float(d["tau"][j]),
                     "dynamic": bool(d["dynamic"][j])}
    passes = bool(drift < 0.05 and n_det == 0 and run.status == "completed")
    if dump and not passes:
        os.makedirs(dump, exist_ok=True)
        name = f"seed{seed}_{damping}_{'up' if move > 0 else 'down'}_{scenario.replace(' ', '_')}.npz"
        np.savez_compressed(os.path.join(dump, name), t_from=t_from, **d)
    return {**row, "t_from": t_from, "drift_deg": drift, "detected_cycles": n_det,
            "rest_threshold_max": run.metrics["rest_threshold_max"], "stick_slip_margin": run.metrics["stick_slip_margin"],
            "passes": passes, "status": run.status, "push_detected": push_detected, "push_moved_deg": push_moved,
            "first_detection": first, "warnings": list(run.metrics.get("warnings", []))}


GRIPS = ("soft", "ordinary", "firm")


def person(args) -> dict:
    """One person (:func:`kukaid.sim.human.make_human`, seed ``7000 + 10 plant seed + k``, grip ``grip``)
    moving the axis to a goal on the plant of ``seed``: (seed, k, grip, damping, cycle)."""
    from kukaid.control.loop import LoopConfig, run_admittance
    from kukaid.control.metrics import window_metrics
    from kukaid.params import model_from_params
    from kukaid.robot import SimRobot
    from kukaid.sim.operator import make_operator

    seed, k, grip, damping, cycle = args
    cfg = LoopConfig(damping=damping, D=50.0, cycle=cycle, duration=13.0)
    op = make_operator("human", 7000 + 10 * seed + k, Q0 + cfg.init_move, t_start=cfg.init_time + cfg.init_rest + 0.8,
                       grip=grip)
    run = run_admittance(SimRobot(ForeignKRC4(draw(seed), seed=seed), Q0, op), model_from_params(fitted_params(seed, None)),
                         cfg)
    d = run.data
    t0 = float(d["time"][0])
    t_rel = op.t_release if math.isfinite(op.t_release) else math.inf
    m = window_metrics(d, op.p.t_grasp - t0, min(t_rel + 1.0 - t0, float(d["time"][-1])), 0.05)
    after = d["time"] > t_rel - t0 + op.p.release_time + 0.05
    return {"seed": seed, "grip": grip, "damping": damping, "cycle": cycle, "status": run.status,
            "xi_true": float(m["xi_true"]), "end_error": float(abs(d["q"][-1] - op.p.goal) / abs(op.p.goal - op.p.q_start)),
            "after_release": int(np.sum(d["detected"][after])) if math.isfinite(t_rel) else 0}


def people(seeds: list[int], jobs: int, as_json: bool) -> None:
    """``--people``: three people (soft, ordinary, firm grips) on each plant, constant D 50 and adaptive
    damping, at 24 and 12 ms: can they guide it, at what effort (ξ on the true hand torque), and does
    anything move after they let go."""
    from scipy import stats

    plan = [(s, k, g, damping, cycle) for s in seeds for k, g in enumerate(GRIPS)
            for damping in ("constant", "adaptive") for cycle in (0.024, 0.012)]
    if jobs > 1:
        with ProcessPoolExecutor(jobs) as ex:
            rows = list(ex.map(person, plan, chunksize=12))
    else:
        rows = [person(p) for p in plan]
    summary = []
    for cycle in (0.024, 0.012):
        by = {dmp: sorted((r for r in rows if r["cycle"] == cycle and r["damping"] == dmp),
                          key=lambda r: (r["seed"], r["grip"])) for dmp in ("constant", "adaptive")}
        diff = np.array([a["xi_true"] - c["xi_true"] for a, c in zip(by["adaptive"], by["constant"])])
        half = float(stats.t.ppf(0.975, diff.size - 1) * np.std(diff, ddof=1) / math.sqrt(diff.size))
        for dmp, rs in by.items():
            ee = np.array([r["end_error"] for r in rs])
            summary.append({"cycle": cycle, "damping": dmp, "runs": len(rs),
                            "completed": sum(r["status"] == "completed" for r in rs),
                            "end_error_median": float(np.median(ee)), "end_error_max": float(ee.max()),
                            "after_release_runs": sum(r["after_release"] > 0 for r in rs),
                            "xi_true_mean": float(np.mean([r["xi_true"] for r in rs]))})
        summary[-1].update(adaptive_minus_constant=float(diff.mean()), ci=[float(diff.mean() - half), float(diff.mean() + half)],
                           wins=int(np.sum(diff < 0)))
    if as_json:
        json.dump({"seeds": seeds, "summary": summary, "runs": rows}, sys.stdout, default=float)
        print()
        return
    print(f"people on the foreign plant: seeds {seeds[0]}-{seeds[-1]}, a soft, an ordinary and a firm grip each")
    print(f"{'cycle':>6} {'damping':>9} | {'completed':>9} | {'end error med / max':>19} | {'after a release':>15} | "
          f"{'mean xi (true)':>14} | adaptive - D 50 on xi: mean [95 % CI], wins")
    for r in summary:
        vs = (f"{r['adaptive_minus_constant']:+.2f} [{r['ci'][0]:+.2f}, {r['ci'][1]:+.2f}], {r['wins']}/{r['runs']}"
              if "wins" in r else "")
        print(f"{1000 * r['cycle']:4.0f} ms {r['damping']:>9} | {r['completed']:4d}/{r['runs']:<4d} | "
              f"{100 * r['end_error_median']:7.1f} / {100 * r['end_error_max']:5.1f} % | {r['after_release_runs']:10d} runs | "
              f"{r['xi_true_mean']:14.2f} | {vs}")


def check(seeds: list[int]) -> None:
    """The plant alone: a 0.2 and a 1 degree step's overshoot, and what holds it at rest."""
    for s in seeds:
        c = draw(s)
        out = []
        for step in (0.2, 1.0):
            sim = ForeignKRC4(c, seed=s)
            sim.reset(Q0)
            sim.advance(0.5)
            sim.command(Q0 + step * DEG)
            d = sim.advance(2.0)
            dq = np.degrees(d["q"] - Q0)
            out.append(f"step {step:g} deg: overshoot {100 * (dq.max() - step) / step:4.1f} %, end {dq[-1] - step:+.4f} deg")
        G = c.M * math.cos(Q0 + c.phi_g)
        print(f"seed {s}: {'; '.join(out)}; gravity at 30 deg {G:.1f} N·m, breakaway Fcm + Fs_L {c.Fcm + c.FsL:.1f} N·m "
              f"({'holds' if c.Fcm + c.FsL > G else 'does not hold'} the link unpowered), gear mode "
              f"{math.sqrt(c.Kg * (1 / c.Jm + 1 / c.JL)) / 2 / math.pi:.0f} Hz, link {math.sqrt(c.Kg / c.JL) / 2 / math.pi:.0f} Hz")


def _seeds(text: str) -> list[int]:
    if "-" in text:
        lo, hi = (int(x) for x in text.split("-"))
        return list(range(lo, hi + 1))
    return [int(x) for x in text.split(",")]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0-9", help="plant seeds, a range A-B or a list [0-9]")
    ap.add_argument("--duration", type=float, default=60.0, help="seconds at rest [60]")
    ap.add_argument("--vibration", type=float, help="scale of every plant's ambient vibration [1: its own draw]")
    ap.add_argument("--jobs", type=int, default=1, help="worker processes [1]")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--check", action="store_true", help="the plants alone: servo steps, what holds them; no admittance")
    ap.add_argument("--dump", help="write each failing run's data (run.data) to DIR/*.npz")
    ap.add_argument("--people", action="store_true", help="people (simulated arms) guiding each plant instead")
    a = ap.parse_args()
    seeds = _seeds(a.seeds)
    if a.check:
        check(seeds)
        return
    if a.people:
        people(seeds, a.jobs, a.json)
        return
    t = time.perf_counter()
    plan = [(s, damping, cycle, move, scenario, a.duration, a.vibration, a.dump)
            for s in seeds for damping, cycle in DAMPINGS for move in (1.0, -1.0) for scenario in SCENARIOS]
    if a.jobs > 1:
        with ProcessPoolExecutor(a.jobs) as ex:
            ident = list(ex.map(identification_row, seeds, [a.vibration] * len(seeds)))
            rows = list(ex.map(one, plan, chunksize=8))  # a seed's runs together: one fit per worker
    else:
        ident = [identification_row(s, a.vibration) for s in seeds]
        rows = [one(p) for p in plan]
    summary = []
    for scenario in SCENARIOS:
        for damping, _ in DAMPINGS + (("both", None),):
            rs = [r for r in rows if r["scenario"] == scenario and damping in (r["damping"], "both")]
            summary.append({"scenario": scenario, "damping": damping, "runs": len(rs), "pass": sum(r["passes"] for r in rs),
                            "drift_max_deg": max((r["drift_deg"] for r in rs if r["drift_deg"] == r["drift_deg"]), default=math.nan),
                            "detected_runs": sum(r["detected_cycles"] > 0 for r in rs),
                            "threshold_max": max(r["threshold"] for r in rs),
                            "rest_threshold_max": max((r["rest_threshold_max"] for r in rs if r["rest_threshold_max"] == r["rest_threshold_max"]), default=math.nan),
                            "stick_slip_runs": sum(r["stick_slip_margin"] > 0 for r in rs),
                            "push_undetected": sum(r["push_detected"] is False for r in rs),
                            "push_moved_min_deg": min((r["push_moved_deg"] for r in rs if r["push_detected"] is not None
                                                       and r["push_moved_deg"] == r["push_moved_deg"]), default=math.nan)})
    doc = {"seeds": seeds, "duration": a.duration, "vibration": a.vibration, "identification": ident,
           "summary": summary, "runs": rows, "seconds": time.perf_counter() - t}
    if a.json:
        json.dump(doc, sys.stdout, default=float)
        print()
        return
    print(f"foreign plant (elastic joint, elasto-plastic + Karnopp friction, KR C4-like cascade): seeds {seeds[0]}-{seeds[-1]}, "
          f"{a.duration:g} s at rest, vibration {'each plant' + chr(39) + 's' if a.vibration is None else f'x {a.vibration:g}'}")
    print("identification (fitted / truth of the rigid axis; sum W against Fcm + Fc_L, what a stop holds):")
    for r in ident:
        c = draw(r["seed"])
        print(f"  seed {r['seed']}: Fc {r['Fc']:5.2f}/{r['Fc_true']:5.2f}  Fs {r['Fs']:5.2f}/{r['Fs_true']:5.2f}  "
              f"Fv {r['Fv']:5.2f}/{r['Fv_true']:5.2f}  Izz {r['Izz']:.2f}/{r['Izz_true']:.2f}  Mx {r['Mx']:5.2f}/{r['Mx_true']:5.2f}  "
              f"sum W {r['sum_W']:5.2f}/{c.Fc:5.2f} ({len(r['W'])} el., k {min(r['k']):.2g}-{max(r['k']):.2g} vs "
              f"sigma0+Kg {r['k_rest_true']:.2g})" + ("  [refit with wider reversals]" if r["wide_reversals"] else "")
              + "".join(f"\n      warning: {w[:150]}" for w in r["warnings"]))
    print(f"{'scenario':>20} {'damping':>9} | {'pass':>7} | {'drift max':>9} | {'runs w/ det':>11} | {'thr':>5} | "
          f"{'thr at rest max':>15} | {'stick-slip':>10} | {'push undetected':>15} | {'push moved min':>14}")
    for r in summary:
        push = (f"{r['push_undetected']:15d} | {r['push_moved_min_deg']:10.3f} deg" if r["scenario"] != "rest"
                else f"{'':>15} | {'':>14}")
        print(f"{r['scenario']:>20} {r['damping']:>9} | {r['pass']:3d}/{r['runs']:<3d} | {r['drift_max_deg']:7.4f} ° | "
              f"{r['detected_runs']:11d} | {r['threshold_max']:5.2f} | {r['rest_threshold_max']:11.2f} N·m | "
              f"{r['stick_slip_runs']:10d} | {push}")
    for r in rows:
        if not r["passes"] or r["push_detected"] is False:
            f = r["first_detection"]
            print(f"  {'fails' if not r['passes'] else 'push undetected'}: seed {r['seed']} {r['damping']} move {r['move']:+g} "
                  f"{r['scenario']}: drift {r['drift_deg']:.4f} deg, {r['detected_cycles']} cycles detected"
                  + (f", first {f['since_window']:.2f} s into the window (t {f['t']:.2f} s, Γr {f['gamma_r']:+.2f} N·m)" if f else "")
                  + ("" if r["status"] == "completed" else f"; {r['status'][:200]}"))
    total = sum(r["passes"] for r in rows), len(rows)
    print(f"all: {total[0]}/{total[1]} runs pass ({doc['seconds']:.0f} s)")


if __name__ == "__main__":
    main()
