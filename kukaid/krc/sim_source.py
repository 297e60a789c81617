"""The virtual KR C4 as a KUKAVARPROXY variable source.

:class:`SimSource` runs a simulator (:class:`kukaid.sim.VirtualKRC4`, or the six-axis
:class:`kukaid.sim.robot_plant.VirtualRobotKRC4`) in real time on a background thread, through its
public interface (``advance``, ``command``, ``follow``, ``t``), and answers the variables a KR C4
serves: ``$AXIS_ACT_MEAS``, ``$AXIS_ACT``, ``$TORQUE_AXIS_ACT[i]``, ``$MOT_TEMP[i]``, ``$OV_PRO``,
``$ROB_TIMER``, global variables; it emulates the KRL ring-buffer logger
(:mod:`kukaid.krc.krl_logger`) sample for sample and the KRL follower program
(:mod:`kukaid.krc.krl_follower`).  :mod:`kukaid.krc.server` serves it over TCP.
"""
from __future__ import annotations

import math
import threading
import time
from typing import Any

from kukaid.krc.krl_follower import STOP_BY_PC, STOP_OUTSIDE, STOP_STALE
from kukaid.krc.kvp import format_e6axis, format_real, parse_bool, parse_int, parse_real

_DEG = 180.0 / math.pi

#: positions (deg) served for the axes that are not simulated (a KR 6 R700 sixx standing)
HOME_DEG = {1: 0.0, 2: -90.0, 3: 90.0, 4: 0.0, 5: 0.0, 6: 0.0}
#: $ROB_TIMER value when the simulation starts (ms); any boot time would do
TIMER0_MS = 1_000_000
#: bandwidth of the virtual robot program that follows KID_TGT (critically damped), Hz
FOLLOW_HZ = 3.0


def _soft_limits(sim: Any) -> dict[str, str]:
    """``$SOFTN_END[i]``/``$SOFTP_END[i]`` (degrees) of A1-A6: the simulated robot's URDF position limits, or (one
    simulated axis) a KR 6 R700 sixx's ranges."""
    from kukaid.models.limits import AxisLimits

    m = getattr(sim, "model_nominal", None)
    out = {}
    for i in range(1, 7):
        if m is not None and i <= len(m.lowerPositionLimit):
            lo, hi = float(m.lowerPositionLimit[i - 1]), float(m.upperPositionLimit[i - 1])
        else:
            lim = AxisLimits.kr6_r700_sixx(i)
            lo, hi = lim.q_min, lim.q_max
        if math.isfinite(lo) and math.isfinite(hi):  # a continuous joint has none
            out[f"$SOFTN_END[{i}]"], out[f"$SOFTP_END[{i}]"] = format_real(lo * _DEG), format_real(hi * _DEG)
    return out


