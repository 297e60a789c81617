"""KUKA Trace recordings (KR C4) -> AxisLog: the channels of a recording's modules mapped to axes.

The files are DIAdem ``.dat`` headers with ``.r64`` data (:mod:`kukaid.logs.diadem`).  A recording
is several modules (one ``.dat``/``.r64`` pair each: ``REC_NextGenDrive#1`` .. ``#6``, one per
drive, and ``REC_KRCIpo``, the interpolator) with different sample times.  Given any file of
them, :func:`read_trace` also reads its siblings ``REC_*.dat`` and puts every channel on one stated
time base (see ``time_base``) over the interval all channels cover.

Channel mapping (case-insensitive; axis number from ``A3``, ``Achse 3``, ``Axis 3`` or a trailing
number in the channel name, else from the module's file name, ``NextGenDrive#3`` -> A3):

- measured position ``q``: ``Istposition``, ``Ist-Position``, ``Position_Ist``, ``AxisPos_Act``,
  ``ActPos``;
- commanded position ``q_cmd``: ``Sollposition``, ``Position_Soll``, ``AxisPos_Cmd``/``_Set``,
  and the plain axis-position channels of a ``KRCIpo`` module (the interpolator's setpoints);
- torque ``tau``: ``Istmoment``, ``Ist-Moment``, ``Moment_Ist``, ``Torque_Act``, ``ActTorque``;
- motor temperature ``temp``: ``Motortemperatur``, ``MotorTemp``.

Units (202): degrees (``Grad``, ``°``, ``deg``) or ``rad``; ``mm``/``m`` for a linear axis;
``Nm``/``N``; ``°C`` or ``K``.  Anything else is an error naming the channel.
"""
from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from kukaid.errors import LogFormatError
from kukaid.logs.core import AxisLog
from kukaid.logs.diadem import Signal, load_signals

_DEG = math.pi / 180.0


# -- mapping ------------------------------------------------------------------------------------
_KEYS = [  # (pattern, quantity)
    (r"soll[-_ ]?pos|sollposition|position[-_ ]?soll|axispos[-_ ]?(cmd|set)|cmdpos|setpos", "q_cmd"),
    (r"ist[-_ ]?pos|istposition|position[-_ ]?ist|axispos[-_ ]?act|actpos|measpos", "q"),
    (r"ist[-_ ]?moment|istmoment|moment[-_ ]?ist|torque[-_ ]?act|acttorque|istdrehmoment", "tau"),
    (r"motor[-_ ]?temp", "temp"),
]
_AXIS_RES = [re.compile(r"(?:^|[^a-z])a(\d{1,2})(?![0-9])", re.I), re.compile(r"achse\s*(\d{1,2})", re.I),
             re.compile(r"axis\s*(\d{1,2})", re.I), re.compile(r"(\d{1,2})\s*$")]
_GENERIC_POS = re.compile(r"pos", re.I)


def _axis_of(name: str) -> int | None:
    for rx in _AXIS_RES:
        m = rx.search(name)
        if m:
            a = int(m.group(1))
            if 1 <= a <= 12:
                return a
    return None


def _classify(sig: Signal, module: str) -> tuple[str, int] | None:
    name = sig.channel.name
    low = name.lower()
    qty = next((q for rx, q in _KEYS if re.search(rx, low)), None)
    if qty is None and "krcipo" in module.lower() and _GENERIC_POS.search(low):
        qty = "q_cmd"  # the interpolator's axis channels are setpoints
    if qty is None:
        return None
    axis = _axis_of(name)
    if axis is None:
        axis = _module_axis(module)  # KR C4 drive traces: the axis is the #N of NextGenDrive#N
    if axis is None:
        return None
    return qty, axis


def _to_si(sig: Signal, qty: str) -> tuple[np.ndarray, str]:
    unit = sig.channel.codes.get(202, "").strip()
    u = unit.lower().replace(" ", "")
    v = sig.values
    if qty in ("q", "q_cmd"):
        if u in ("grad", "°", "deg", "grd", "degree", "degrees"):
            return v * _DEG, "revolute"
        if u == "rad":
            return v, "revolute"
        if u == "mm":
            return v * 1e-3, "prismatic"
        if u == "m":
            return v, "prismatic"
    elif qty == "tau":
        if u in ("nm", "n*m", "n·m"):
            return v, "revolute"
        if u == "n":
            return v, "prismatic"
    elif qty == "temp":
        if u in ("°c", "c", "gradc", "degc", "grad", "°"):
            return v, ""
        if u == "k":
            return v - 273.15, ""
    raise LogFormatError(f"{sig.channel.where(202)}: unit '{unit}' is not supported for {qty}")


