"""Pre-processing of an axis log for identification: zero-phase low-pass, differentiation, modes.

What :func:`preprocess` does, in order (the paper's recipe, section 2, made explicit):

0. **Time base.**  A controller samples at a fixed rate, but a PC that records the samples may
   stamp each when it arrives; differentiating on such stamps turns their jitter into velocity
   (±3 ms on 12 ms stamps fitted Fv 12 % low).  The even grid over the same span replaces the
   stamps when the positions are smoother on it; positions truly sampled at uneven times are
   interpolated onto it (:func:`evenly_sampled`).  ``Prepared.settings["time_base"]`` says which.
1. **Low-pass, zero-phase.**  Position and torque are filtered with the same Butterworth filter
   run forward and backward (applied as its exact zero-phase response, see :func:`lowpass`), so the filter adds no delay and the
   torque and the motion derived from the position stay aligned.  The paper uses 3rd order at
   5 Hz for the KR C4 (83 Hz).  Defaults adapt to the sample rate ``fs``
   (see :func:`filter_defaults`): up to 250 Hz: order 3, 5 Hz (the paper); above: order 4,
   ``fs / 10`` (the EMPS recipe: 100 Hz at 1 kHz).  The cut-off must lie below 0.9 * Nyquist.
2. **Differentiation** of the *filtered* position by central differences (``numpy.gradient``),
   the paper's and the EMPS recipe (``diff="central"``, the default).  ``diff="spectral"`` gives
   the exact derivatives of the filtered signal instead (multiplication by j*2*pi*f in the FFT
   that filters; uniform sampling at the median interval assumed); central differences read a
   5 Hz component 2.3 % low in velocity and 4.6 % low in acceleration at 12 ms.
3. **Edges trimmed.**  ``edge`` samples are dropped at both ends (default ``ceil(5 fs / cutoff)``,
   five periods of the cut-off: 50 samples at 1 kHz / 100 Hz, 84 at 83 Hz / 5 Hz), where the
   zero-phase filter's start-up transients live.  Optional decimation by an integer factor
   follows (the rows kept are reported in ``Prepared.rows``).
4. **Modes.**  Quasi-static samples: ``|qd| < qd_thr`` (default 0.0017 rad/s, the paper's
   0.1 deg/s).  Dynamic samples: ``|qd| >= qd_thr`` **and** at least ``reversal_window``
   seconds away from any velocity reversal, start or stop (default ``1.2 / cutoff``: 0.24 s at
   5 Hz; 0 when that is a dozen samples or fewer, see :func:`default_reversal_window`).  Around a reversal (and a start from standstill) the joint passes through pre-sliding
   (Maxwell-slip, not Stribeck) and the filtered torque smears the friction jump (2 Fc, or Fs
   at a start) over about that time (a 5 Hz zero-phase step
   response stays more than 1 % off within 0.23 s of the step), so the sliding model does not
   hold there; these samples are excluded on purpose rather than fitted badly.
   Acceleration phases are *kept* in the dynamic set: the dynamic model carries ``Izz qdd``.
   For the paper's staged friction method, which needs constant velocity, ``Prepared.plateau``
   marks dynamic samples with ``|qdd| < qdd_tol`` (default 0.05 rad/s²: an inertia of 2 kg·m²
   then adds under 0.1 N·m).

All numbers SI: s, rad (m), rad/s, rad/s², N·m (N).
"""
from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, field, replace
from typing import Any, Collection, Sequence

import numpy as np

from kukaid.errors import FitError

#: Paper's mode-switching threshold, eq. (12): 0.1 deg/s in rad/s.
QD_THR_DEFAULT = 0.0017
QDD_TOL_DEFAULT = 0.05


def filter_defaults(fs: float) -> dict[str, float]:
    """Default filter settings for a sample rate ``fs`` (Hz).

    Returns ``{"order", "cutoff", "edge", "reversal_window"}``: order 3 and 5 Hz up to 250 Hz
    (the paper, KR C4 at 83 Hz), else order 4 and ``fs/10`` Hz (EMPS at 1 kHz: 100 Hz);
    ``edge = ceil(5 fs / cutoff)`` samples; ``reversal_window = 1.2 / cutoff`` s.
    """
    if fs <= 250.0:
        order, cutoff = 3, 5.0
    else:
        order, cutoff = 4, fs / 10.0
    return {"order": order, "cutoff": cutoff, "edge": int(math.ceil(5.0 * fs / cutoff)),
            "reversal_window": default_reversal_window(fs, cutoff)}


