"""Export a trajectory as a KRL program (``.src`` + ``.dat``) that a KR C4 (KSS 8.x) runs.

The program moves one axis alone, axis-specifically, while the other axes stay where they are
when it starts (their positions are read from ``$AXIS_ACT``):

* the trajectory is reduced to via points: standstills become ``WAIT SEC`` (an exact stop),
  reversals and starts/stops are kept exactly, and every moving stretch is replaced by the
  fewest straight pieces that stay within ``tol`` (degrees) of the commanded position;
* the ``.dat`` holds the via points as ``E6AXIS`` aggregates of the moving axis (degrees) and,
  per point, the axis velocity (``$VEL_AXIS``, % of the maximum), the program override
  (``$OV_PRO``, %; used for speeds below 1 % of the maximum, since ``$VEL_AXIS`` is an integer
  percentage; scaled by the operator's override at the start, never raised above it, given back
  at the end), the acceleration (``$ACC_AXIS``, %) and the dwell after the point (s);
* the ``.src`` moves to the start with a slow exact ``PTP``, then loops over the points with
  ``PTP ... C_PTP`` (approximated) inside a moving stretch and an exact ``PTP`` + ``WAIT SEC``
  at each standstill.  The override only changes at a standstill (after ``WAIT SEC``, an
  advance-run stop), so a constant-velocity plateau runs at one speed.

The percentages assume that the maximum speed and acceleration of the axis on the controller
(``$VEL_AXIS_MA``, ``$ACC_AXIS_MA`` machine data) equal the limits used for the export (the
``.dat`` states them); check them before running, and run in T1 first.  The controller plans
its own ramps: the robot reproduces the plateaus, standstills and reversals of the trajectory
and approximates the curved stretches; the capture logs what it really did.
"""
from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from kukaid import __version__
from kukaid.errors import KukaidError
from kukaid.atomic import write_texts_atomic

_DEG = math.pi / 180.0
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]{0,23}$")
# a module may not be named as a KRL keyword or as what its program declares or calls (KRL ignores case)
_TAKEN = frozenset("""AND B_AND B_EXOR B_NOT B_OR BOOL BRAKE C_DIS C_ORI C_PTP C_VEL CASE CHAR CIRC CIRC_REL CONST
    CONTINUE DECL DEF DEFAULT DEFDAT DEFFCT DELAY DO ELSE END ENDDAT ENDFCT ENDFOR ENDIF ENDLOOP ENDSWITCH ENDWHILE
    ENUM EXIT EXOR EXT EXTFCT FALSE FOR GLOBAL GOTO HALT IF IMPORT INT INTERRUPT IS LIN LIN_REL LOOP NOT OR PRIO PTP
    PTP_REL PUBLIC REAL REPEAT RESUME RETURN SEC SIGNAL STEP STRUC SWITCH THEN TO TRIGGER TRUE UNTIL WAIT WHEN WHILE
    E6AXIS AXIS BAS P I OVR_NOW OVR_USER OVR_SET N_PTS WAIT_START Q_START XP VEL_PCT ACC_PCT OVR_PCT WAIT_S""".split())


_OVERRIDE_NOTE = ("; The speeds are at $OV_PRO 100 %: a lower override scales them; below 1 % of the maximum the",
                  "; program lowers $OV_PRO further (never above the operator's) and gives it back at the end.")


def _override_loop_start() -> list[str]:
    """After the move to the start: the operator's override kept, and at each point the program's
    override scaled by it (changed at standstill only). The points' speeds are at 100 %: a lower
    override scales them, as it does any KRL program's, and the program never raises it (it did, to
    up to 27 % in T1 at 10 %: new-user trial 19); :func:`_override_restore` gives it back at the end."""
    return ["  OVR_USER = $OV_PRO ; the operator's override: the points' speeds are scaled by it, never raised",
            "  OVR_NOW = OVR_USER", "  WAIT SEC WAIT_START", "  FOR I = 1 TO N_PTS",
            "    OVR_SET = (OVR_PCT[I] * OVR_USER) / 100",
            "    IF (OVR_SET < 1) AND (OVR_USER > 0) THEN",
            "      OVR_SET = 1",
            "    ENDIF",
            "    IF OVR_SET <> OVR_NOW THEN",
            "      WAIT SEC 0 ; advance-run stop: change the override at standstill only",
            "      $OV_PRO = OVR_SET", "      OVR_NOW = OVR_SET", "    ENDIF"]


