"""Capture an axis log from a KR C4 (real or virtual) over KUKAVARPROXY.

Two modes:

``poll``
    Read ``$AXIS_ACT_MEAS`` (all axes in one E6AXIS) and ``$TORQUE_AXIS_ACT[i]`` (one request per
    axis) as fast as the link allows, then the controller's clock ``$ROB_TIMER`` (ms), and
    ``$MOT_TEMP[i]`` once a second.  The controller updates these values once an interpolation
    cycle (12 ms; 4 ms at the fastest), and a poll is usually much faster: each controller sample
    is recorded once (:class:`_NewSample`), stamped with ``$ROB_TIMER``.  A poll whose timer equals
    the previous poll's saw one controller sample throughout (the virtual KR C4 serves the stamp of
    its newest sample); it is new when the stamp is.  Once two polls have seen one stamp, the clock
    stamps samples and only such polls are recorded (a poll during which a sample arrived would pair
    the new position with an old torque).  Otherwise (a controller whose ``$ROB_TIMER`` runs on
    every millisecond) a poll is new when its values differ
    from the last recorded sample, or two cycles after it (a standing axis whose values repeat
    exactly).  A controller that does not answer ``$ROB_TIMER`` is polled without it: samples are
    stamped on the PC with ``time.monotonic()`` at the middle of their exchanges (network jitter
    shows as uneven spacing, recorded, not hidden) and kept when their values change, or two
    cycles after the last one (a sample arriving between the position and the torque requests
    may then add one row that pairs the new position with the old torque).  Held repeats of one
    sample (kukaid 0.1's poll mode logged each 12 ms sample about 100 times; ``kukaid fit`` refuses
    such logs) are never written.
``ring``
    Read blocks of samples taken every interpolation cycle by the KRL ring-buffer logger
    (:mod:`kukaid.krc.krl_logger`); sample times come from the controller's ``$ROB_TIMER`` (ms),
    so no sample is lost to network jitter as long as the PC keeps up with the ring.  Only
    published blocks are read: the samples of the block being filled when capture stops (at most
    ``bs - 1`` cycles) are not in the log.

Read-only: capture never writes a robot variable.  The single exception is ring mode, where it
writes ``KID_RD`` -- the acknowledgement counter of kukaid's own logger -- to hand consumed blocks
back to the SUB program.

The log is written incrementally (:class:`kukaid.logs.writer.AxisLogWriter`), flushed at least
every 0.5 s (``flush_interval``), so a killed capture leaves a readable file holding every sample
up to the last flush.  A dropped connection is survived: the client reconnects with back-off,
the interval without samples is recorded with ``writer.mark_gap`` (dataset ``gaps``), and nothing
before it is lost.  SIGINT and SIGTERM end the capture cleanly.  Achieved rate and request
latency (mean, p99, max) are stored as attributes of the log.
"""
from __future__ import annotations

import math
import signal
import threading
import time
from pathlib import Path
from typing import Any, Callable, Iterable

import numpy as np

from kukaid.errors import ControllerError, KukaidError
from kukaid.krc.kvp import (DEFAULT_PORT, KvpClient, KvpConnectionError, KvpError, KvpProtocolError,
                           KvpValueError, KvpVariableError, parse_e6axis, parse_int, parse_real, parse_string)

_DEG = math.pi / 180.0
MODES = ("poll", "ring")


class _Stop:
    """Stop flag set by SIGINT/SIGTERM (main thread only) or by an external event."""

    def __init__(self, event: threading.Event | None) -> None:
        self.event = event or threading.Event()
        self.signal: int | None = None
        self._old: dict[int, Any] = {}

    def __call__(self) -> bool:
        return self.event.is_set()

    def _handler(self, signum, frame) -> None:
        self.signal = signum
        self.event.set()

    def install(self) -> None:
        if threading.current_thread() is not threading.main_thread():
            return
        for s in (signal.SIGINT, signal.SIGTERM):
            try:
                self._old[s] = signal.signal(s, self._handler)
            except (ValueError, OSError):
                pass

    def restore(self) -> None:
        for s, h in self._old.items():
            try:
                signal.signal(s, h)
            except (ValueError, OSError):
                pass
        self._old.clear()