#: a friction jump smeared over at most this many samples by the filter is not excluded
SMEAR_SAMPLES_KEPT = 12.5


def default_reversal_window(fs: float, cutoff: float) -> float:
    """Default exclusion around reversals, s: ``1.2 / cutoff`` (the zero-phase filter smears a
    friction jump over about that time), or 0 when that is at most a dozen samples (a fast log
    filtered at fs/10, such as EMPS at 1 kHz: the few smeared samples are kept, as the EMPS recipe
    keeps them, and excluding them biases Fc and Fv by about 2 %)."""
    rw = 1.2 / cutoff
    return 0.0 if rw * fs <= SMEAR_SAMPLES_KEPT else rw


#: the settings a user can set, and the option of `kukaid fit` that sets each
_OPTIONS = {"cutoff": "--cutoff", "order": "--order", "edge": "--edge", "reversal_window": "--reversal-window",
            "qd_thr": "--qd-thr", "decimate": "--decimate", "diff": "--diff"}


def settings_reason(settings: dict, given: Collection[str] = ()) -> str:
    """One line saying why the pre-processing settings are what they are (for the fit's output);
    ``given``: the settings the user set (keys of :data:`_OPTIONS`), said to be the user's rather
    than given the default's reason."""
    fs, fc = settings["fs"], settings["cutoff"]
    rate = "the paper's KR C4 recipe (up to 250 Hz)" if fs <= 250 else "fs/10 (the EMPS recipe above 250 Hz)"
    rw = settings["reversal_window"]
    user = [f"{flag} {settings[k]:g}" if isinstance(settings[k], (int, float)) else f"{flag} {settings[k]}"
            for k, flag in _OPTIONS.items() if k in given]
    why = [f"set by the user: {', '.join(user)}"] if user else []
    if "cutoff" not in given:
        why.append(f"cut-off{'' if 'order' in given else ' and order'} from the {fs:.4g} Hz sample rate: {rate}")
    elif "order" not in given:
        why.append(f"order from the {fs:.4g} Hz sample rate: {rate}")
    if "edge" not in given:
        why.append("edge = 5 periods of the cut-off")
    if settings.get("time_base") == "re-stamped":
        why.append("time stamps uneven, the positions smoother on an even grid: the grid replaces them")
    elif settings.get("time_base") == "resampled":
        why.append("samples taken at uneven times: positions interpolated onto an even grid")
    if "reversal_window" not in given:
        why.append(f"reversal window {rw * 1e3:.3g} ms" + (" (the filter smears a friction jump over "
                                                           f"{1.2 * fs / fc:.3g} samples: kept)" if rw == 0 else ""))
    return "; ".join(why)


@dataclass(frozen=True, eq=False)
class Prepared:
    """One axis of a log, filtered and differentiated, with its mode masks (all arrays (n,)).

    Attributes
    ----------
    time : s.   q : filtered position, rad (m).   qd : rad/s.   qdd : rad/s².
    tau : filtered torque, N·m (N).   tau_raw, q_raw : the unfiltered samples of the kept rows.
    dynamic : bool, samples the sliding (dynamic-mode) model is fitted on.
    quasi_static : bool, ``|qd| < qd_thr``.
    plateau : bool, dynamic samples at nearly constant velocity (``|qdd| < qdd_tol``).
    rows : indices of the kept samples in the original log.
    fs : sample rate of the original log, Hz.
    tau_span : the unfiltered torque at the original rate over the kept span (before
    decimation: the noise level is read from its second differences, which decimation would
    fill with the signal's curvature).
    settings : the filter settings used.
    axis, joint, kind, source : the axis number, "revolute"/"prismatic", experiment kind, file.
    """

    time: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    tau: np.ndarray
    tau_raw: np.ndarray
    q_raw: np.ndarray
    dynamic: np.ndarray
    quasi_static: np.ndarray
    plateau: np.ndarray
    rows: np.ndarray
    fs: float
    tau_span: np.ndarray
    settings: dict[str, Any] = field(default_factory=dict)
    axis: int = 3
    joint: str = "revolute"
    kind: str = ""
    source: str = ""

    @property
    def n(self) -> int:
        return int(self.time.size)

    @property
    def qd_thr(self) -> float:
        return float(self.settings["qd_thr"])