def _override_restore() -> list[str]:
    return ["  $OV_PRO = OVR_USER ; the operator's override back"]



def _program_start(apo_pct: float) -> list[str]:
    """The declarations and set-up of an excitation program, up to reading the start pose into P."""
    return ["  DECL E6AXIS P", "  DECL INT I", "  DECL INT OVR_NOW", "  DECL INT OVR_USER", "  DECL INT OVR_SET",
            "  BAS (#INITMOV, 0)", "  $ADVANCE = 3",
            f"  $APO.CPTP = {int(apo_pct)}", "  ; move to the start point, exact stop", "  P = $AXIS_ACT"]

def via_points(t: np.ndarray, q: np.ndarray, tol: float, still: float = 1e-9) -> list[int]:
    """Indices of the via points: ends of standstills, reversals, and a piecewise-linear fit.

    Parameters
    ----------
    t : (N,) s.   q : (N,) or (N, A) rad: one axis, or several moving together (a reversal of any
        axis is a via point, a piece must fit every axis).
    tol : largest position deviation of the straight pieces, rad.
    still : a sample step smaller than this (rad) counts as standstill.
    """
    q2 = q.reshape(len(q), -1)
    dq = np.diff(q2, axis=0)
    mov = np.abs(dq) > still
    moving = mov.any(axis=1)
    sgn = np.sign(dq) * mov
    # forced breakpoints: changes between standstill and motion, and direction reversals
    forced = {0, len(q) - 1}
    for i in range(1, len(dq)):
        if moving[i] != moving[i - 1] or (moving[i] and np.any(sgn[i] != sgn[i - 1])):
            forced.add(i)
    forced_l = sorted(forced)
    out = [0]
    for a, b in zip(forced_l[:-1], forced_l[1:]):
        if not moving[a]:  # standstill stretch: one piece
            out.append(b)
            continue
        i = a
        while i < b:
            good, step = i + 1, 1  # a piece of one sample always fits
            while good < b:
                cand = min(good + step, b)
                if _fits(t, q2, i, cand, tol):
                    good, step = cand, step * 2
                    continue
                lo, hi = good, cand  # lo fits, hi does not: bisect
                while hi - lo > 1:
                    mid = (lo + hi) // 2
                    if _fits(t, q2, i, mid, tol):
                        lo = mid
                    else:
                        hi = mid
                good = lo
                break
            out.append(good)
            i = good
    return out


def _fits(t: np.ndarray, q: np.ndarray, i: int, j: int, tol: float) -> bool:
    if j <= i + 1:
        return True
    s = ((t[i:j + 1] - t[i]) / (t[j] - t[i]))[:, None]
    line = q[i] + s * (q[j] - q[i])
    return bool(np.max(np.abs(line - q[i:j + 1])) <= tol)


def _speed_split(pct: np.ndarray, dur: np.ndarray) -> tuple[int, np.ndarray]:
    """One override and integer velocities (both 1..100 %) for speeds ``pct`` (% of the maximum).

    ``$VEL_AXIS`` is an integer percentage, so slow speeds need ``$OV_PRO`` below 100 %, and
    the override is shared by a whole stretch between standstills.  Chooses the override that
    minimises the largest timing error of a piece, ``dur * |v / v_programmed - 1|`` (s), so a
    long constant-velocity plateau keeps its speed and a short ramp piece may run fast.
    Speeds below 0.01 % of the maximum cannot be programmed and run at 0.01 %.
    """
    best = (math.inf, 100, np.clip(np.round(pct), 1, 100))
    for ovr in range(100, 0, -1):
        vel = np.clip(np.round(pct * 100.0 / ovr), 1, 100)
        err = float(np.max(dur * np.abs(pct / (vel * ovr / 100.0) - 1.0)))
        if err < best[0] - 1e-9:
            best = (err, ovr, vel)
    return best[1], best[2].astype(int)