def _temp_to_c(x: np.ndarray | float, unit: str) -> Any:
    return x - 273.15 if unit == "K" else x


class _Recorder:
    """Buffers samples and hands them to the writer at least every ``flush_interval`` s."""

    def __init__(self, writer, n_axes: int, flush_interval: float) -> None:
        self.writer = writer
        self.a = n_axes
        self.flush_interval = flush_interval
        self.buf: list[tuple[float, np.ndarray, np.ndarray, np.ndarray]] = []
        self.last_flush = time.monotonic()
        self.n = 0
        self.t_last = -math.inf
        self.t_first = math.nan

    def add(self, t: float, q: np.ndarray, tau: np.ndarray, temp: np.ndarray) -> None:
        if t <= self.t_last:
            return
        self.buf.append((t, q, tau, temp))
        self.t_last = t
        if self.n == 0 and len(self.buf) == 1:
            self.t_first = t
        self.maybe_flush()

    def maybe_flush(self) -> None:
        if time.monotonic() - self.last_flush >= self.flush_interval:
            self.flush()

    def flush(self) -> None:
        if self.buf:
            t = np.array([b[0] for b in self.buf])
            q = np.array([b[1] for b in self.buf]).reshape(-1, self.a)
            tau = np.array([b[2] for b in self.buf]).reshape(-1, self.a)
            temp = np.array([b[3] for b in self.buf]).reshape(-1, self.a)
            self.buf = []
            try:
                self.writer.append(t, q=q, tau=tau, temp=temp)
            finally:  # a full disk keeps the leading samples that fit: count those
                self.n = self.writer.n
        self.writer.flush()
        self.last_flush = time.monotonic()