def fast_length(m: int) -> int:
    """The smallest length >= m whose prime factors are 2, 3 and 5 (a fast FFT length)."""
    best = 1 << max(0, (int(m) - 1).bit_length())
    p5 = 1
    while p5 < best:
        p35 = p5
        while p35 < best:
            p = p35
            while p < m:
                p *= 2
            best = min(best, p)
            p35 *= 3
        p5 *= 5
    return int(best)


def lowpass(x: np.ndarray, fs: float, cutoff: float | None, order: int, derivatives: int = 0) -> list[np.ndarray]:
    """Zero-phase Butterworth low-pass of ``x`` (the forward-backward filter's response).

    A digital Butterworth filter of order N (bilinear transform, cut-off ``cutoff`` Hz) run
    forward then backward has the real, zero-phase response
    ``|H(f)|^2 = 1 / (1 + (tan(pi f / fs) / tan(pi cutoff / fs))^(2N))``.  It is applied here
    exactly, by FFT, on the signal extended at both ends by odd reflection (as
    ``scipy.signal.sosfiltfilt`` pads) and with the line through the extended ends removed (so
    the periodic extension has no jump).  Away from the edges (which :func:`preprocess` trims)
    this equals ``sosfiltfilt(butter(N, cutoff, fs=fs))`` to rounding; it avoids importing
    scipy.signal (over a second), which keeps ``kukaid fit`` fast.

    Returns ``[filtered, d/dt filtered, ...]`` up to ``derivatives`` exact (spectral)
    derivatives of the filtered signal, per second.  ``cutoff=None``: no filtering (only the
    spectral derivatives).
    """
    x = np.asarray(x, dtype=float)
    n = x.size
    pad = min(n - 1, int(math.ceil(8.0 * fs / (cutoff or fs / 10.0))))
    if pad > 0:
        x = np.r_[2 * x[0] - x[pad:0:-1], x, 2 * x[-1] - x[-2:-pad - 2:-1]]
    m = x.size
    slope = (x[-1] - x[0]) / (m - 1) if m > 1 else 0.0
    line = x[0] + slope * np.arange(m)
    # x - line is 0 at both ends, so zeros appended up to a length with small prime factors keep
    # the periodic extension continuous; an FFT of an arbitrary length (a large prime factor) can
    # cost far more than m log m
    N = fast_length(m)
    f = np.fft.rfftfreq(N, d=1.0 / fs)
    X = np.fft.rfft(x - line, n=N)
    if cutoff:
        ratio = np.tan(np.pi * np.minimum(f, 0.5 * fs * (1 - 1e-12)) / fs) / np.tan(np.pi * cutoff / fs)
        X = X / (1.0 + ratio ** (2 * int(order)))
    out = [np.fft.irfft(X, n=N)[pad:pad + n] + line[pad:pad + n]]
    jw = 2j * np.pi * f
    for k in range(1, derivatives + 1):
        X = X * jw
        d = np.fft.irfft(X, n=N)[pad:pad + n]
        if k == 1:
            d = d + slope * fs
        out.append(d)
    return out


def reversal_distance(t: np.ndarray, qd: np.ndarray, qd_thr: float) -> np.ndarray:
    """Time (s) from every sample to the nearest velocity reversal, start or stop (inf if none).

    Events are the quasi-static samples (``|qd| < qd_thr``: stops, starts, slow reversals) and
    the midpoints between two consecutive samples whose velocity changes sign.
    """
    quasi = np.abs(qd) < qd_thr
    flip = np.flatnonzero(np.sign(qd[1:]) * np.sign(qd[:-1]) < 0)
    ev = np.sort(np.r_[t[quasi], 0.5 * (t[flip] + t[flip + 1])])
    if ev.size == 0:
        return np.full(t.size, np.inf)
    j = np.searchsorted(ev, t)
    left = np.where(j > 0, t - ev[np.maximum(j - 1, 0)], np.inf)
    right = np.where(j < ev.size, ev[np.minimum(j, ev.size - 1)] - t, np.inf)
    return np.minimum(np.abs(left), np.abs(right))