def check_krl_name(name: str) -> str:
    """``name`` if it is a KRL module name, else a KukaidError saying what one is."""
    if not _NAME.fullmatch(name):
        raise KukaidError(f"KRL export: module name '{name}' is not a KRL name (letter or _, then letters, "
                          f"digits, _; at most 24 characters)")
    if name.upper() in _TAKEN:
        raise KukaidError(f"KRL export: module name '{name}' is a KRL keyword or a name the program uses; "
                          f"choose another (e.g. kukaid_{name.lower()})")
    return name


def krl_program(traj: Any, name: str | None = None, limits: Any = None, tol_deg: float = 0.005,
                start_vel_pct: int = 10, apo_pct: int = 100, max_points: int = 5000) -> tuple[str, str, dict]:
    """Build the ``.src`` and ``.dat`` texts of a trajectory; returns (src, dat, summary).

    Parameters
    ----------
    traj : a :class:`kukaid.excite.Trajectory` (axis 1 to 6).
    name : module name (KRL identifier, at most 24 characters); default ``kukaid_<kind>``.
    limits : :class:`kukaid.excite.AxisLimits` giving the 100 % speed and acceleration
        (default: the trajectory's own limits, else KR 6 R700 sixx A3).
    tol_deg : largest deviation of the via-point path from the trajectory, degrees.
    start_vel_pct : $VEL_AXIS of the move to the start point, %.   apo_pct : $APO.CPTP, %.
    max_points : refuse programs with more via points (KRL data memory).
    """
    from kukaid.models.limits import AxisLimits

    axis = int(traj.axis)
    if not 1 <= axis <= 6:
        raise KukaidError(f"KRL export: axis A{axis} is not a robot axis (1 to 6)")
    name = check_krl_name(name or f"kukaid_{traj.kind}")
    if limits is None:
        limits = AxisLimits.from_dict(traj.limits) if traj.limits else AxisLimits.kr6_r700_sixx(axis)
    if not tol_deg > 0:
        raise KukaidError(f"KRL export: tolerance must be positive, got {tol_deg}")
    t, q = np.asarray(traj.t), np.asarray(traj.q)
    idx = via_points(t, q, tol_deg * _DEG)
    qdd = np.abs(np.gradient(np.gradient(q, t), t))
    # build points: each motion piece ends at a point; a standstill adds a dwell to the point before
    pts: list[dict[str, Any]] = []
    wait0 = 0.0
    for a, b in zip(idx[:-1], idx[1:]):
        dqab = q[b] - q[a]
        dtab = t[b] - t[a]
        if abs(dqab) <= 1e-9:
            if pts:
                pts[-1]["wait"] += dtab
            else:
                wait0 += dtab
            continue
        pts.append({"i": b, "q": q[b], "v": abs(dqab) / dtab, "dur": dtab, "acc": float(qdd[a:b + 1].max()),
                    "wait": 0.0})
    if not pts:
        raise KukaidError("KRL export: the trajectory does not move")
    if len(pts) > max_points:
        raise KukaidError(f"KRL export: {len(pts)} via points exceed {max_points}; raise the tolerance "
                          f"(now {tol_deg:g} deg) or shorten the trajectory")
    pts[-1]["wait"] = max(pts[-1]["wait"], 0.0)
    # runs: stretches between standstills share one override and one acceleration
    runs: list[list[int]] = [[]]
    for k, p in enumerate(pts):
        runs[-1].append(k)
        if p["wait"] > 0 and k < len(pts) - 1:
            runs.append([])
    errs: list[float] = [0.0]  # speed errors of the pieces of 0.5 s or longer (the plateaus)
    for run in runs:
        pct = np.array([pts[k]["v"] / limits.qd_max * 100.0 for k in run])
        if np.any(pct > 100.0 + 1e-6):
            k = run[int(np.argmax(pct))]
            raise KukaidError(f"KRL export: speed {pts[k]['v']:.4g} rad/s at t = {t[pts[k]['i']]:.3f} s is above the "
                              f"velocity limit {limits.qd_max:.4g} rad/s")
        ovr, vel = _speed_split(np.clip(pct, 1e-6, 100.0), np.array([pts[k]["dur"] for k in run]))
        acc_pct = int(min(100, max(1, math.ceil(1.2 * max(pts[k]["acc"] for k in run) / limits.qdd_max * 100))))
        for k, v in zip(run, vel):
            pts[k].update(vel=int(v), ovr=ovr, accp=acc_pct, v_real=v * ovr / 1e4 * limits.qd_max)
        errs += [abs(pts[k]["v_real"] - pts[k]["v"]) / pts[k]["v"] for k in run if pts[k]["dur"] >= 0.5]
        # approximate inside a run, exact stop at its last point
    n = len(pts)
    ax = f"A{axis}"
    err = max(errs)
    src = "\n".join([
        "&ACCESS RVP",
        "&REL 1",
        f"DEF {name}( )",
        f"; generated by kukaid {__version__}: '{traj.kind}' excitation of {ax}, {n} via points, "
        f"{traj.duration:.2f} s",
        f"; {ax} moves alone; the other axes stay at their positions at program start.",
        f"; Assumes {ax} maximum speed {limits.qd_max / _DEG:.1f} deg/s and acceleration "
        f"{limits.qdd_max / _DEG:.1f} deg/s^2 ($VEL_AXIS_MA/$ACC_AXIS_MA); run in T1 first.",
        *_OVERRIDE_NOTE,
        *_program_start(apo_pct),
        f"  P.{ax} = Q_START.{ax}",
        f"  $VEL_AXIS[{axis}] = {int(start_vel_pct)}",
        "  PTP P",
        *_override_loop_start(),
        f"    $VEL_AXIS[{axis}] = VEL_PCT[I]",
        f"    $ACC_AXIS[{axis}] = ACC_PCT[I]",
        f"    P.{ax} = XP[I].{ax}",
        "    IF WAIT_S[I] > 0.0 THEN",
        "      PTP P",
        "      WAIT SEC WAIT_S[I]",
        "    ELSE",
        "      PTP P C_PTP",
        "    ENDIF",
        "  ENDFOR",
        "  PTP P",
        *_override_restore(),
        "END",
        "",
    ])

    def deg(x: float) -> str:
        return f"{x / _DEG:.5f}"

    lines = [
        "&ACCESS RVP",
        "&REL 1",
        f"DEFDAT {name}",
        f"; point data of {name}.src, generated by kukaid {__version__}; {ax} in degrees",
        f"; limits: {ax} {limits.q_min / _DEG:.2f} .. {limits.q_max / _DEG:.2f} deg, "
        f"{limits.qd_max / _DEG:.1f} deg/s, {limits.qdd_max / _DEG:.1f} deg/s^2; "
        f"via-point tolerance {tol_deg:g} deg; largest speed error of a piece of 0.5 s or more {100 * err:.2f} %",
        f"  DECL INT N_PTS = {n}",
        f"  DECL REAL WAIT_START = {wait0:.3f}",
        f"  DECL E6AXIS Q_START = {{{ax} {deg(q[0])}}}",
        f"  DECL E6AXIS XP[{n}]",
    ]
    lines += [f"  XP[{k}] = {{{ax} {deg(p['q'])}}}" for k, p in enumerate(pts, 1)]
    lines.append(f"  DECL INT VEL_PCT[{n}]")
    lines += [f"  VEL_PCT[{k}] = {p['vel']}" for k, p in enumerate(pts, 1)]
    lines.append(f"  DECL INT OVR_PCT[{n}]")
    lines += [f"  OVR_PCT[{k}] = {p['ovr']}" for k, p in enumerate(pts, 1)]
    lines.append(f"  DECL INT ACC_PCT[{n}]")
    lines += [f"  ACC_PCT[{k}] = {p['accp']}" for k, p in enumerate(pts, 1)]
    lines.append(f"  DECL REAL WAIT_S[{n}]")
    lines += [f"  WAIT_S[{k}] = {p['wait']:.3f}" for k, p in enumerate(pts, 1)]
    lines += ["ENDDAT", ""]
    dat = "\n".join(lines)
    summary = {"name": name, "points": n, "breakpoints": [int(i) for i in idx], "max_speed_error": err, "tolerance_deg": tol_deg,
               "q_deg": [p["q"] / _DEG for p in pts], "time": [float(t[p["i"]]) for p in pts]}
    return src, dat, summary