def capture_kvp(output: str | Path, host: str = "127.0.0.1", port: int = DEFAULT_PORT,
                axes: Iterable[int] = (3,), duration: float | None = None, until_interrupt: bool = False,
                mode: str = "poll", progress: Callable[[float], None] | None = None, *,
                timeout: float = 1.0, reconnect_wait: float = 30.0, flush_interval: float = 0.25,
                temp_every: float = 1.0, temp_unit: str = "K", ring_poll: float = 0.03,
                max_consecutive_errors: int = 5, attrs: dict[str, Any] | None = None,
                stop_event: threading.Event | None = None) -> dict[str, Any]:
    """Record an axis log from the KUKAVARPROXY at ``host:port`` into ``output`` (HDF5).

    Parameters
    ----------
    output : path of the HDF5 axis log (created; an existing file is replaced -- the CLI refuses
        that without --force).
    host, port : the proxy.
    axes : axes to record (KUKA numbering; 7..12 are the external axes E1..E6).
    duration : s of capture; with ``until_interrupt`` the capture runs until SIGINT/SIGTERM
        (or ``stop_event``), ``duration`` then being an optional upper bound.
    mode : "poll" or "ring" (see the module docstring).
    progress : optional callable receiving the seconds captured so far.
    timeout : s, limit on every request.
    reconnect_wait : s to keep trying to reconnect after the link drops before giving up (the
        samples recorded so far stay in the file).
    flush_interval : s between writes to disk (at most 0.5 s).
    temp_every : s between motor-temperature reads in poll mode.
    temp_unit : unit of ``$MOT_TEMP`` on the controller, "K" (KSS) or "C"; logged in °C.
    attrs : extra attributes for the log (trajectory, experiment, ...).
    stop_event : a threading.Event that ends the capture when set (for use from a thread).

    Returns
    -------
    dict with n_samples, duration_s, rate_hz, latency_mean_s, latency_p99_s, latency_max_s,
    n_requests, n_reconnects, gaps (list of [t_start, t_end]), stopped_by, and output.
    """
    from kukaid.logs import AxisLogWriter

    axes = tuple(int(a) for a in axes)
    if not axes:
        raise KukaidError("capture: give at least one --axis")
    if len(set(axes)) != len(axes) or not all(1 <= a <= 12 for a in axes):
        raise KukaidError(f"capture: axes must be distinct numbers 1 to 12; got {list(axes)}")
    if mode not in MODES:
        raise KukaidError(f"capture: --mode must be one of {MODES}; got {mode!r}")
    if duration is None and not until_interrupt:
        raise KukaidError("capture: give --duration S or --until-interrupt for a KUKAVARPROXY capture")
    if duration is not None and not duration > 0:
        raise KukaidError(f"capture: --duration must be positive; got {duration}")
    if temp_unit not in ("K", "C"):
        raise KukaidError(f"capture: temp_unit must be 'K' or 'C'; got {temp_unit!r}")
    flush_interval = min(float(flush_interval), 0.5)

    client = KvpClient(host, port, timeout=timeout)
    try:
        client.connect()
        client.ping()
    except KvpError as e:
        client.close()
        raise ControllerError(f"capture: {e}") from None

    timer = mode == "ring" or _has_timer(client)
    stop = _Stop(stop_event)
    info: dict[str, Any] = {
        "source": "kukavarproxy", "kvp_host": host, "kvp_port": int(port), "capture_mode": mode,
        "time_source": "controller $ROB_TIMER" if timer else "pc-monotonic",
        "temp_unit_controller": temp_unit,
    }
    if mode == "poll":
        info["poll_samples"] = "each controller sample once (held repeats not recorded)"
    info.update(attrs or {})
    writer = AxisLogWriter(output, axes, channels=("q", "tau", "temp"), attrs=info, flush_every=1 << 30)
    rec = _Recorder(writer, len(axes), flush_interval)
    latencies: list[float] = []
    gaps: list[list[float]] = []
    result: dict[str, Any] = {}
    stop.install()
    t0 = time.monotonic()
    err: BaseException | None = None
    try:
        loop = _poll_loop if mode == "poll" else _ring_loop
        stopped_by = loop(client, axes, rec, writer, latencies, gaps, stop, t0, duration, progress,
                          reconnect_wait=reconnect_wait, temp_every=temp_every, temp_unit=temp_unit,
                          ring_poll=ring_poll, max_errors=max_consecutive_errors, result=result, timer=timer)
    except BaseException as e:
        err = e
        stopped_by = "error"
    finally:
        stop.restore()
        try:
            rec.flush()
        finally:
            writer.close()
            client.close()
    wall = time.monotonic() - t0
    lat = np.asarray(latencies, dtype=float)
    span = (rec.t_last - rec.t_first) if rec.n > 1 else 0.0
    summary = {
        "output": str(output),
        "n_samples": rec.n,
        "duration_s": float(span),
        "wall_s": float(wall),
        "rate_hz": float((rec.n - 1) / span) if span > 0 else 0.0,
        "latency_mean_s": float(lat.mean()) if lat.size else math.nan,
        "latency_p99_s": float(np.percentile(lat, 99)) if lat.size else math.nan,
        "latency_max_s": float(lat.max()) if lat.size else math.nan,
        "n_requests": int(lat.size),
        "n_reconnects": int(client.n_reconnects),
        "gaps": gaps,
        "stopped_by": stopped_by,
        **result,
    }
    if rec.n == 0:  # a file without a sample records nothing: not left in the way of the next try
        Path(output).unlink(missing_ok=True)
    else:
        _finish_attrs(Path(output), summary)
    if err is not None:
        if isinstance(err, ControllerError):  # KvpError, or a malformed ring block
            kept = f"after {rec.n} samples (kept in {output})" if rec.n else "with no sample recorded, no log written"
            raise ControllerError(f"capture stopped {kept}: {err}") from None
        raise err
    if rec.n < 2:
        where = f"recorded in {output}" if rec.n else "recorded, no log written"
        raise ControllerError(f"capture: only {rec.n} sample(s) {where}; the controller "
                              "answered but no usable samples came back")
    return summary