#: share of the steps between samples that may skip samples (a step over 1.75 x the first quartile):
#: the filters treat the samples as evenly spaced, and a single axis validated with 0.5, 1, 2, 5 % of
#: its samples dropped gave 1.5, 4.4, 6.4, 10.9 % relative error (0.52 % with all of them)
MAX_SKIPPED_SHARE = 0.005


def _controller_step(d: np.ndarray) -> float:
    """The controller's step from the steps between stamps ``d``: their median, or their first
    quartile when over a quarter of them are 1.75 x that or longer (then many skip a sample, and a
    median falls between one and two steps).  The first quartile alone reads jitter of the stamps
    as a shorter step and its long steps as skips (±3 ms on 12 ms: 0.7 % of the steps, refused);
    the median holds the step up to ±0.45 of a step."""
    quartile = float(np.percentile(d, 25))
    return quartile if np.mean(d > 1.75 * quartile) > 0.25 else float(np.median(d))


def check_even_samples(time: np.ndarray, where: str, attrs: dict | None = None) -> None:
    """Refuse a log whose samples skip many controller samples (FitError naming it).

    ``attrs`` (the log's attributes) says how it was recorded: a ring capture that skips samples
    lost them to ring overflows, and the remedy is a longer ring or a faster reader, not ring mode.

    The low-pass filters treat the samples as evenly spaced. Jitter in the stamps (the LWR4+'s, at
    most 1.4 x the step) and a gap or two (a reconnect, a ring overflow) are not refused; a log where
    steps of two or more samples are common (a KUKAVARPROXY poll capture on a busy PC: 6 % of the
    steps for one axis, about half for six) is filtered on a distorted time base, and its fit,
    validation and diagnosis are off by several times the error of the same motion sampled evenly."""
    d = np.diff(np.asarray(time, float))
    if d.size < 20:
        return
    step = _controller_step(d)
    share = float(np.mean(d > 1.75 * step))
    if share > MAX_SKIPPED_SHARE:
        attrs = attrs or {}
        if attrs.get("capture_mode") == "ring":
            ovf = attrs.get("ring_overflows")
            why = ("a ring capture loses samples when the PC does not read the ring in time"
                   + (f" ({int(ovf)} ring overflows in this one)" if ovf is not None else "")
                   + ": give the logger a longer ring (kukaid krl-logger --blocks, --block-samples) or read it "
                     "over a faster link, and capture again")
        else:
            why = ("a KUKAVARPROXY poll capture misses samples when a poll takes longer than a cycle; record with "
                   "capture --mode ring (the program of kukaid krl-logger)")
        raise FitError(f"{where}: {100 * share:.2g} % of the steps between samples skip samples (steps up to "
                       f"{1e3 * float(d.max()):.4g} ms, the log's step {1e3 * step:.4g} ms; at most "
                       f"{100 * MAX_SKIPPED_SHARE:g} % can be filtered as evenly spaced): {why}")


#: the time-base judgements of the logs seen last: (id of its time, of its positions, columns) ->
#: (weak references to those arrays, re-stamped or not); a fit, a compare or a robot fit prepares
#: one log several times (each axis, each column set), and on a 1-hour six-axis log with uneven
#: stamps each judgement costs 0.7 s
_JUDGED: dict[tuple, tuple] = {}
_JUDGED_KEPT = 16


def _roughness(q: np.ndarray, cols: tuple, x: np.ndarray) -> float:
    """The positions' squared second derivatives on the time base ``x``, summed over ``cols``."""
    return float(sum(np.sum(np.gradient(np.gradient(q[:, c], x), x) ** 2) for c in cols))