def export_krl(traj: Any, folder: str | Path, name: str | None = None, **options: Any) -> tuple[Path, Path]:
    """Write ``<name>.src`` and ``<name>.dat`` into ``folder`` (atomically); returns both paths."""
    src, dat, summary = krl_program(traj, name=name, **options)
    folder = Path(folder)
    p_src, p_dat = folder / f"{summary['name']}.src", folder / f"{summary['name']}.dat"
    write_texts_atomic({p_src: src, p_dat: dat})
    return p_src, p_dat


def krl_program_robot(traj: Any, name: str | None = None, tol_deg: float = 0.05, start_vel_pct: int = 10,
                      apo_pct: int = 100, max_points: int = 5000) -> tuple[str, str, dict]:
    """``.src`` and ``.dat`` texts of a trajectory of several axes moving together (e.g. ``fourier``).

    The conventions of :func:`krl_program`, for every axis of ``traj``
    (:class:`kukaid.excite.fourier.RobotTrajectory`, axes 1 to 6): via points within ``tol_deg`` of
    every axis, exact stops and dwells at standstills, ``PTP ... C_PTP`` in between; per point and
    axis the velocity (``VEL_PCT[i, k]``, % of the axis's maximum, so the synchronous PTP moves
    every axis at its own speed) and per run and axis the acceleration (``ACC_PCT``).  The limits are
    the trajectory's own (``traj.limits``); the ``.dat`` states them.
    """
    axes = tuple(int(a) for a in traj.axes)
    if not axes or not all(1 <= a <= 6 for a in axes):
        raise KukaidError(f"KRL export: axes {list(axes)} are not robot axes (1 to 6)")
    name = check_krl_name(name or f"kukaid_{traj.kind}")
    if not tol_deg > 0:
        raise KukaidError(f"KRL export: tolerance must be positive, got {tol_deg}")
    limits = traj.axis_limits()
    qd_max = np.array([lim.qd_max for lim in limits])
    qdd_max = np.array([lim.qdd_max for lim in limits])
    t, q = np.asarray(traj.t), np.asarray(traj.q)
    idx = via_points(t, q, tol_deg * _DEG)
    qdd = np.abs(np.gradient(np.gradient(q, t, axis=0), t, axis=0))
    pts: list[dict[str, Any]] = []
    wait0 = 0.0
    for a, b in zip(idx[:-1], idx[1:]):
        dq, dtab = q[b] - q[a], t[b] - t[a]
        if np.all(np.abs(dq) <= 1e-9):
            if pts:
                pts[-1]["wait"] += dtab
            else:
                wait0 += dtab
            continue
        pts.append({"i": b, "q": q[b], "v": np.abs(dq) / dtab, "dur": dtab, "acc": qdd[a:b + 1].max(axis=0),
                    "wait": 0.0})
    if not pts:
        raise KukaidError("KRL export: the trajectory does not move")
    if len(pts) > max_points:
        raise KukaidError(f"KRL export: {len(pts)} via points exceed {max_points}; raise the tolerance "
                          f"(now {tol_deg:g} deg) or shorten the trajectory")
    runs: list[list[int]] = [[]]
    for k, p in enumerate(pts):
        runs[-1].append(k)
        if p["wait"] > 0 and k < len(pts) - 1:
            runs.append([])
    for run in runs:
        pct = np.array([pts[k]["v"] / qd_max * 100.0 for k in run])  # (points, axes)
        if np.any(pct > 100.0 + 1e-6):
            k, j = np.unravel_index(int(np.argmax(pct / 100.0)), pct.shape)
            p = pts[run[k]]
            raise KukaidError(f"KRL export: A{axes[j]} speed {p['v'][j]:.4g} rad/s at t = {t[p['i']]:.3f} s is above "
                              f"the velocity limit {qd_max[j]:.4g} rad/s")
        # an axis that hardly moves in a piece does not set the override (its timing error is no matter)
        dur = np.array([pts[k]["dur"] for k in run])[:, None] * (pct > 0.01)
        ovr, vel = _speed_split(np.clip(pct, 1e-6, 100.0).ravel(), dur.ravel())
        vel = vel.reshape(pct.shape)
        acc = np.max([pts[k]["acc"] for k in run], axis=0)
        accp = np.clip(np.ceil(1.2 * acc / qdd_max * 100), 1, 100).astype(int)
        for r, k in enumerate(run):
            pts[k].update(vel=vel[r], ovr=ovr, accp=accp)
    n, A = len(pts), len(axes)
    names = [f"A{a}" for a in axes]
    src = [
        "&ACCESS RVP",
        "&REL 1",
        f"DEF {name}( )",
        f"; generated by kukaid {__version__}: '{traj.kind}' excitation of {', '.join(names)} together, {n} via points, "
        f"{traj.duration:.2f} s",
        "; Assumes each axis's maximum speed and acceleration ($VEL_AXIS_MA/$ACC_AXIS_MA) equal the limits",
        f"; in {name}.dat; check them, check the motion for collisions, and run in T1 first.",
        *_OVERRIDE_NOTE,
        *_program_start(apo_pct),
    ]
    src += [f"  P.{x} = Q_START.{x}" for x in names]
    src += [f"  $VEL_AXIS[{a}] = {int(start_vel_pct)}" for a in axes]
    src += ["  PTP P", *_override_loop_start()]
    src += [f"    $VEL_AXIS[{a}] = VEL_PCT[I,{k}]" for k, a in enumerate(axes, 1)]
    src += [f"    $ACC_AXIS[{a}] = ACC_PCT[I,{k}]" for k, a in enumerate(axes, 1)]
    src += [f"    P.{x} = XP[I].{x}" for x in names]
    src += ["    IF WAIT_S[I] > 0.0 THEN", "      PTP P", "      WAIT SEC WAIT_S[I]", "    ELSE", "      PTP P C_PTP",
            "    ENDIF", "  ENDFOR", "  PTP P", *_override_restore(), "END", ""]

    def e6(x: np.ndarray) -> str:
        return "{" + ", ".join(f"{nm} {v / _DEG:.5f}" for nm, v in zip(names, x)) + "}"

    lim_txt = "; ".join(f"A{a} {lim.q_min / _DEG:.2f} .. {lim.q_max / _DEG:.2f} deg, {lim.qd_max / _DEG:.1f} deg/s, "
                        f"{lim.qdd_max / _DEG:.1f} deg/s^2" for a, lim in zip(axes, limits))
    dat = ["&ACCESS RVP", "&REL 1", f"DEFDAT {name}",
           f"; point data of {name}.src, generated by kukaid {__version__}; axes in degrees",
           f"; limits: {lim_txt}", f"; via-point tolerance {tol_deg:g} deg",
           f"  DECL INT N_PTS = {n}", f"  DECL REAL WAIT_START = {wait0:.3f}", f"  DECL E6AXIS Q_START = {e6(q[0])}",
           f"  DECL E6AXIS XP[{n}]"]
    dat += [f"  XP[{k}] = {e6(p['q'])}" for k, p in enumerate(pts, 1)]
    dat.append(f"  DECL INT VEL_PCT[{n},{A}]")
    dat += [f"  VEL_PCT[{k},{j}] = {int(p['vel'][j - 1])}" for k, p in enumerate(pts, 1) for j in range(1, A + 1)]
    dat.append(f"  DECL INT OVR_PCT[{n}]")
    dat += [f"  OVR_PCT[{k}] = {p['ovr']}" for k, p in enumerate(pts, 1)]
    dat.append(f"  DECL INT ACC_PCT[{n},{A}]")
    dat += [f"  ACC_PCT[{k},{j}] = {int(p['accp'][j - 1])}" for k, p in enumerate(pts, 1) for j in range(1, A + 1)]
    dat.append(f"  DECL REAL WAIT_S[{n}]")
    dat += [f"  WAIT_S[{k}] = {p['wait']:.3f}" for k, p in enumerate(pts, 1)]
    dat += ["ENDDAT", ""]
    summary = {"name": name, "points": n, "axes": list(axes), "breakpoints": [int(i) for i in idx],
               "tolerance_deg": tol_deg, "time": [float(t[p["i"]]) for p in pts]}
    return "\n".join(src), "\n".join(dat), summary