def _finish_attrs(path: Path, summary: dict[str, Any]) -> None:
    """Store the capture statistics as attributes once the SWMR writer is closed."""
    import h5py

    try:
        with h5py.File(path, "r+") as f:
            for k in ("rate_hz", "latency_mean_s", "latency_p99_s", "latency_max_s", "n_requests",
                      "n_reconnects", "wall_s", "ring_overflows", "ring_blocks", "n_polls", "n_held_polls"):
                if k in summary and summary[k] is not None:
                    f.attrs[k] = summary[k]
            f.attrs["n_gaps"] = len(summary["gaps"])
            f.attrs["stopped_by"] = str(summary["stopped_by"])
            if summary["n_samples"] > 1:
                t = f["time"][()]
                f.attrs["sample_time"] = float(np.median(np.diff(t)))
    except OSError:
        pass  # statistics are a convenience; the samples are already safe on disk


def _done(stop: _Stop, t0: float, duration: float | None) -> str | None:
    if stop():
        return "signal" if stop.signal is not None else "stop-event"
    if duration is not None and time.monotonic() - t0 >= duration:
        return "duration"
    return None


def _reconnect_wait(reconnect_wait: float, t0: float, duration: float | None) -> float:
    """How long to try reconnecting: never past the end of the capture's duration."""
    if duration is None:
        return reconnect_wait
    return min(reconnect_wait, max(t0 + duration - time.monotonic(), 0.0))


def _reconnect(client: KvpClient, stop: _Stop, max_wait: float) -> bool:
    """Reconnect with back-off; False when Ctrl-C / SIGTERM (or the stop event) ended the attempts.

    A stop asked for while the link is down ends the capture as it would with the link up (the
    samples recorded are the log), not as a failure to reconnect."""
    try:
        client.reconnect(max_wait=max_wait, should_stop=stop)
    except KvpConnectionError:
        if stop():
            return False
        raise
    return True


def _recover(client: KvpClient, rec: _Recorder, writer, gaps: list, stop: _Stop, t0: float,
             reconnect_wait: float, err: KvpError) -> None:
    """The link failed: keep what we have, reconnect with back-off, mark the gap."""
    gap_start = rec.t_last if math.isfinite(rec.t_last) else time.monotonic() - t0
    rec.flush()
    client.close()
    if not _reconnect(client, stop, reconnect_wait):
        return  # stopped: the loop ends at its next check; the log ends at its last sample
    gap_end = time.monotonic() - t0
    writer.mark_gap(gap_start, gap_end)
    gaps.append([float(gap_start), float(gap_end)])


def _has_timer(client: KvpClient) -> bool:
    """Does the controller answer ``$ROB_TIMER`` (an INT, ms)?"""
    try:
        parse_int(client.read("$ROB_TIMER"), "$ROB_TIMER")
        return True
    except (KvpVariableError, KvpValueError):
        return False
    except KvpError:
        return False  # the link: the poll loop reconnects; stamped on the PC meanwhile


#: ms a reading of ``$ROB_TIMER`` may lie before the last one without the controller having restarted
#: (the timer counts milliseconds exactly: further back is a restart, not a sample read again)
CLOCK_BACK_MS = 100


class _RobTimer:
    """``$ROB_TIMER`` readings (ms, a 32-bit INT that rolls over) as ms since the capture's first one."""

    def __init__(self) -> None:
        self._first: int | None = None
        self._last: int | None = None
        self._unwrap = 0

    def __call__(self, raw: int) -> float:
        t = int(raw) + self._unwrap
        if self._last is not None and t < self._last - 2**30:  # rolled over
            self._unwrap += 2**31
            t += 2**31
        elif self._last is not None and t < self._last - CLOCK_BACK_MS:
            # a restart: its samples were dropped until the clock caught up, and the rest joined on as one log
            raise ControllerError(f"the controller's clock ($ROB_TIMER) went back by {(self._last - t) / 1000:.3f} s: "
                                  "it restarted, and what it records now is another session; capture again")
        if self._first is None:
            self._first = t
        self._last = t
        return float(t - self._first)