class SimSource:
    """The virtual KR C4 served over KUKAVARPROXY, advanced in real time by a background thread.

    Parameters
    ----------
    sim : a :class:`kukaid.sim.VirtualKRC4` (or anything with ``advance``, ``command``, ``t``), or
        a simulator of several axes (``sim.axes``, e.g. the six-axis
        :class:`kukaid.sim.robot_plant.VirtualRobotKRC4`: samples are rows over its axes).
    axis : the simulated axis of a one-axis simulator (KUKA numbering); the axes not simulated
        stand still at :data:`HOME_DEG` with zero torque.
    trajectory : optional trajectory to follow from the start (``sim.follow``); otherwise the axis
        holds its position and follows writes of the global ``KID_TGT`` (REAL, degrees).
    speed : simulated seconds per wall-clock second (1.0 = real time).
    ring : optional :class:`kukaid.krc.krl_logger.RingLayout`: emulate the KRL ring-buffer logger.
    follower : optional :class:`kukaid.krc.krl_follower.FollowerConfig`: emulate the KRL follower
        program of ``kukaid run-admittance --backend kvp`` (``KID_TGT`` is followed only while
        ``KID_RUN`` is TRUE, clamped to the window; motion stops when ``KID_HB`` goes stale).
        Without it, every write of ``KID_TGT`` commands the axis directly.
    on_run : optional function called (with no argument, the simulator paused) the first time
        the follower's ``KID_RUN`` turns TRUE: serve-sim puts its simulated hand on the link then,
        so the hand's timing counts from the run, not from how fast a client connects.
    temp_kelvin : serve ``$MOT_TEMP`` in kelvin (as KSS does) rather than °C.
    keep_truth : keep every 12 ms sample (for :meth:`truth`).

    Served: ``$AXIS_ACT_MEAS`` (measured, E6AXIS deg), ``$AXIS_ACT`` (setpoint, E6AXIS deg),
    ``$TORQUE_AXIS_ACT[i]`` (N·m), ``$MOT_TEMP[i]``, ``$SOFTN_END[i]``/``$SOFTP_END[i]`` (the software limit
    switches, deg: the simulated robot's URDF limits, or a KR 6 R700 sixx's), ``$OV_PRO`` (INT, writable), ``$ROB_TIMER``
    (ms), ``$TIMER[i]``-free globals (any name written once becomes readable), ``KID_TGT``.
    """

    def __init__(self, sim: Any, axis: int = 3, trajectory: Any = None, speed: float = 1.0,
                 ring: Any = None, temp_kelvin: bool = True, keep_truth: bool = True,
                 tick: float = 0.004, follower: Any = None, on_run: Any = None) -> None:
        self.sim = sim
        self.axis = int(axis)
        self.axes = tuple(int(a) for a in getattr(sim, "axes", None) or (self.axis,))
        self.speed = float(speed)
        self.tick = float(tick)
        self.temp_kelvin = temp_kelvin
        self.keep_truth = keep_truth
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.globals: dict[str, str] = {"$OV_PRO": "100", "KID_TGT": "0.0", **_soft_limits(sim)}
        self._latest: dict[str, float] | None = None
        self._truth: list[dict[str, Any]] = []
        self.error: BaseException | None = None
        if trajectory is not None:
            import numpy as np

            q0 = (sim.start_position(trajectory) if hasattr(sim, "start_position")
                  else float(np.asarray(trajectory.q, dtype=float).ravel()[0]))
            if hasattr(sim, "reset"):
                sim.reset(q0)  # standstill at the start of the trajectory, as VirtualKRC4.run does
            sim.follow(trajectory)
        self.t0_sim = float(sim.t)
        self._clock: tuple[float, float] | None = None  # (wall, sim) at the start of the real-time run
        self._pending: list[tuple[float, float]] = []  # written targets: (arrival, sim time; q rad)
        self._goal: float | None = None  # the target the robot program is moving to, rad
        self._ref, self._ref_v = 0.0, 0.0  # its motion: position rad, velocity rad/s
        self.follower = follower
        self._on_run = on_run
        if follower is not None:
            self.globals.update({"KID_TGT": format_real(float(sim.q) * _DEG), "KID_HB": "0", "KID_RUN": "FALSE",
                                 "KID_STOP": "0", "KID_CLAMP": "0"})
            self._hb_t = float(sim.t)
        self.ring = ring
        if ring is not None:
            from kukaid.krc.krl_logger import RingLayout

            if not isinstance(ring, RingLayout):
                raise TypeError("ring must be a RingLayout")
            self.globals.update({"KID_CFG": f'"{ring.config_text()}"', "KID_WR": "0", "KID_RD": "0",
                                 "KID_OVF": "0"})
            for i in range(1, ring.nb + 1):
                self.globals[f"KID_B{i}"] = '""'
            self._ring_cur: list[str] = []
            # the program samples once per interpolation cycle (12 ms): every k-th of a faster simulator's samples
            self._ring_every = max(1, round(float(sim.cfg.ipo_period) / float(sim.cfg.sample_time)))
            self._ring_seen = 0
        self._prime()
        self._done = float(sim.t)  # simulated time requested so far (the simulator counts whole servo ticks of it)

    # -- lifecycle ----------------------------------------------------------------------------
    def _prime(self) -> None:
        blk = self.sim.advance(0.012)
        self._ingest(blk)

    def start(self) -> "SimSource":
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="virtual-krc4", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None

    def __enter__(self) -> "SimSource":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    def _run(self) -> None:
        wall0 = time.monotonic()
        sim0 = self._done = float(self.sim.t)
        self._clock = (wall0, sim0)
        try:
            while not self._stop.is_set():
                self._advance_to(sim0 + (time.monotonic() - wall0) * self.speed)
                self._stop.wait(self.tick)
        except BaseException as e:  # surfaced by serve-sim
            self.error = e

    def step(self, seconds: float) -> None:
        """Advance the simulator ``seconds`` of its own time now, as the real-time thread does as
        the wall clock goes on: a source that is not started, stepped by a test on events (one
        12 ms sample per poll), serves the same samples at any speed of the machine."""
        self._advance_to(self._done + float(seconds))

    def _advance_to(self, target: float) -> None:
        """Advance to simulated time ``target``, IPO tick by IPO tick: a written target is taken at
        the first tick after it arrived, as the robot program reads it once per interpolation cycle."""
        ipo = float(self.sim.cfg.ipo_period)
        blocks = []
        with self._lock:
            while self._done < target:
                tick = (math.floor(self._done / ipo + 1e-6) + 1) * ipo
                end = min(target, tick)
                blocks.append(self.sim.advance(end - self._done))
                self._done = end
                if end == tick:
                    self._ipo_tick(tick)
            self._follower_watch()
        for blk in blocks:
            self._ingest(blk)

    def _sim_now(self) -> float:
        """Simulated time corresponding to this moment of the wall clock, s."""
        if self._clock is None:
            return float(self.sim.t)
        wall0, sim0 = self._clock
        return sim0 + (time.monotonic() - wall0) * self.speed

    def _target(self, q: float) -> None:
        """A new position target (rad), taken at the next IPO tick (called with the lock held)."""
        self._pending.append((self._sim_now(), q))

    def _ipo_tick(self, tick: float) -> None:
        """One interpolation cycle of the virtual robot program that follows ``KID_TGT``.

        It takes the latest target written before the tick and moves towards it as a PTP
        follower does, smoothly: a critically damped second-order motion (``FOLLOW_HZ``), so a
        PC whose writes are not locked to the IPO clock (two in one cycle, none in the next) does
        not make the axis jerk.
        """
        due = [q for t, q in self._pending if t <= tick + 1e-9]
        if due:
            self._pending = [(t, q) for t, q in self._pending if t > tick + 1e-9]
            if self._goal is None:
                self._ref, self._ref_v = float(self.sim.q), 0.0
            self._goal = due[-1]
        if self._goal is None:
            return
        h = float(self.sim.cfg.ipo_period)
        w = 2.0 * math.pi * FOLLOW_HZ
        self._ref_v += h * (w * w * (self._goal - self._ref) - 2.0 * w * self._ref_v)
        self._ref += h * self._ref_v
        self.sim.command(self._ref)
        if abs(self._goal - self._ref) < 1e-9 and abs(self._ref_v) < 1e-9:
            self._goal = None  # arrived: the robot holds

    def _follower_watch(self) -> None:
        """The follower program's heartbeat check (called with the lock held)."""
        f = self.follower
        if f is None or self.globals["KID_RUN"] != "TRUE" or self.globals["KID_STOP"] == str(STOP_OUTSIDE):
            return  # not running (the program ended at the start when it found the axis outside its window)
        if (float(self.sim.t) - self._hb_t) * 1000.0 > f.stale_ms:
            self.globals["KID_RUN"] = "FALSE"
            self.globals["KID_STOP"] = str(STOP_STALE)
            self._halt()

    def _halt(self) -> None:
        """The follower stops: targets still waiting are dropped, the motion brakes (without
        coming back: the critically damped motion from speed v settles v / w further on)."""
        self._pending = []
        if self._goal is not None:
            self._goal = self._ref + self._ref_v / (2.0 * math.pi * FOLLOW_HZ)

    def _follow(self, key: str, value: str) -> bool:
        """A write to the follower's globals (called with the lock held); False refuses it."""
        g = self.globals
        try:
            if key == "KID_TGT":
                q, clamped = self.follower.clamp(parse_real(value, key))
                if g["KID_RUN"] == "TRUE" and g["KID_STOP"] != str(STOP_OUTSIDE):
                    self._target(q / _DEG)
                    g["KID_CLAMP"] = str(int(g["KID_CLAMP"]) + int(clamped))
            elif key == "KID_HB":
                parse_int(value, key)
                if value != g["KID_HB"]:
                    self._hb_t = self._sim_now()
            elif key == "KID_RUN":
                run = parse_bool(value, key)
                outside = self.follower.clamp(float(self.sim.q) * _DEG)[1]
                if run and g["KID_RUN"] != "TRUE" and outside:
                    # the program found the axis outside its window when it started and ended: nothing moves
                    g["KID_STOP"] = str(STOP_OUTSIDE)
                elif run and g["KID_RUN"] != "TRUE":
                    self._hb_t = self._sim_now()
                    g["KID_STOP"] = "0"
                    if self._on_run is not None:
                        self._on_run()
                        self._on_run = None
                elif not run and g["KID_RUN"] == "TRUE":
                    g["KID_STOP"] = str(STOP_BY_PC)
                    self._halt()
                value = "TRUE" if run else "FALSE"
            elif key in ("KID_STOP", "KID_CLAMP"):
                return False  # written by the program only
        except Exception:
            return False
        g[key] = value
        return True

    @property
    def sim_time(self) -> float:
        """Simulated seconds since the source was created."""
        return float(self.sim.t) - self.t0_sim

    # -- samples ------------------------------------------------------------------------------
    def _ingest(self, blk: dict[str, Any]) -> None:
        import numpy as np

        t = np.atleast_1d(np.asarray(blk.get("time", []), dtype=float))
        if t.size == 0:
            return
        rows = []
        keys = [k for k in ("time", "q", "tau", "q_cmd", "temp", "tau_ext_true") if k in blk and blk[k] is not None]
        cols = {k: np.asarray(blk[k], dtype=float) for k in keys}
        for i in range(t.size):  # a number per axis: float for one axis, an array over self.axes for several
            rows.append({k: (float(x[i]) if x.ndim == 1 else x[i].copy()) for k, x in cols.items()})
        with self._lock:
            self._latest = rows[-1]
            if self.keep_truth:
                self._truth.extend(rows)
            if self.ring is not None:  # as KID_SAMPLE: once per interpolation cycle, whatever the servo's rate
                for row in rows:
                    if self._ring_seen % self._ring_every == 0:
                        self._ring_sample(row)
                    self._ring_seen += 1

    def _timer_ms(self, t: float) -> int:
        return TIMER0_MS + int(round((t - self.t0_sim) * 1000.0))

    def _value(self, row: dict[str, Any], key: str, axis: int, default: float) -> float:
        """Channel ``key`` of ``axis`` in a sample row; ``default`` for an axis not simulated."""
        if axis not in self.axes or key not in row:
            return default
        v = row[key]
        return float(v) if isinstance(v, float) else float(v[self.axes.index(axis)])

    def _axis_deg(self, row: dict[str, Any], key: str) -> dict[str, float]:
        key = key if key in row else "q"
        out = {f"A{a}": (self._value(row, key, a, 0.0) * _DEG if a in self.axes else v) for a, v in HOME_DEG.items()}
        out.update({f"E{a - 6}": self._value(row, key, a, 0.0) * _DEG for a in self.axes if a > 6})  # external axes
        return out

    def _temp(self, row: dict[str, Any], axis: int) -> float:
        c = self._value(row, "temp", axis, 25.0)
        return c + 273.15 if self.temp_kelvin else c

    def _ring_sample(self, row: dict[str, float]) -> None:
        from kukaid.krc.krl_logger import format_sample

        ring = self.ring
        q = [self._axis_deg(row, "q")[f"A{a}"] for a in ring.axes]
        tau = [self._value(row, "tau", a, 0.0) for a in ring.axes]
        temp = [self._temp(row, a) for a in ring.axes]
        self._ring_cur.append(format_sample(self._timer_ms(row["time"]), q, tau, temp))
        if len(self._ring_cur) >= ring.bs:
            wr = int(self.globals["KID_WR"])
            rd = int(self.globals["KID_RD"])
            if wr - rd < ring.nb:
                k = wr + 1
                self.globals[f"KID_B{(k - 1) % ring.nb + 1}"] = f'"{k}|' + "".join(self._ring_cur) + '"'
                self.globals["KID_WR"] = str(k)
            else:
                self.globals["KID_OVF"] = str(int(self.globals["KID_OVF"]) + 1)
            self._ring_cur = []

    def truth(self) -> dict[str, Any]:
        """Every 12 ms sample taken so far: dict of arrays (time, q, tau, ...), SI, sim time."""
        import numpy as np

        with self._lock:
            rows = list(self._truth)
        keys = rows[0].keys() if rows else ("time", "q", "tau")
        return {k: np.array([r[k] for r in rows], dtype=float) for k in keys}

    # -- variable source ----------------------------------------------------------------------
    def read(self, name: str) -> str | None:
        key = name.upper()
        with self._lock:
            row = self._latest
            if key in self.globals:
                return self.globals[key]
        if row is None:
            return None
        if key == "$AXIS_ACT_MEAS":
            return format_e6axis(self._axis_deg(row, "q"))
        if key == "$AXIS_ACT":
            return format_e6axis(self._axis_deg(row, "q_cmd"))
        if key == "$ROB_TIMER":
            return str(self._timer_ms(row["time"]))
        idx = _index(key, "$TORQUE_AXIS_ACT")
        if idx is not None:
            if not 1 <= idx <= 6:
                return None
            return format_real(self._value(row, "tau", idx, 0.0))
        idx = _index(key, "$MOT_TEMP")
        if idx is not None:
            if not 1 <= idx <= 6:
                return None
            return format_real(self._temp(row, idx), 2)
        return None

    def write(self, name: str, value: str) -> bool:
        key = name.upper()
        if key.startswith("$") and key != "$OV_PRO":
            return False  # system variables are read-only here
        if key in ("KID_RD", "$OV_PRO"):
            try:
                value = str(parse_int(value, key))
            except Exception:
                return False
        if key in ("KID_WR", "KID_OVF", "KID_CFG") and self.ring is not None:
            return False  # written by the logger only
        if self.follower is not None and key in ("KID_TGT", "KID_HB", "KID_RUN", "KID_STOP", "KID_CLAMP"):
            with self._lock:
                return self._follow(key, value)
        if key == "KID_TGT":
            if len(self.axes) > 1:
                return False  # a target of one axis: not for a simulator of several
            try:
                q = parse_real(value, "KID_TGT") / _DEG
            except Exception:
                return False
            with self._lock:
                self._target(q)
        with self._lock:
            self.globals[key] = value
        return True


def _index(key: str, base: str) -> int | None:
    if not key.startswith(base + "[") or not key.endswith("]"):
        return None
    inner = key[len(base) + 1:-1].strip()
    return int(inner) if inner.isdigit() else None