def _restamped(log: Any, t: np.ndarray, grid: np.ndarray, cols: tuple) -> bool:
    """Are the positions ``cols`` of ``log`` smoother on the even ``grid`` than on its stamps ``t``?
    Judged once per log (its time and position arrays, held by weak reference: a log that is gone
    leaves no judgement a new one could take for its own)."""
    key = (id(log.time), id(log.q), cols)
    seen = _JUDGED.get(key)
    if seen is not None and seen[0]() is log.time and seen[1]() is log.q:
        return seen[2]

    out = _roughness(log.q, cols, grid) < _roughness(log.q, cols, t)
    try:
        _JUDGED[key] = (weakref.ref(log.time), weakref.ref(log.q), out)
    except TypeError:       # arrays that take no weak reference are judged every time
        return out
    while len(_JUDGED) > _JUDGED_KEPT:
        del _JUDGED[next(iter(_JUDGED))]
    return out


def evenly_sampled(log: Any, cols: Sequence[int] | None = None) -> tuple[Any, str]:
    """``log`` on an even time grid over the same span, as the filters take it, and how ("even",
    "re-stamped" or "resampled").

    "even": its stamps already are.  "re-stamped": a controller samples its axes at a fixed rate,
    but a PC that records them often stamps each sample when it arrives, with jitter (the LWR4+
    recordings: stamps 3.2 to 6.8 ms apart at 5 ms while the position increments stay smooth);
    when the positions are smoother on the grid than on the stamps (smaller second differences),
    the grid replaces the stamps.  "resampled": the samples were taken at the uneven stamps (the
    positions are smoother on them), so the positions (and commanded positions) are interpolated
    onto the grid, linearly (at 12 ms an error of ``qdd dt² / 8``, under 1e-5 rad at 0.5 rad/s²);
    the torque is kept as sampled (interpolation would smooth the noise that the noise floor reads
    from second differences, and at ±3 ms its timing error is far below the filter's 5 Hz).
    Differentiated on the stamps, either jitter turns into velocity and acceleration (the LWR4+: tens
    of rad/s² and, through the inertia, tens of N·m that no joint felt; ±3 ms on 12 ms fitted Fv
    12 % low).  ``cols``: the columns of ``q`` to judge by (default all); one column at a time, so a
    long log needs no (N, n) temporaries beyond the resampled positions."""
    t = np.asarray(log.time, float)
    grid = np.linspace(t[0], t[-1], t.size)
    if t.size < 3 or np.allclose(np.diff(t), grid[1] - grid[0], rtol=1e-3, atol=0.0):
        return log, "even"
    cols = tuple(range(log.q.shape[1]) if cols is None else cols)
    if _restamped(log, t, grid, cols):
        return replace(log, time=grid), "re-stamped"
    moved = {name: np.column_stack([np.interp(grid, t, x[:, c]) for c in range(x.shape[1])])
             for name in ("q", "q_cmd") if (x := getattr(log, name)) is not None}
    return replace(log, time=grid, **moved), "resampled"