class _NewSample:
    """Which polls bring a new controller sample (see the module docstring, ``poll``).

    ``cycle_ms`` is the controller's interpolation cycle (12 ms): values repeated exactly for two
    cycles are a new sample of a standing axis, not a held one."""

    def __init__(self, cycle_ms: float) -> None:
        self.cycle_ms = float(cycle_ms)
        self.prev_ms: float | None = None  # the timer of the previous poll
        self.kept_ms: float | None = None  # the timer (or PC time, ms) of the last kept sample
        self.kept_values: np.ndarray | None = None
        self.stamps_samples = False  # two polls have seen one stamp: the clock stamps samples, not milliseconds

    def reset(self) -> None:
        """The link dropped: the next poll's timer has no predecessor."""
        self.prev_ms = None

    def __call__(self, stamp_ms: float, values: np.ndarray, stamp_is_sample: bool) -> bool:
        prev, self.prev_ms = self.prev_ms, stamp_ms
        one_sample = stamp_is_sample and prev is not None and prev == stamp_ms
        self.stamps_samples |= one_sample
        if self.kept_ms is None:
            new = True
        elif stamp_ms <= self.kept_ms:
            new = False
        elif self.stamps_samples:  # only a poll that saw one sample throughout: never a mixed row
            new = one_sample
        else:  # new values are a new sample, or exactly repeated ones two cycles on (a standing axis)
            new = not np.array_equal(values, self.kept_values) or stamp_ms - self.kept_ms >= 2 * self.cycle_ms
        if new:
            self.kept_ms, self.kept_values = stamp_ms, values
        return new


def _poll_loop(client: KvpClient, axes, rec: _Recorder, writer, latencies, gaps, stop, t0, duration,
               progress, *, reconnect_wait, temp_every, temp_unit, max_errors, result, timer=True, **_) -> str:
    from kukaid.krc.krl_logger import IPO_MS

    keys = [f"A{a}" if a <= 6 else f"E{a - 6}" for a in axes]
    temp = np.full(len(axes), np.nan)
    next_temp = 0.0
    errors = 0
    last_progress = 0.0
    is_new = _NewSample(IPO_MS)
    clock = _RobTimer()
    gap_start: float | None = None  # controller time of the last sample before a dropped link
    polls = held = 0
    te = time.monotonic()
    while True:
        why = _done(stop, t0, duration)
        if why:
            result.update(n_polls=polls, n_held_polls=held)
            return why
        try:
            ts = time.monotonic()
            pos = parse_e6axis(client.read("$AXIS_ACT_MEAS"), "$AXIS_ACT_MEAS")
            latencies.append(client.last_latency)
            tau = np.empty(len(axes))
            for j, a in enumerate(axes):
                name = f"$TORQUE_AXIS_ACT[{a}]"
                tau[j] = parse_real(client.read(name), name)
                latencies.append(client.last_latency)
            raw = None
            if timer:  # after the values: they were taken at or before this time
                raw = parse_int(client.read("$ROB_TIMER"), "$ROB_TIMER")
                latencies.append(client.last_latency)
            te = time.monotonic()
            if te - t0 >= next_temp:
                for j, a in enumerate(axes):
                    name = f"$MOT_TEMP[{a}]"
                    temp[j] = _temp_to_c(parse_real(client.read(name), name), temp_unit)
                    latencies.append(client.last_latency)
                next_temp = te - t0 + temp_every
            try:
                q = np.array([pos[k] for k in keys]) * _DEG
            except KeyError as e:
                raise KvpValueError(f"$AXIS_ACT_MEAS has no field {e.args[0]} (axis not present)") from None
            polls += 1
            stamp_ms = clock(raw) if raw is not None else (0.5 * (ts + te) - t0) * 1000.0
            if is_new(stamp_ms, np.concatenate([q, tau]), raw is not None):
                t = stamp_ms / 1000.0
                if gap_start is not None:  # the first sample after a dropped link ends its gap
                    rec.flush()
                    writer.mark_gap(gap_start, t)
                    gaps.append([float(gap_start), float(t)])
                    gap_start = None
                rec.add(t, q, tau, temp.copy())
            else:
                held += 1
                rec.maybe_flush()
            errors = 0
        except (KvpConnectionError, KvpProtocolError) as e:
            errors += 1
            if errors > max_errors:
                raise KvpError(f"{errors} consecutive link failures, last: {e}") from None
            is_new.reset()
            if timer:  # the gap is marked in the controller's time, at the first sample after it
                if gap_start is None:
                    gap_start = rec.t_last if math.isfinite(rec.t_last) else 0.0
                rec.flush()
                client.close()
                _reconnect(client, stop, _reconnect_wait(reconnect_wait, t0, duration))
            else:
                _recover(client, rec, writer, gaps, stop, t0, _reconnect_wait(reconnect_wait, t0, duration), e)
            continue
        except (KvpVariableError, KvpValueError) as e:
            raise KvpError(str(e)) from None
        if progress is not None and te - last_progress > 0.1:
            progress(te - t0)
            last_progress = te