def _siblings(path: Path) -> list[Path]:
    m = re.match(r"^(.*)_[^_]+$", path.stem)
    if not m:
        return [path]
    prefix = m.group(1)
    sib = sorted(p for p in path.parent.glob("*.dat")
                 if p.stem.startswith(prefix + "_") and "_" not in p.stem[len(prefix) + 1:] or p == path)
    return sib or [path]


_DRIVE_MODULE = re.compile(r"drive\s*#\s*(\d{1,2})\s*$", re.I)


def _module_axis(module: str) -> int | None:
    """Axis number of a drive module from its file name (``REC_NextGenDrive#3`` -> 3)."""
    m = _DRIVE_MODULE.search(module)
    return int(m.group(1)) if m and 1 <= int(m.group(1)) <= 12 else None


def _is_drive(module: str) -> bool:
    """A drive module (``NextGenDrive``, ``Drive#N``) records motor-side quantities."""
    return "drive" in module.lower()


def is_gear_ratio_file(text: str | Path) -> bool:
    """``--gear-ratio``'s value names a JSON file (else it is ``A1=120.5,...`` itself)."""
    return str(text).lower().endswith(".json") or Path(str(text)).is_file()


def parse_gear_ratios(text: str | Path | dict | None) -> dict[int, float]:
    """Gear ratios (motor turns per axis turn, sign included) per axis.

    ``text`` is ``"A1=120.5,A2=-121,3=100"``, a JSON file holding ``{"A1": 120.5, ...}`` (also
    ``{"gear_ratio": {...}}``), or such a dict.  Every ratio must be finite and non-zero.
    """
    if text is None:
        return {}
    where = "--gear-ratio"
    if isinstance(text, dict):
        raw = text
    elif is_gear_ratio_file(text):
        from kukaid.jsonfile import read_json

        where = str(text)
        raw = read_json(text, LogFormatError, "JSON file of gear ratios", schemas=())
        if isinstance(raw, dict) and isinstance(raw.get("gear_ratio"), dict):
            raw = raw["gear_ratio"]
        if not isinstance(raw, dict):
            raise LogFormatError(f"{text}: expected an object {{\"A1\": ratio, ...}}")
    else:
        raw = {}
        for part in filter(None, (p.strip() for p in str(text).split(","))):
            k, sep, v = part.partition("=")
            if not sep:
                raise LogFormatError(f"{where}: '{part}' is not AXIS=RATIO (e.g. A1=120.5)")
            raw[k.strip()] = v.strip()
    out: dict[int, float] = {}
    for k, v in raw.items():
        m = re.fullmatch(r"[Aa]?(\d{1,2})", str(k).strip())
        if not m or not 1 <= int(m.group(1)) <= 12:
            raise LogFormatError(f"{where}: '{k}' is not an axis (A1 to A12)")
        try:
            r = float(v)
        except (TypeError, ValueError):
            raise LogFormatError(f"{where}: gear ratio of {k} is not a number: {v!r}") from None
        if not math.isfinite(r) or r == 0:
            raise LogFormatError(f"{where}: gear ratio of {k} must be finite and non-zero; got {r:g}")
        out[int(m.group(1))] = r
    return out


def _sample_time(t: np.ndarray) -> float:
    return float(np.median(np.diff(t))) if t.size > 1 else math.inf