def preprocess(log: Any, axis: int | None = None, cutoff: float | None = None, order: int | None = None,
               qd_thr: float | None = None, edge: int | None = None, decimate: int = 1,
               reversal_window: float | None = None, qdd_tol: float = QDD_TOL_DEFAULT,
               filter_torque: bool = True, diff: str | None = None) -> Prepared:
    """Filter, differentiate and classify the samples of one axis of ``log``.

    Parameters
    ----------
    log : :class:`kukaid.logs.core.AxisLog`.
    axis : KUKA axis number (default: the log's only axis, or A3 if it has several).
    cutoff : low-pass cut-off, Hz (default from the sample rate, :func:`filter_defaults`).
    order : Butterworth order (default from the sample rate).
    qd_thr : dynamic/quasi-static velocity threshold, rad/s (m/s); default 0.0017.
    edge : samples trimmed at both ends (default ``ceil(5 fs / cutoff)``).
    decimate : keep every ``decimate``-th sample after filtering (default 1).
    reversal_window : s; dynamic samples closer than this to a velocity reversal are excluded
        (default :func:`default_reversal_window`: ``1.2 / cutoff``, 0 when that is a dozen samples
        or fewer).  0 disables.
    qdd_tol : rad/s², acceleration below which a dynamic sample counts as constant velocity.
    filter_torque : filter the torque as well as the position (default True, the paper).
    diff : "central" (default: central differences of the filtered position, the paper's and
        the EMPS recipe) or "spectral" (exact derivatives of the filtered position).

    Raises
    ------
    FitError : the log is too short for the filter, has non-finite values, or a bad setting.
    """
    where = log.attrs.get("source_file", "axis log")
    if axis is None:
        axis = log.axes[0] if len(log.axes) == 1 else (3 if 3 in log.axes else log.axes[0])
    col = log.index(axis)
    for name, x in (("time", log.time), ("q", log.q[:, col]), ("tau", log.tau[:, col])):
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            raise FitError(f"{where}: channel '{name}' of A{axis} is not finite (NaN or inf) at row {bad[0]}")
    if log.time.size < 8:
        raise FitError(f"{where}: only {log.time.size} samples; too short to filter and differentiate")
    check_even_samples(log.time, where, log.attrs)
    log, time_base = evenly_sampled(log)
    t = np.asarray(log.time, dtype=float)
    q = np.asarray(log.q[:, col], dtype=float)
    tau = np.asarray(log.tau[:, col], dtype=float)
    fs = 1.0 / float(np.median(np.diff(t)))
    d = filter_defaults(fs)
    order = int(d["order"] if order is None else order)
    cutoff = float(d["cutoff"] if cutoff is None else cutoff)
    if not (order >= 1):
        raise FitError(f"filter order must be >= 1, got {order}")
    if not (0.0 < cutoff < 0.9 * fs / 2.0):
        raise FitError(f"{where}: filter cut-off {cutoff:g} Hz must be in (0, {0.9 * fs / 2:.4g}) Hz "
                       f"(0.9 x Nyquist at {fs:.4g} Hz)")
    edge = int(math.ceil(5.0 * fs / cutoff)) if edge is None else int(edge)
    if edge < 0:
        raise FitError(f"edge must be >= 0 samples, got {edge}")
    decimate = int(decimate)
    if decimate < 1:
        raise FitError(f"decimate must be a positive integer, got {decimate}")
    qd_thr = QD_THR_DEFAULT if qd_thr is None else float(qd_thr)
    if not qd_thr >= 0:
        raise FitError(f"qd_thr must be >= 0 rad/s, got {qd_thr}")
    rw = default_reversal_window(fs, cutoff) if reversal_window is None else float(reversal_window)
    padlen = 3 * (2 * ((order + 1) // 2) + 1)  # sosfiltfilt's default pad length
    need = max(2 * edge + 10, padlen + 1)
    if t.size < need:
        raise FitError(f"{where}: {t.size} samples is too short for the filter (order {order}, filter cut-off "
                       f"{cutoff:g} Hz at {fs:.4g} Hz, edge trim {edge} samples each side): need at least {need}")
    diff = "central" if diff is None else diff
    if diff == "central":
        qf = lowpass(q, fs, cutoff, order)[0]
        qd = np.gradient(qf, t)
        qdd = np.gradient(qd, t)
    elif diff == "spectral":
        qf, qd, qdd = lowpass(q, fs, cutoff, order, derivatives=2)
    else:
        raise FitError(f"diff must be 'central' or 'spectral', got '{diff}'")
    tf = lowpass(tau, fs, cutoff, order)[0] if filter_torque else tau.copy()
    rows = np.arange(edge, t.size - edge)[::decimate]
    t_k = t[rows]
    qd_k = qd[rows]
    quasi = np.abs(qd_k) < qd_thr
    dist = reversal_distance(t, qd, qd_thr)[rows]
    dynamic = (~quasi) & (dist >= rw)
    plateau = dynamic & (np.abs(qdd[rows]) < qdd_tol)
    settings = {"cutoff": cutoff, "order": order, "edge": edge, "decimate": decimate, "qd_thr": qd_thr,
                "reversal_window": rw, "qdd_tol": qdd_tol, "filter_torque": bool(filter_torque), "fs": fs, "diff": diff,
                "time_base": time_base}
    return Prepared(time=t_k, q=qf[rows], qd=qd_k, qdd=qdd[rows], tau=tf[rows], tau_raw=tau[rows], q_raw=q[rows],
                    dynamic=dynamic, quasi_static=quasi, plateau=plateau, rows=rows, fs=fs, settings=settings,
                    axis=int(axis), joint=log.joint[col], kind=str(log.attrs.get("experiment", "") or ""),
                    source=str(where), tau_span=tau[edge:t.size - edge])