def _ring_loop(client: KvpClient, axes, rec: _Recorder, writer, latencies, gaps, stop, t0, duration,
               progress, *, reconnect_wait, temp_unit, ring_poll, max_errors, result, **_) -> str:
    from kukaid.krc.krl_logger import IPO_MS, parse_block, parse_config, slot_name

    def rd(name: str) -> str:
        v = client.read(name)
        latencies.append(client.last_latency)
        return v

    layout = parse_config(parse_string(rd("KID_CFG"), "KID_CFG"))
    missing = [a for a in axes if a not in layout.axes]
    if missing:
        raise KvpError(f"the KRL logger on the controller records axes {list(layout.axes)}, not "
                       f"A{missing[0]}; regenerate it with `kukaid krl-logger --axis ...`")
    a_n = len(layout.axes)
    cols = [layout.axes.index(a) for a in axes]
    # start with the newest block: older blocks belong to an earlier session
    done = parse_int(rd("KID_WR"), "KID_WR")
    client.write("KID_RD", str(done))
    latencies.append(client.last_latency)
    ovf0 = _ovf(client) or 0  # after the hand-back: overflows from before this capture do not count
    clock = _RobTimer()
    last_ms: float | None = None
    errors = 0
    blocks = 0
    last_progress = 0.0
    while True:
        why = _done(stop, t0, duration)
        if why:
            ovf = _ovf(client)
            result.update(ring_blocks=blocks, ring_overflows=None if ovf is None else max(ovf - ovf0, 0))
            return why
        try:
            wr = parse_int(rd("KID_WR"), "KID_WR")
            if wr < done:  # the logger restarted (KID_RD with it): every block it wrote since is new, unread;
                done = 0     # skipped, its ring stayed full and nothing was recorded again (trial 20)
            for k in range(done + 1, wr + 1):
                arr = parse_block(parse_string(rd(slot_name(k, layout)), slot_name(k, layout)), k, layout)
                for row in arr:
                    ms = clock(row[0])
                    t = ms / 1000.0
                    if last_ms is not None and ms - last_ms > 1.5 * IPO_MS:
                        g = [last_ms / 1000.0, t]
                        rec.flush()
                        writer.mark_gap(*g)
                        gaps.append(g)
                    last_ms = ms
                    q = row[1:1 + a_n][cols] * _DEG
                    tau = row[1 + a_n:1 + 2 * a_n][cols]
                    temp = _temp_to_c(row[1 + 2 * a_n:1 + 3 * a_n][cols], temp_unit)
                    rec.add(t, q, tau, temp)
                blocks += 1
            if wr > done:
                client.write("KID_RD", str(wr))
                latencies.append(client.last_latency)
                done = wr
            errors = 0
        except (KvpConnectionError, KvpProtocolError) as e:
            errors += 1
            if errors > max_errors:
                raise KvpError(f"{errors} consecutive link failures, last: {e}") from None
            # unacknowledged blocks stay in the ring: only an overflow loses samples (seen in the stamps)
            rec.flush()
            client.close()
            _reconnect(client, stop, _reconnect_wait(reconnect_wait, t0, duration))
            continue
        except (KvpVariableError, KvpValueError) as e:
            raise KvpError(str(e)) from None
        rec.maybe_flush()
        now = time.monotonic()
        if progress is not None and now - last_progress > 0.1:
            progress(now - t0)
            last_progress = now
        stop.event.wait(ring_poll)


def _ovf(client: KvpClient) -> int | None:
    try:
        return parse_int(client.read("KID_OVF"), "KID_OVF")
    except KvpError:
        return None