def _nearest(base: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each instant of ``base``: the index of the nearest instant of ``t`` (two or more), and
    whether they coincide (to a millionth of a sample)."""
    tol = 1e-6 * min(_sample_time(base), _sample_time(t))
    i = np.clip(np.searchsorted(t, base), 1, t.size - 1)
    i = np.where(np.abs(t[i - 1] - base) <= np.abs(t[i] - base), i - 1, i)
    return i, np.abs(t[i] - base) <= tol


def _on_base(base: np.ndarray, t: np.ndarray, vals: np.ndarray) -> tuple[np.ndarray, bool]:
    """``vals`` sampled at ``t`` put on ``base``: recorded values where the instants coincide,
    linear interpolation between them; and whether any value was interpolated."""
    if t.size < 2:
        return np.interp(base, t, vals), True
    i, same = _nearest(base, t)
    if same.all():
        return vals[i], False
    out = np.interp(base, t, vals)
    out[same] = vals[i[same]]
    return out, True


def _common_grid(times: list[np.ndarray]) -> np.ndarray:
    """The instants every channel was sampled at (the slowest module's grid where they align)."""
    grid = max(times, key=_sample_time)
    keep = np.ones(grid.size, dtype=bool)
    for t in (t for t in times if t.size > 1):
        keep &= _nearest(grid, t)[1]
    return grid[keep]


TIME_BASES = ("position", "finest", "common")


_WHAT = {"q": "measured position (Istposition)", "tau": "torque (Istmoment)",
         "q_cmd": "commanded position (KRCIpo setpoint)", "temp": "motor temperature (Motortemperatur)"}


def _left_out(path: Path, mapped: dict, axes: list[int]) -> list[str]:
    """One line per channel a recording leaves out of its log: an axis with only one of position and
    torque is not logged; a setpoint or temperature is logged only when every logged axis has one."""
    out = []
    for a in sorted({a for _, a in mapped} - set(axes)):
        have = [q for q in ("q", "tau") if (q, a) in mapped]
        if have:
            miss = "tau" if have == ["q"] else "q"
            out.append(f"{path}: A{a} is not in the log: the recording has its {_WHAT[have[0]]} but no {_WHAT[miss]} "
                       "channel")
        else:  # only its setpoint or temperature: its drive module is not there (not copied with the rest)
            what = " and ".join(_WHAT[x] for x in ("q_cmd", "temp") if (x, a) in mapped)
            out.append(f"{path}: A{a} is not in the log: the recording has its {what} but no {_WHAT['q']} and no "
                       f"{_WHAT['tau']} channel (its drive module, NextGenDrive#{a}, missing?)")
    for qty in ("q_cmd", "temp"):
        lack = [a for a in axes if (qty, a) not in mapped]
        if 0 < len(lack) < len(axes):
            out.append(f"{path}: no {_WHAT[qty]} in the log, for any axis: the recording has none for "
                       f"{', '.join(f'A{a}' for a in lack)}")
    return out


def read_trace(path: str | Path, *, siblings: bool = True, time_base: str = "position",
               gear_ratio: str | Path | dict | None = None, hints: list[str] | None = None,
               **_ignored: Any) -> AxisLog:
    """Read a KUKA Trace recording into an :class:`~kukaid.logs.core.AxisLog` (SI units).

    Parameters
    ----------
    path : one ``.dat`` (or ``.r64``) file of the recording.
    siblings : also read the recording's other modules (``PREFIX_*.dat`` beside ``path``): every
        ``PREFIX_NextGenDrive#N`` and ``PREFIX_KRCIpo``.
    time_base : "position" (default: the sample instants of the measured position of the first
        axis; channels sampled at other instants are interpolated linearly onto them), "finest"
        (the shortest sample time among the mapped channels, same interpolation), or "common"
        (only the instants at which every channel was sampled: no interpolation, the slowest
        module's rate).  Where a channel's instant coincides with one of the base (to a millionth
        of a sample) its recorded value is taken, never an interpolated one.
    gear_ratio : motor turns per axis turn, per axis (dict, ``"A1=120.5,A2=-121"`` or a JSON
        file; see :func:`parse_gear_ratios`).  When given, the position and torque channels of the
        drive modules (motor side) are put on the joint: ``q = q_motor / r``,
        ``tau = tau_motor * r`` (gear losses are not modelled); then every drive axis needs one.
        Without it the drive channels are taken as recorded (joint side).

    A channel without an axis number in its name takes the axis of its module's file name
    (``NextGenDrive#3`` -> A3).  Every axis with both a measured position and a torque channel is
    logged; commanded position and motor temperature are added when present for every logged
    axis.  ``hints``, when given, gets one line per channel the recording left out so: an axis with
    a position but no torque (or the reverse), a temperature or setpoint some logged axes lack.  The attributes ``time_base``, ``time_base_note``, ``trace_sample_times``,
    ``interpolated`` and ``gear_ratio`` say how the log was made.
    """
    path = Path(path)
    if path.suffix.lower() == ".r64":
        dat = path.with_suffix(".dat")
        if not dat.exists():
            raise LogFormatError(f"{path}: no header file {dat.name} beside this data file")
        path = dat
    if not path.exists():
        raise LogFormatError(f"{path}: no such file")
    if time_base not in TIME_BASES:
        raise LogFormatError(f"{path}: time base must be one of {', '.join(TIME_BASES)}; got {time_base!r}")
    ratios = parse_gear_ratios(gear_ratio)
    files = _siblings(path) if siblings else [path]
    mapped: dict[tuple[str, int], tuple[Signal, np.ndarray]] = {}
    joint_of: dict[int, str] = {}
    names: list[str] = []
    steps: dict[str, float] = {}
    motor: set[tuple[str, int]] = set()
    for f in files:
        module = f.stem
        for sig in load_signals(f):
            names.append(sig.channel.name)
            steps.setdefault(module, _sample_time(sig.time))
            c = _classify(sig, module)
            if c is None:
                continue
            qty, axis = c
            if (qty, axis) in mapped:
                prev = mapped[(qty, axis)][0].channel
                raise LogFormatError(f"{sig.channel.where()}: A{axis} already has a {qty} channel "
                                     f"('{prev.name}' in {prev.file.name}); keep one of them")
            vals, joint = _to_si(sig, qty)
            if joint:
                if joint_of.setdefault(axis, joint) != joint:
                    raise LogFormatError(f"{sig.channel.where(202)}: A{axis} mixes revolute and linear units")
            if ratios and qty in ("q", "q_cmd", "tau") and _is_drive(module):
                if axis not in ratios:
                    raise LogFormatError(f"{sig.channel.where()}: no gear ratio for A{axis} (given for "
                                         f"{', '.join(f'A{a}' for a in sorted(ratios))}); give one per drive axis")
                vals = vals * ratios[axis] if qty == "tau" else vals / ratios[axis]
                motor.add((qty, axis))
            mapped[(qty, axis)] = (sig, vals)
    axes = sorted({a for q, a in mapped if q == "q"} & {a for q, a in mapped if q == "tau"})
    left_out = _left_out(path, mapped, axes)
    if hints is not None:
        hints.extend(left_out)
    if not axes:
        raise LogFormatError(f"{path}: no axis has both a measured position (Istposition) and a torque "
                             f"(Istmoment) channel; channels: {names[:12]}")
    used = [(k, v) for k, v in mapped.items() if k[1] in axes]
    t_lo = max(v[0].time[0] for _, v in used)
    t_hi = min(v[0].time[-1] for _, v in used)
    if not t_hi > t_lo:
        raise LogFormatError(f"{path}: the channels' time ranges do not overlap")
    eps = 1e-9 * max(1.0, abs(t_hi))
    if time_base == "position":
        ref = mapped[("q", axes[0])][0]
        base = ref.time
        how = f"the sample instants of {ref.channel.name} (A{axes[0]}, {ref.channel.file.stem})"
    elif time_base == "finest":
        ref = min((v[0] for _, v in used), key=lambda s: _sample_time(s.time))
        base = ref.time
        how = f"the finest sample time, that of {ref.channel.file.stem}"
    else:
        base = _common_grid([v[0].time for _, v in used])
        how = "the instants at which every channel was sampled"
    time = base[(base >= t_lo - eps) & (base <= t_hi + eps)]
    if time.size < 2:
        raise LogFormatError(f"{path}: fewer than 2 samples where all channels overlap"
                             + (" on a common grid (try --time-base position)" if time_base == "common" else ""))
    if not ratios:
        for (qty, a), (sig, vals) in mapped.items():
            if qty == "q" and a in axes and _is_drive(sig.channel.file.stem) and joint_of.get(a) == "revolute" \
                    and np.max(np.abs(vals)) > 4 * math.pi:
                raise LogFormatError(
                    f"{sig.channel.where()}: reaches {np.degrees(np.max(np.abs(vals))):.6g} degrees, beyond +-720: "
                    f"a motor-side position; give the gear ratios, kukaid load {path} --gear-ratio A1=...,A2=... "
                    "(or a JSON file) -o LOG.h5, and give LOG.h5 (the other commands have no --gear-ratio)")
    data: dict[str, np.ndarray | None] = {}
    interpolated: list[str] = []
    for qty in ("q", "tau", "q_cmd", "temp"):
        if not all((qty, a) in mapped for a in axes):
            data[qty] = None
            continue
        cols = []
        for a in axes:
            sig, vals = mapped[(qty, a)]
            col, interp = _on_base(time, sig.time, vals)
            cols.append(col)
            if interp:
                interpolated.append(f"{qty} A{a}")
        data[qty] = np.column_stack(cols)
    dt = _sample_time(time)
    note = f"time base: {how}, {dt * 1e3:.4g} ms, {time[0]:.6g} to {time[-1]:.6g} s (where every channel has data)"
    note += (f"; linearly interpolated onto it: {', '.join(interpolated)}" if interpolated
             else "; every channel as recorded (no interpolation)")
    if ratios:
        note += f"; drive (motor-side) channels put on the joint with gear ratios " \
                f"{', '.join(f'A{a}={ratios[a]:g}' for a in axes if a in ratios)}"
    elif any(_is_drive(v[0].channel.file.stem) for _, v in used):
        note += "; drive channels taken as joint-side (no gear ratio given)"
    joint = tuple(joint_of.get(a, "revolute") for a in axes)
    attrs: dict[str, Any] = {
        "source": "kuka-trace",
        "source_file": str(path),
        "trace_files": [str(f) for f in files],
        "trace_channels": {f"{q} A{a}": f"{s.channel.name} ({s.channel.file.name})"
                           for (q, a), (s, _) in mapped.items() if a in axes},
        "trace_sample_times": steps,
        "time_base": time_base,
        "time_base_note": note,
        "interpolated": interpolated,
        "gear_ratio": {f"A{a}": ratios[a] for a in axes if a in ratios},
        "motor_side_converted": sorted(f"{q} A{a}" for q, a in motor if a in axes),
        "left_out": left_out,
    }
    return AxisLog(time=time, axes=tuple(axes), joint=joint, attrs=attrs, **data)
